"""`nlos-cl reproduce flood`: a multizone sensor's flood illumination read as confocal, measured.
The experiment (experiment: flood, write_doc), the sensor, its simulation and one draw's run
(study), the page (report); every number in flood.yaml."""
from .experiment import flood, write_doc

__all__ = ["flood", "write_doc"]
