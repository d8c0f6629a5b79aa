"""`nlos-cl reproduce real`: nlos_cl on measured datasets others recorded. The experiment
(experiment: real, write_doc), each dataset's runs (runs), the page and figures (report); the
cases in real.yaml."""
from .experiment import real, write_doc

__all__ = ["real", "write_doc"]
