"""Measured-data processing: time zero from the direct return, the first-bounce
gate, background subtraction, the instrument response, counts / dead / hot bins and pile-up,
each step reported. `process_measured(set) -> Processed(histograms, h_from_response_s,
report)`; docs/captures.md says what each step does on the measured datasets."""
from .pipeline import Processed, pooled_h, process_capture, process_measured

__all__ = ["Processed", "pooled_h", "process_capture", "process_measured"]
