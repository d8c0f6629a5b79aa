"""Tracking hidden objects over frames (docs/tracking.md): a constant-velocity Kalman tracker
with identities, gating, association, warm-started model fits and fixed-lag smoothing, and
`track_sequence`, which builds one for a sequence file and runs it.

What a tracker takes lives in its own layer and is reached from there or from the facade
(`nl.MovingTarget`, `nl.simulate_sequence`, `nl.read_sequence`, ...): moving scenes
(nlos_cl.physics.trajectory), frames simulated one by one (nlos_cl.simulation.sequence),
sequence files (nlos_cl.io.ytal), background removal (nlos_cl.localization.background), sensor
noise (nlos_cl.physics.noise). `from nlos_cl.tracking import MovingTarget` still works (old code,
the notebooks): those names resolve here on first use, without importing their layers before.
"""
from __future__ import annotations

import importlib

from .kalman import Measurement
from .motion import ConstantVelocity, Interacting, MotionModel
from .options import MeasurementNoise, SearchPlan, TrackRules, grouped
from .sequences import TrackedFrame, track_sequence
from .track import Track
from .tracker import Tracker

# Other layers' names once re-exported here: where they live (resolved on first use).
_ELSEWHERE = {"Sequence": "..io.ytal.reading", "read_sequence": "..io.ytal.reading",
              "SequenceFrame": "..io.ytal.sequence", "write_sequence": "..io.ytal.sequence",
              "BackgroundRemover": "..localization.background",
              "SensorNoise": "..physics.noise", "MovingTarget": "..physics.trajectory",
              "Trajectory": "..physics.trajectory", "SimFrame": "..simulation.sequence",
              "frame_seed": "..simulation.sequence", "simulate_sequence": "..simulation.sequence"}

__all__ = ["ConstantVelocity", "Interacting", "Measurement", "MeasurementNoise", "MotionModel",
           "SearchPlan", "Track", "TrackRules", "TrackedFrame", "Tracker", "grouped",
           "track_sequence"]


def __getattr__(name):
    if name in _ELSEWHERE:
        return getattr(importlib.import_module(_ELSEWHERE[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
