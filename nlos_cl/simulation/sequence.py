"""Moving scenes simulated frame by frame on the device.

Frame k is at t = k / fps. Each moving target's mesh is translated onto its trajectory (its
facets are cut once and translated: subdividing commutes with translation); static targets
(clutter: a wall, a box) stay where they are, and their signal is simulated once and added on
the device every frame. So static and moving targets never shadow each other here (the moving
targets, simulated together in one nl.simulate call, do shadow one another). Per-frame
noise (nl.AWGN or nl.PhotonCounter) is seeded from (seed, k) by NumPy's SeedSequence, so frame k
of a sequence is the same whether or not the frames before it were drawn.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.errors import require
from ..core.limits import MAX_FRAMES, require_count
from ..core.tuning import FRAME_FACET_M
from ..physics.trajectory import MovingTarget


@dataclass(frozen=True)
class SimFrame:
    """One simulated frame: its index, time, the (noisy) signals on the device, and the
    moving targets' true centres (K, 3) in our frame."""

    index: int
    t_s: float
    signals: object  # nl.Signals
    truths: np.ndarray


def frame_seed(seed: int, index: int) -> int:
    """The noise seed of frame `index` of a sequence seeded with `seed` (deterministic)."""
    from ..physics.noise import check_seed
    state = np.random.SeedSequence([check_seed(seed), int(index)]).generate_state(1)
    return int(state[0])


def simulate_sequence(setup, moving, *, n_frames: int, fps: float, static=(), time_axis=None,
                      noise=None, seed: int = 0, facet_size_m: float = FRAME_FACET_M, backend=None):
    """An iterator of `SimFrame`s, one simulated (and, with `noise`, noisy) frame at a time, so
    a long sequence never has to fit in memory. `moving`: MovingTargets (one or several);
    `static`: nl.Targets that do not move; `noise`: nl.AWGN(snr_db), nl.PhotonCounter(...) or
    None. Arguments are checked now, frames simulated as they are asked for."""
    from ..core.paths import TimeAxis, default_time_axis
    from ..ops.backend import resolve_backend
    from ..physics.noise import check_seed
    from ..physics.scene import Setup, Target
    moving = (moving,) if isinstance(moving, MovingTarget) else tuple(moving)
    static = (static,) if isinstance(static, Target) else tuple(static)
    require(isinstance(setup, Setup), "setup", f"expected a nlos_cl.Setup, got "
            f"{type(setup).__name__}", "build one with nl.Setup(...) or nl.paper_setup()")
    require(len(moving) >= 1 and all(isinstance(m, MovingTarget) for m in moving), "moving",
            "expected one or more MovingTarget(target, trajectory)",
            "pass e.g. [MovingTarget(nl.Target(mesh), Trajectory([0, 5], [[2, 4, 0], [5, 1, 0]]))]")
    require(all(isinstance(t, Target) for t in static), "static", "expected nl.Target objects",
            "wrap each static mesh: nl.Target(nl.box(...))")
    require(isinstance(n_frames, (int, np.integer)) and not isinstance(n_frames, bool)
            and n_frames >= 1, "n_frames", f"must be a positive integer, got {n_frames!r}",
            "pass e.g. 50")
    require_count("n_frames", n_frames, MAX_FRAMES, "frames", "simulate fewer frames (each is "
                  "one forward model), or several shorter sequences")
    require(isinstance(fps, (int, float)) and not isinstance(fps, bool) and math.isfinite(fps)
            and fps > 0 and math.isfinite(n_frames / fps), "fps", f"must be a positive frame "
            f"rate in Hz (frame k at k / fps), got {fps!r}", "pass e.g. 10")
    require(noise is None or hasattr(noise, "apply"), "noise", f"expected a noise model "
            f"(nl.AWGN, nl.PhotonCounter) or None, got {type(noise).__name__}",
            "pass nl.AWGN(10)")
    check_seed(seed)
    axis = default_time_axis(setup) if time_axis is None else time_axis
    require(isinstance(axis, TimeAxis), "time_axis", f"expected a nl.TimeAxis, got "
            f"{type(axis).__name__}", "pass TimeAxis(t0_s, dt_s, n_bins)")
    backend = resolve_backend(backend)
    return _frames(setup, moving, static, axis, noise, int(seed), float(facet_size_m),
                   backend, int(n_frames), float(fps))


def _frames(setup, moving, static, axis, noise, seed, facet, backend, n_frames, fps):
    from ..physics.scene import Scene
    from .frame import simulate
    background = None
    if static:  # simulated once: it is the same in every frame
        background = simulate(Scene(setup, static[0], facet, more_targets=static[1:]), axis,
                              backend=backend)
    facets = [m.target.facets(facet) for m in moving]
    for k in range(n_frames):
        t = k / fps
        sig, truths = _moving_signals(setup, moving, facets, facet, axis, t, backend, simulate)
        if background is not None:  # in the moving targets' units (an axpy on the device)
            sig = sig.derive(sig.handle + background.handle * (background.scale_w / sig.scale_w))
        if noise is not None:
            sig = noise.apply(sig, frame_seed(seed, k))
        yield SimFrame(k, t, sig, truths)


def _moving_signals(setup, moving, facets, facet, axis, t, backend, simulate):
    from ..core.geometry import Facets
    from ..physics.scene import Scene
    placed = [m.placed(t) for m in moving]
    truths = np.array([m.trajectory.at(t) for m in moving])
    scene = Scene(setup, placed[0], facet, truth=truths[0], more_targets=tuple(placed[1:]))
    for i, (m, f) in enumerate(zip(moving, facets)):  # each mesh cut once, moved
        scene.use_facets(i, Facets(f.centres + truths[i] - m.centre, f.normals, f.areas))
    sig = simulate(scene, axis, backend=backend)
    layout = replace(sig.layout, truth=truths[0], truths=truths)
    return type(sig)(sig.backend, sig.handle, sig.scale_w, layout), truths
