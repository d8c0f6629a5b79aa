"""How many targets the tracker's model fit looks for each frame, where the number is not given
(`targets='auto'`, up to a cap): births and deaths from the data.

Per frame, with the model estimator:
- while some live track is tentative, or none is alive, the frame is fitted cold with the model
  selection's 'auto' (model.policy.select: a plate more only where the BIC says the data hold
  it), up to one more target than there are live tracks (and the cap): a target is found, a
  spurious tentative track gets no measurement and dies;
- once every live track is confirmed, their number is fitted, warm-started from them (the
  fixed-K path that tracking was measured with);
- a fit whose residual still holds a return (sanity.leftover_note: the detection's test on
  the residual) in BIRTH_FRAMES frames in a row is fitted again with 'auto', up to one more
  target; where that finds no more, the next try waits COOL_FRAMES frames (a shape or light the
  model lacks also leaves a residual, frame after frame).
Deaths from the data too: a fixed number of plates places one even where its target has gone,
so each plate's support (model.policy.criteria.support: the BIC gain of keeping it) is read and
a plate the data do not hold is no measurement; the lifecycle then ends its track after its
misses.
"""
from __future__ import annotations

from ..localization.separate import LEFTOVER

BIRTH_FRAMES = 2
COOL_FRAMES = 10


class TargetCount:
    """The per-frame number of targets for a tracker whose count is not given (`cap` at
    most)."""

    def __init__(self, cap: int):
        self.cap, self.run, self.cool = int(cap), 0, 0

    def for_frame(self, tracks) -> tuple:
        """(targets, max_targets) for this frame's fit: ('auto', live + 1 capped) while a track
        is tentative or none lives, else (confirmed count, that count)."""
        live = [t for t in tracks if t.status in ("tentative", "confirmed")]
        if not live or any(t.status != "confirmed" for t in live):
            return "auto", max(1, min(self.cap, len(live) + 1))
        n = min(len(live), self.cap)
        return n, n

    def try_more(self, location, targets) -> bool:
        """After a fixed-K fit: is it time to look for one target more (the residual held a
        return BIRTH_FRAMES frames in a row, no cool-down, below the cap)?"""
        if self.cool > 0:
            self.cool -= 1
        if targets == "auto" or targets >= self.cap or location is None:
            self.run = 0
            return False
        fits = [getattr(t, "fit", None) for t in location.targets]
        left = any(w.startswith(LEFTOVER) for f in fits if f is not None for w in f.warnings)
        self.run = self.run + 1 if left else 0
        return self.run >= BIRTH_FRAMES and self.cool == 0

    def tried(self, found_more: bool) -> None:
        """The 'auto' refit's outcome: no more targets cools the next try down."""
        self.run = 0
        if not found_more:
            self.cool = COOL_FRAMES


def supported(found: list) -> list:
    """The measurements whose plate the data hold (a fit's `support` >= 0, or not measured)."""
    def held(m):
        fit = getattr(getattr(m, "source", None), "fit", None)
        kept = None if fit is None else (fit.diagnostics or {}).get("support")
        return kept is None or kept >= 0.0
    return [m for m in found if held(m)]
