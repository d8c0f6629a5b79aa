"""Tracking hidden objects over frames (docs/tracking.md): a constant-velocity Kalman tracker
with identities, gating, association, warm-started model fits and fixed-lag smoothing.

The tracker's inputs live in their own layers and are re-exported here for convenience:
moving scenes (nlos_cl.physics.trajectory) simulated frame by frame (nlos_cl.simulation.sequence),
sequence files (nlos_cl.io.ytal), background removal (nlos_cl.localization.background) and sensor
noise (nlos_cl.physics.noise). SciPy, h5py and trimesh load on first use.
"""
from __future__ import annotations

from ..io.ytal.reading import Sequence, read_sequence
from ..io.ytal.sequence import SequenceFrame, write_sequence
from ..localization.background import BackgroundRemover
from ..physics.noise import SensorNoise
from ..physics.trajectory import MovingTarget, Trajectory
from ..simulation.sequence import SimFrame, frame_seed, simulate_sequence
from .kalman import Measurement
from .motion import ConstantVelocity, Interacting
from .track import Track
from .tracker import Tracker

__all__ = ["BackgroundRemover", "ConstantVelocity", "Interacting", "Measurement", "MovingTarget",
           "SensorNoise", "Sequence", "SequenceFrame", "SimFrame", "Track", "Tracker", "Trajectory",
           "frame_seed", "read_sequence", "simulate_sequence", "write_sequence"]
