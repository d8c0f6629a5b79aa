"""Layer 6: simulated histograms: one frame from a scene (frame.py), a sequence of frames
from moving targets (sequence.py)."""
