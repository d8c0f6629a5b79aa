"""Tracking hidden objects over frames (issue 12): moving scenes simulated frame by frame,
sequence files (y-tal fields with a leading frame axis, read lazily), background removal on the
device, and a constant-velocity Kalman tracker with identities. See docs/tracking.md.

Nothing here is imported by the rest of the library; SciPy, h5py and trimesh load on first use.
"""
from __future__ import annotations

from .background import BackgroundRemover
from .kalman import ConstantVelocity, Measurement
from .noise import SensorNoise
from .reading import Sequence, read_sequence
from .sequence import SequenceFrame, write_sequence
from .simulate import SimFrame, frame_seed, simulate_sequence
from .tracker import Track, Tracker
from .trajectory import MovingTarget, Trajectory

__all__ = ["BackgroundRemover", "ConstantVelocity", "Measurement", "MovingTarget", "SensorNoise",
           "Sequence", "SequenceFrame", "SimFrame", "Track", "Tracker", "Trajectory", "frame_seed",
           "read_sequence", "simulate_sequence", "write_sequence"]
