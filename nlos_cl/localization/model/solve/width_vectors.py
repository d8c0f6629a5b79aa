"""The warm fit's solver variables (`WidthVectors`, model.fit's `width_vectors`): each plate's
width and yaw stepped as its width vector."""
from __future__ import annotations

import numpy as np

from ..shapes import plate


class WidthVectors:
    """The solver's variables with each plate's (width w, yaw a) replaced by its width vector
    e = w (-sin a, cos a), the plate's extent across it on the search plane (its normal is
    (cos a, sin a)). Why: a plate's histograms are spread in time by its extent along the
    paths' gradient, ~ e . grad(path), so the data pin one component of e and leave the other
    loose: in (w, a) that is a curved valley (w cos(a - a0) = const), along which Gauss-Newton
    steps overshoot and damped ones crawl; in e it is a straight line. The paper's scene's
    stream bench: two of its eight noise draws took 34-35 model calls from the previous
    draw's plate (3-4 rejected steps, then ~0.02 m of width a step, max_nfev reached), with e
    25 and 31, to a lower cost. Bounds: e inside the box of the width's upper bound; the
    width is clipped into its bounds where e leaves them (a flat spot the solver steps off);
    the yaw stays within pi of its start (no wrap)."""

    def __init__(self, pairs, yaw0):
        self.pairs, self.yaw0 = pairs, yaw0  # [(width j, yaw j)] in theta; start yaws

    @classmethod
    def of(cls, obj):
        """For an objective's free parameters, or None: no plate with width and yaw free."""
        if not getattr(obj.shape, "WIDTH_VECTORS", False):  # the plate's (width, yaw) pairs
            return None
        where = {int(f): j for j, f in enumerate(np.flatnonzero(obj.free))}
        pairs = [(where[w], where[a]) for k in range(len(obj.base))
                 for w, a in [(k * plate.N_PARAMS + plate.WIDTH, k * plate.N_PARAMS + plate.YAW)]
                 if w in where and a in where]
        if not pairs:
            return None
        theta0 = obj.start()[0]
        return cls(pairs, {a: float(theta0[a]) for _, a in pairs})

    def bounds(self, lo, hi):
        lo, hi = lo.copy(), hi.copy()
        for w, a in self.pairs:
            lo[w], lo[a], hi[a] = -hi[w], -hi[w], hi[w]
        return lo, hi

    def to_phi(self, theta):
        phi = np.array(theta, np.float64)
        for w, a in self.pairs:
            phi[w], phi[a] = -theta[w] * np.sin(theta[a]), theta[w] * np.cos(theta[a])
        return phi

    def to_theta(self, phi):
        theta = np.array(phi, np.float64)
        for w, a in self.pairs:
            yaw, start = np.arctan2(-phi[w], phi[a]), self.yaw0[a]
            theta[a] = start + (yaw - start + np.pi) % (2.0 * np.pi) - np.pi
            theta[w] = np.clip(np.hypot(phi[w], phi[a]), plate.LOWER[plate.WIDTH],
                               plate.UPPER[plate.WIDTH])
        return theta

    def dtheta_dphi(self, phi):
        """d theta / d phi (n, n) at phi (the width's clip ignored: a flat spot's edge)."""
        m = np.eye(len(phi))
        for w, a in self.pairs:
            ex, ey = phi[w], phi[a]
            r2 = ex * ex + ey * ey
            r = np.sqrt(r2)
            m[w, w], m[w, a], m[a, w], m[a, a] = ex / r, ey / r, -ey / r2, ex / r2
        return m

    def dphi_dtheta(self, theta):
        """d phi / d theta (n, n) at theta: the Jacobian back in the shape's parameters."""
        m = np.eye(len(theta))
        for w, a in self.pairs:
            s, c = np.sin(theta[a]), np.cos(theta[a])
            m[w, w], m[w, a], m[a, w], m[a, a] = -s, -theta[w] * c, c, -theta[w] * s
        return m
