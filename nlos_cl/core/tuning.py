"""Every tuning default of nlos_cl in one place: the numbers a user may want to change, each
with the reason it has its value. Modules import them from here; none repeats them.

Physics and the method's fixed numbers (c, the paper's h) are in constants.py."""
from __future__ import annotations

# A target's mesh is cut into facets this wide (m): at the paper's 10 ps bins (3 mm of path)
# 1 cm facets give histograms within 0.1 % of 5 mm ones (docs/physics.md); tracking's frame
# streams use twice that (FRAME_FACET_M) for speed, where the per-frame error is noise-limited.
FACET_M = 0.01
FRAME_FACET_M = 0.02

# Score in log mode (sum of log-likelihoods) above this many detectors: a product of many
# per-detector likelihoods underflows float32.
LOG_MODE_ABOVE_DETECTORS = 8

# With more histograms than this, searches that only need the neighbourhood of the answer
# (locate_capture's coarse region, the model fit's starts and short fits) use this many,
# spread over the wall (core.geometry.farthest_points); the final answer uses every one.
SEARCH_DETECTORS = 64

# With more histograms than this, a one-target fit whose plate misses the data chooses among
# plate, box, ellipsoid and cylinder (~45 LM fits: model.closed) on this many, spread over the
# wall, and refits only the chosen closed shape on every one (model.subset). CC-SOCR's scan
# read as one laser (a misfit plate; the closed shapes rejected as the sanity check does on
# every detector): 256 / 1,024 / 4,096 points 46 / ~45 / 35 s with the choice on 64,
# 10.7 / 11.7 / 10.3 s on 16, the same answers (depth 0.953-0.955 m); 24 points 12.8 -> 8.4 s.
# On 120 draws (one, closed, mismatch; 0-39, master seed 2201) 13 of the SPAD patches of
# 25-64 spots moved, by at most 6 mm (6 closer, 7 farther), medians, p90s, worst errors and
# failures unchanged; those draws' locates 1.4-3.5x faster, each family 28-33 % faster.
# On 8 (stop 50): 4,096 points 10.1-10.3 -> 7.8-7.9 s, 24 points 6.5 -> 4.4 s, 12 points
# 5.8 -> 4.3 s (two interleaved rounds), depths 0.938-0.955 m; the same 120 draws: 15 moved
# (mismatch 18 0.18 -> 0.06 m, 19 0.085 -> 0.116 m, the rest by <= 2 mm), medians, p90s
# (mismatch 0.3019 -> 0.3027), worst errors unchanged, failures (> 0.15 m) 13 -> 12, each
# family 21-30 % less time.
CHOICE_DETECTORS = 8

# With more histograms than SEARCH_DETECTORS, the fit on every one starts from the spread
# subset's converged answer and takes at most this many residual evaluations (each accepted
# step one Jacobian over every histogram): the subset's answer is within a few of its own sds
# of the full optimum, where Levenberg-Marquardt converges in a few Gauss-Newton steps, and
# every evaluation costs the whole capture (LCT's 4,096 x 2,048 counts: ~15 s a Jacobian on 2
# cores). Measured: docs/model-estimator.md, "Many histograms".
FINISH_NFEV = 4

# search="auto": frames timed per search (after one warm-up each) before the Locator keeps the
# faster one for its grid.
AUTO_TRIALS = 3

# Small read-only device inputs (taps, spots, axes) kept per Runtime, most recently used.
CONSTANT_CACHE = 64

# Locator plans that nl.locate keeps, most recently used (one per layout, grid, estimator,
# search and backend): a stream of frames through nl.locate builds its plan once.
PLAN_CACHE = 8

# A model fit is checked before it is reported (localization/model/policy/sanity.py) and replaced by
# the paper's argmax, with a warning, where it claims a target larger than MAX_EXTENT_M in any
# dimension (the people, boxes, plates and vehicles' sides nlos_cl is for; held-out draws
# fitted a 0.7 m square as a 2.1 x 3.0 m box, 0.56 m off), or where a detector's ellipse path
# through its centre differs from the path through the paper's argmax (on the target's visible
# surface) by more than the fitted diagonal + 2 ARGMAX_MARGIN_M. A Birge ratio (residual
# variance / noise's) above MISFIT_BIRGE alone is warned about only (measured paired captures
# gave 370-500 and a wrong depth; a closed box, 1,238 and the right centre); a closed shape
# above it whose depth the spots cannot tell falls back to the argmax (model.sanity).
MAX_EXTENT_M = 2.5
MISFIT_BIRGE = 100.0
# ... and a closed shape above MISFIT_BIRGE that removes less than EXPLAINED_MIN of the
# no-target cost (its depth seen or not) falls back too: closed fits to simulated closed
# targets leave 3e-6 to 5e-5 of it at any noise (20-60 dB, Birge 2.5-14,000: stop 50, 15
# scenes), CC-SOCR's "4" fitted as an ellipsoid or box as one laser 0.19-0.27 (Birge
# 300-430, the centre 0.1-0.3 m behind the letter); 0.9 leaves a real closed target's model
# error (pulse tails, reflectance) twice CC-SOCR's margin below it.
EXPLAINED_MIN = 0.9
ARGMAX_MARGIN_M = 0.15


def auto_log_mode(n_detectors: int) -> bool:
    """The default scoring mode for this many detectors (LOG_MODE_ABOVE_DETECTORS)."""
    return int(n_detectors) > LOG_MODE_ABOVE_DETECTORS

# A plate counts as partly hidden where the other plates block more than this share of its
# paths (localization.model.forward.shadow.hidden_shares): its size is then held by the warm
# fit's prior, and a tracker does not learn its size from that frame (tracking.warm.remember).
HIDDEN_SHARE = 0.05
