"""y-tal HDF5 files: single captures (capture.py), sequences of frames (sequence.py writes,
reading.py reads lazily), their shared fields (fields.py), which laser point goes with which
sensor point (pairing.py) and coordinate frame (frames.py)."""
