"""Fig. 5: the signals at detectors A, B, C (raw + noise, Gauss filter, Gauss fit) and their
pulse widths (FWHM) against the paper's."""
from __future__ import annotations

from pathlib import Path

import nlos_cl as nl
from nlos_cl.apps import plotting

from ..common import PAPER, Result, Settings, fwhm_ns, paper_target, simulate_clean, title

FILTER_H_S = 0.8e-9  # the paper's Fig. 5 window


def fig5(s: Settings, out: Path) -> Result:
    clean = simulate_clean(paper_target(s=s), s)
    noisy = nl.add_noise(clean, s.snr_db, 0)
    filtered = nl.gauss_filter(noisy, FILTER_H_S).histograms()
    fitted, fit = nl.gauss_fit(noisy)
    c, n, fh = clean.histograms(), noisy.histograms(), fitted.histograms()
    t = c.time_axis.centres()
    rows, panels = [], []
    for d, name in enumerate("ABC"):
        row = {"detector": name, "fwhm_clean_ns": round(fwhm_ns(t, c.data[d]), 3),
               "fwhm_filtered_ns": round(fwhm_ns(t, filtered.data[d]), 3),
               "fwhm_fit_ns": round(fwhm_ns(t, fh.data[d]), 3),
               "fit_converged": bool(fit.converged[d]), "paper_fwhm_ns": PAPER["fig5"]["fwhm_ns"][d]}
        rows.append(row)
        sl = plotting.signal_window(c.data[d], t)
        panels.append((f"detector {name}: FWHM {row['fwhm_clean_ns']} ns (paper "
                       f"{row['paper_fwhm_ns']})", t[sl] * 1e9,
                       [(n.data[d, sl], "-", "raw + noise"),
                        (filtered.data[d, sl], "--", "Gauss filter h = 0.8 ns"),
                        (fh.data[d, sl], ":", "Gauss fit")]))
    figure = plotting.signals_figure(panels, "Fig. 5: signals at detectors A, B, C (10 dB)", out,
                                     "fig5")
    return Result("fig5", title("fig5"), rows,
                  {"fwhm_ns": [r["fwhm_clean_ns"] for r in rows],
                   "paper_fwhm_ns": PAPER["fig5"]["fwhm_ns"]}, [figure])
