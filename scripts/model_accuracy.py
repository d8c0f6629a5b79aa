"""Accuracy of the model-based estimator against the paper's argmax, on data from nl.simulate.

    .venv/bin/python scripts/model_accuracy.py [--seeds 3] [--only grid,extended,...] [--json F]

Tables: the paper's 5 x 5 grid; extended targets at (4, 2, 0); other wall-spot layouts (and
height); two targets; the photon-count curve. "simulate" rows use nl.simulate at the library's
defaults (1 cm facets, 1 ps bins) while the fit uses its own coarse plate model; "same-model"
rows simulate the fit's own facet lattice (a best case, for comparison only).
"""
from __future__ import annotations

import argparse
import json
import math
import time
import warnings

import numpy as np

import nlos_cl as nl
from nlos_cl.localization.model import ModelEstimator
from nlos_cl.localization.model.estimator import GAUSS_LATTICE
from nlos_cl.localization.model.plate import plate_facets

PAPER_SPOTS = [[-0.5, 0, 0], [-1.0, 0, 0], [-1.5, 0, 0]]
TRIANGLE = [[-0.5, 0, 0], [-1.0, 0, 0.5], [-1.0, 0, -0.5]]
CIRCLE8 = [[-1.0 + 0.5 * math.cos(a), 0.0, 0.5 * math.sin(a)]
           for a in np.arange(8) * 2 * math.pi / 8]
GRID = nl.Grid.from_ranges(x=(0, 6), y=(0.01, 6), step_m=0.01)


def scene(position, size=(0.3, 1.6), spots=PAPER_SPOTS, normal=(-1, 0, 0), same_model=False):
    mesh = nl.rectangle(size[0], size[1], centre=position, normal=normal, cell_m=0.01)
    sc = nl.Scene(nl.paper_setup(detector_spots=spots), nl.Target(mesh), 0.01, truth=position)
    if same_model:  # the fit's own cell lattice instead of 1 cm facets
        yaw = math.atan2(normal[1], normal[0])
        p = [*position, size[0], size[1], yaw]
        object.__setattr__(sc, "_facets", plate_facets(p, GAUSS_LATTICE))
    return sc


def both(signals, seed, truth, log_mode=False, noise=None, targets=1):
    """(paper error, model error(s), model seconds, model LocatedTargets) for one noisy frame."""
    noisy = nl.add_noise(signals, 10, seed=seed, model=noise)
    filt = nl.gauss_filter(noisy)
    paper = nl.locate(filt, GRID, log_mode=log_mode, estimator="paper")
    t = time.perf_counter()
    model = nl.locate(filt, GRID, log_mode=log_mode, estimator=ModelEstimator(targets=targets),
                      raw=noisy)
    dt = time.perf_counter() - t
    truths = np.atleast_2d(truth)
    p_err = min(np.linalg.norm(paper.position - t_) for t_ in truths)
    m_err = [min(np.linalg.norm(tg.position - t_) for tg in model.targets) for t_ in truths]
    return p_err, m_err, dt, model.targets


def summary(name, p, m, times):
    p, m = np.asarray(p), np.asarray(m)
    print(f"| {name} | {p.mean():.3f} / {p.max():.3f} | {m.mean():.3f} / {m.max():.3f} | "
          f"{np.mean(times):.2f} / {np.max(times):.2f} |")
    return {"case": name, "paper_mean": p.mean(), "paper_max": p.max(), "model_mean": m.mean(),
            "model_max": m.max(), "model_s_mean": float(np.mean(times))}


def header(title):
    print(f"\n### {title}\n\n| case | paper argmax mean / max (m) | model mean / max (m) | "
          "model s/frame mean / max |\n|---|---|---|---|")


def grid_table(seeds, spots=PAPER_SPOTS, label="paper layout", log_mode=False):
    rows = []
    for same in (False, True):
        p, m, t = [], [], []
        for x in range(1, 6):
            for y in range(1, 6):
                pos = (float(x), float(y), 0.0)
                sig = nl.simulate(scene(pos, spots=spots, same_model=same))
                for s in range(seeds):
                    pe, me, dt, _ = both(sig, s, pos, log_mode)
                    p.append(pe), m.extend(me), t.append(dt)
        rows.append(summary(f"5x5 grid, {label}, {'same-model' if same else 'simulate'} data",
                            p, m, t))
    return rows


def extended_table(seeds):
    rows = []
    for spots, label, log_mode in ((PAPER_SPOTS, "paper layout", False),
                                   (CIRCLE8, "8-spot circle", True)):
        for size in ((0.8, 1.2), (0.6, 0.6), (1.0, 1.0), (0.5, 1.5)):
            sig = nl.simulate(scene((4.0, 2.0, 0.0), size, spots))
            res = [both(sig, s, (4.0, 2.0, 0.0), log_mode) for s in range(seeds)]
            rows.append(summary(f"{size[0]} x {size[1]} m at (4, 2, 0), {label}",
                                [r[0] for r in res], [r[1][0] for r in res], [r[2] for r in res]))
    return rows


def layout_table(seeds):
    rows = grid_table(seeds, TRIANGLE, "3 non-collinear spots", False)
    rows += grid_table(seeds, CIRCLE8, "8 spots on a 0.5 m circle", True)
    print("\nheight (1.6 m tall rectangle, non-collinear layouts): |z error| per case")
    for spots, label in ((TRIANGLE, "3 non-collinear"), (CIRCLE8, "8-spot circle")):
        for pos in ((4.0, 2.0, 0.3), (2.0, 3.0, -0.4), (3.0, 1.5, 0.0)):
            sig = nl.simulate(scene(pos, spots=spots))
            errs = [abs(both(sig, s, pos, True)[3][0].position[2] - pos[2]) for s in range(seeds)]
            print(f"  {label} at {pos}: mean |dz| {np.mean(errs):.3f} m, max {np.max(errs):.3f}")
            rows.append({"case": f"height {label} {pos}", "dz_mean": float(np.mean(errs)),
                         "dz_max": float(np.max(errs))})
    return rows


def two_targets(seeds):
    rows = []
    for a, b in (((4.0, 2.0, 0.0), (2.0, 4.0, 0.0)), ((3.0, 2.0, 0.0), (3.0, 3.2, 0.0))):
        sigs = [nl.simulate(scene(p, (0.3, 0.3), CIRCLE8)) for p in (a, b)]
        total = _sum_signals(sigs)
        for k in (2, "auto"):
            res = [both(total, s, [a, b], True, targets=k) for s in range(seeds)]
            found = [len(r[3]) for r in res]
            print(f"  {a} + {b}, targets={k}: found {found}")
            rows.append(summary(f"two 0.3 m squares {a} + {b}, 8 spots, targets={k}",
                                [r[0] for r in res], [max(r[1]) for r in res],
                                [r[2] for r in res]))
    return rows


def _sum_signals(sigs):
    hs = [s.histograms() for s in sigs]
    total = hs[0].with_data(hs[0].data + hs[1].data)
    return nl.upload(total)


def photon_table(seeds):
    rows = []
    base = nl.simulate(scene((4.0, 2.0, 0.0))).histograms()
    counter = nl.PhotonCounter()
    per_det = counter.expected_counts(base).data
    background = (counter.dark_count_rate_hz + counter.ambient_rate_hz) * counter.tdc_bin_s \
        * counter.n_pulses
    signal = (per_det - background).sum(axis=1).mean()
    for photons in (3000, 1000, 300, 100, 30):
        pc = nl.PhotonCounter(n_pulses=counter.n_pulses * photons / signal)
        p, m, t = [], [], []
        for s in range(seeds):
            counts = pc.counts(base, seed=s)
            filt = nl.gauss_filter(counts)
            p.append(nl.locate(filt, GRID, estimator="paper").error_m)
            t0 = time.perf_counter()
            loc = nl.locate(filt, GRID, estimator="model", raw=counts)
            t.append(time.perf_counter() - t0)
            m.append(loc.error_m)
        rows.append(summary(f"{photons} signal photons / detector at (4, 2, 0)", p, m, t))
    return rows


def coverage_table(seeds):
    """How often the truth lies in the reported 95 % region, full estimator, nl.simulate data."""
    rows = []
    for pos, size in (((4.0, 2.0, 0.0), (0.3, 1.6)), ((2.0, 3.0, 0.0), (0.3, 1.6)),
                      ((4.0, 2.0, 0.0), (0.8, 1.2))):
        sig = nl.simulate(scene(pos, size))
        inside, errs = [], []
        for s in range(seeds * 10):
            _, m_err, _, targets = both(sig, 1000 + s, pos)
            d = targets[0].position[:2] - np.array(pos[:2])
            inside.append(float(d @ np.linalg.solve(targets[0].covariance[:2, :2], d)) <= 5.991)
            errs.append(m_err[0])
        print(f"| {size[0]} x {size[1]} m at {pos} | {len(inside)} | {np.mean(inside):.3f} | "
              f"{np.mean(errs):.4f} |")
        rows.append({"case": f"{size} at {pos}", "frames": len(inside),
                     "coverage": float(np.mean(inside)), "mean_error": float(np.mean(errs))})
    return rows


TABLES = {"grid": ("5 x 5 grid (paper's target, 10 dB AWGN)", grid_table),
          "extended": ("Extended targets at (4, 2, 0), facing -x, 10 dB", extended_table),
          "layouts": ("Other layouts, 5 x 5 grid, 10 dB", layout_table),
          "two": ("Two targets (signals summed), 10 dB", two_targets),
          "photons": ("Photon counting (PhotonCounter defaults, scaled pulses)", photon_table),
          "coverage": ("95 % region coverage, nl.simulate data, 10 x seeds frames", coverage_table)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--only", default=",".join(TABLES))
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    out = {}
    for key in args.only.split(","):
        title, fn = TABLES[key]
        header(title)
        out[key] = fn(args.seeds)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1, default=float)


if __name__ == "__main__":
    main()
