"""Layer 5: files: atomic writes, scene files, y-tal captures and sequences, calibration."""
