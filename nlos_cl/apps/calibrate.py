"""`nlos-cl calibrate PAIRS.csv`: the paper's Eq. 26 calibration, path = a t + b, fitted from
measured (path, peak time) pairs."""
from __future__ import annotations

import json


def calibrate(args) -> int:
    from ..io.calibration import fit_calibration, read_calibration_pairs
    fit = fit_calibration(*read_calibration_pairs(args.pairs))
    result = {"a_m_per_s": fit.calibration.a_m_per_s, "b_m": float(fit.calibration.b_m[0]),
              "rmse_m": fit.rmse_m, "r2": fit.r2, "pairs": fit.n_pairs,
              "speed_error": fit.speed_error}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"path = {fit.calibration.a_m_per_s * 1e-7:.4f} cm/ns * t + "
              f"{fit.calibration.b_m[0] * 100:.2f} cm  (RMSE {fit.rmse_m * 100:.2f} cm, "
              f"R^2 {fit.r2:.4f}, slope {100 * fit.speed_error:+.2f} % from c, {fit.n_pairs} pairs)")
    return 0
