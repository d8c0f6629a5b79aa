"""`nlos-cl reproduce tracking`: the tracker's tables of docs/tracking.md. The experiment
(experiment: tracking, write_doc), its sections (sections), the cases read and checked from
tracking.yaml (cases), one tracked sequence measured (runs), the tables (report)."""
from .experiment import tracking, write_doc

__all__ = ["tracking", "write_doc"]
