"""`nlos-cl simulate [SCENE.yaml] --out F.h5`: a scene file (or the paper's scene) simulated into a
y-tal capture (or, with --frames, a sequence of a moving scene)."""
from __future__ import annotations



def _paper_spec(args):
    """The paper's scene from the command-line options, as a scene file would give it."""
    from ..physics.noise import PhotonCounter
    from ..physics.noise import AWGN
    from ..core.paths import default_time_axis, simulation_bin
    from ..physics.scene import paper_scene
    from ..io.scenefile import SceneSpec
    scene = paper_scene(position=_paper_position(args.position), facet_size_m=args.facet or 0.01)
    noise = None
    if args.photons:
        noise = PhotonCounter(n_pulses=args.pulses, tdc_bin_s=args.tdc_ps * 1e-12)
    elif args.snr_db is not None:
        noise = AWGN(args.snr_db)
    dt_s = (args.dt_ps or 10.0) * 1e-12
    if args.photons and args.dt_ps is None:  # bins that sum into the TDC's (a 33 ps TDC: 8.25 ps)
        dt_s = simulation_bin(args.tdc_ps * 1e-12, dt_s)
    axis = default_time_axis(scene.setup, dt_s)
    return SceneSpec(scene, axis, noise, args.seed or 0, "paper rectangle 0.3 m x 1.6 m")


PAPER_POSITION = (-4.0, 0.0, 2.0)  # y-tal's X, Y, Z of the paper's target (ours: 4, 2, 0)


def _paper_position(given) -> tuple:
    """--position, in y-tal's frame as every capture and output states it (X along the wall,
    Y up, Z the depth from the wall), converted to ours once, here."""
    import math

    from ..core.errors import require
    from ..io.scenefile import MAX_SCENE_M
    from ..io.ytal.frames import YTAL
    X, Y, Z = (float(v) for v in (given or PAPER_POSITION))
    require(math.hypot(X, Y, Z) <= MAX_SCENE_M, "--position", f"{[X, Y, Z]} lies beyond the "
            f"{MAX_SCENE_M:g} m a scene spans: that looks like millimetres", "pass metres, e.g. "
            "--position -4 0 2")
    require(Z > 0, "--position", f"Z = {Z:g} m puts the target on or behind the relay wall "
            "(y-tal's frame: the wall is Z = 0, the hidden space Z > 0)",
            "pass a depth Z > 0, e.g. --position -4 0 2")
    return tuple(float(v) for v in YTAL.to_internal([X, Y, Z]))


def _scene_spec(args):
    from ..core.errors import require
    if args.scene is None:
        return _paper_spec(args)
    clash = [f for f in ("position", "facet", "dt_ps", "snr_db", "seed") if getattr(args, f)
             is not None] + (["photons"] if args.photons else [])
    require(not clash, f"--{clash[0].replace('_', '-')}" if clash else "", "describes the "
            "paper's scene, but a scene file was given", "put it in the scene file instead")
    from ..io.scenefile import load_scene
    return load_scene(args.scene)


def _simulate_frames(args, spec) -> int:
    """A sequence file: frame k at t = k / fps, moving targets on their trajectories, static
    ones (clutter) simulated once, per-frame noise seeded from the scene's seed."""
    from ..ops.backend import resolve_backend
    from ..io.ytal.sequence import write_sequence
    from ..physics.trajectory import MovingTarget
    from ..simulation.sequence import simulate_sequence
    scene = spec.scene
    moving = [MovingTarget(t, p) for t, p in zip(scene.targets, spec.trajectories) if p]
    static = [t for t, p in zip(scene.targets, spec.trajectories) if p is None]
    frames = simulate_sequence(scene.setup, moving, static=static, n_frames=args.frames,
                               fps=args.fps, time_axis=spec.time_axis, noise=spec.noise,
                               seed=spec.seed, facet_size_m=scene.facet_size_m,
                               backend=resolve_backend(args.device))
    path = write_sequence(args.out, frames, fps=args.fps,
                          device_distance_m=scene.setup.device_distance_m,
                          metadata={"scene": spec.description or str(args.scene),
                                    "noise": repr(spec.noise), "seed": spec.seed},
                          force=args.force)
    print(f"wrote {path}: {args.frames} frames at {args.fps:g} Hz, {len(moving)} moving and "
          f"{len(static)} static target(s)")
    return 0


def simulate(args) -> int:
    import nlos_cl as nl
    from ..ops.backend import resolve_backend
    from ..io.ytal.capture import write_capture
    from ..core.errors import require
    spec = _scene_spec(args)
    require(args.frames is None or args.scene is not None, "--frames", "needs a scene file "
            "with moving targets", "give a scene file whose targets have a `trajectory:`")
    if args.frames is not None:
        require(spec.moving, "--frames", "asks for a sequence, but no target of the scene "
                "file has a trajectory", "give a target `trajectory: {t_s: [...], positions: "
                "[...]}` in place of `position`")
        return _simulate_frames(args, spec)
    scene = spec.scene
    signals = nl.simulate(scene, spec.time_axis, backend=resolve_backend(args.device))
    if spec.noise is not None:
        signals = nl.add_noise(signals, model=spec.noise, seed=spec.seed)
    hist = signals.histograms()
    noise = repr(spec.noise) if spec.noise is not None else "none"
    truths = [[float(v) for v in t] for t in scene.truths]
    path = write_capture(args.out, hist, device_distance_m=scene.setup.device_distance_m,
                         metadata={"scene": spec.description or str(args.scene),
                                   "targets": truths, "noise": noise, "seed": spec.seed},
                         force=args.force)
    print(f"wrote {path}: {hist.n_detectors} detectors x {hist.time_axis.n_bins} bins of "
          f"{hist.time_axis.dt_s * 1e12:g} ps, {len(truths)} target(s) at "
          f"{in_capture_frame(truths, scene_file=args.scene is not None)}, noise: {noise}")
    return 0


def in_capture_frame(points, scene_file: bool = True) -> str:
    """Scene points (ours: the scene file's x, y, z) as the capture file and every command
    reading it gives them: y-tal's X, Y, Z."""
    from ..io.ytal.frames import YTAL
    file = [[round(float(v), 4) + 0.0 for v in YTAL.from_internal(p)] for p in points]
    mapping = " (the scene file's x, y, z as X = -x, Y = z, Z = y)" if scene_file else ""
    return f"(X, Y, Z) = {file} m in the capture's y-tal frame{mapping}"
