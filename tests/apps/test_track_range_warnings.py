"""`nlos-cl track` on a sequence of one confocal spot (a range track): every warning a frame
gives names that frame, as the 2-D tracks' do ('frame 2 (t 2.000 s): ...'), and a text
repeated by later frames is said once more at the end with them, not once per frame."""
import numpy as np

import nlos_cl as nl
from nlos_cl.apps.cli import main as cli
from nlos_cl.tracking import ranges, write_sequence

C = nl.SPEED_OF_LIGHT


def _spot(tmp_path, n=6):
    """A one-spot confocal sequence, a Gaussian return at 1.5 m of range in every frame."""
    axis = nl.TimeAxis(0.0, 16e-12, 768)
    centres = axis.t0_s + axis.dt_s * (np.arange(axis.n_bins) + 0.5)
    y = np.exp(-0.5 * ((centres * C - 3.0) / 0.02) ** 2)[None]
    frames = [(float(k), nl.HistogramSet(y, axis, [(0.0, 0.0, 0.0)], [(0.0, 0.0, 0.0)],
                                         nl.PathCalibration(C, [0.0]))) for k in range(n)]
    return write_sequence(tmp_path / "spot.h5", frames, fps=1.0)


def test_range_track_warnings_name_their_frame(tmp_path, capsys, monkeypatch):
    path = _spot(tmp_path)
    measured, seen = ranges.detected_range, iter(range(100))

    def warning_on_frames_2_and_4(histograms, h_s=None, **kw):
        k = next(seen)
        if k in (2, 4):  # what NumPy or the detection would say about a frame's record
            np.log(np.zeros(1))
        return measured(histograms, h_s, **kw)
    monkeypatch.setattr(ranges, "detected_range", warning_on_frames_2_and_4)
    assert cli(["track", str(path), "--no-progress"]) == 0
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert len(err) == 2, err
    assert err[0].startswith("nlos-cl: warning: frame 2 (t 2.000 s): ") and "divide" in err[0]
    assert err[1].endswith("(again: frame 4, t 4.000 s)"), err


def test_a_warning_with_each_frames_own_numbers_is_folded(tmp_path, capsys, monkeypatch):
    """A text that differs from frame to frame only in its numbers (the model fit's Birge
    ratio, a target's index) is said with its first frame, then once with the frames that
    gave it again (30 lines on `nlos-cl track` of docs/scenes/walk.yaml before)."""
    import warnings
    path = _spot(tmp_path)
    measured, seen = ranges.detected_range, iter(range(100))

    def doubtful(histograms, h_s=None, **kw):
        k = next(seen)
        if k >= 1:
            warnings.warn(f"model fit, target 1 of 1: Birge ratio {200 + 7 * k} > 100")
        if k == 3:  # the same frame, another target: that frame once
            warnings.warn("model fit, target 2 of 2: Birge ratio 169 > 100")
        return measured(histograms, h_s, **kw)
    monkeypatch.setattr(ranges, "detected_range", doubtful)
    assert cli(["track", str(path), "--no-progress"]) == 0
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert err == [
        "nlos-cl: warning: frame 1 (t 1.000 s): model fit, target 1 of 1: Birge ratio 207 > 100",
        ("nlos-cl: warning: model fit, target 1 of 1: Birge ratio 207 > 100 (again, with each "
         "frame's own numbers: frames 2-5, t 2.000 .. 5.000 s)")], err
