"""How many targets the tracker's model fit looks for each frame, where the number is not given
(`targets='auto'`, up to a cap): births and deaths from the data.

Per frame, with the model estimator:
- while no track is alive, the frame is fitted cold with the model selection's 'auto'
  (model.policy.select: a plate more only where the BIC says the data hold it), up to the cap;
- while tracks live (tentative ones too), their number of plates is fitted (a track's
  object's extra plates too: tracking.association.objects), warm-started from their
  plates (tracking.warm; a track born this frame keeps its birth fit's plate): a tentative
  track is confirmed by that cheap fit, and a spurious one gets no measurement (below) and dies.
  (Before, a tentative track sent each frame to a cold 'auto' fit up to one target more: on a
  walker past furniture 10-50 s a frame on 2 shared cores, against ~0.1 s warm);
- a fit whose residual still holds a return (sanity.leftover_note: the detection's test on
  the residual) in BIRTH_FRAMES frames in a row is fitted again with 'auto', up to one more
  target; whatever that finds, the next try waits COOL_FRAMES frames (a shape or light the
  model lacks leaves a residual frame after frame: a person walker's plate fit sent every
  few frames to this 'auto' refit, and what it found died tentative), so the 'auto' refit runs
  on at most one frame in COOL_FRAMES + 1.
Deaths from the data too: a fixed number of plates places one even where its target has gone,
so each plate's support (model.policy.criteria.support: the BIC gain of keeping it) is read and
a plate the data do not hold is no measurement; the lifecycle then ends its track after its
misses.
"""
from __future__ import annotations

from ..localization.estimate import LEFTOVER
from .warm import plates

BIRTH_FRAMES = 2
COOL_FRAMES = 10


class TargetCount:
    """The per-frame number of targets for a tracker whose count is not given (`cap` at
    most)."""

    def __init__(self, cap: int):
        self.cap, self.run, self.cool = int(cap), 0, 0

    def for_frame(self, tracks) -> tuple:
        """(targets, max_targets) for this frame's fit: ('auto', cap) while no track lives, else
        (the live tracks' count, capped; that count)."""
        live = [t for t in tracks if t.status in ("tentative", "confirmed")]
        if not live:
            return "auto", self.cap
        n = min(plates(live), self.cap)  # a track's object may be fitted as touching plates
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
        """After an 'auto' refit, found more or not: the next waits COOL_FRAMES frames."""
        self.run, self.cool = 0, COOL_FRAMES


def supported(found: list) -> list:
    """The measurements whose plate the data hold (a fit's `support` >= 0, or not measured)."""
    def held(m):
        fit = getattr(getattr(m, "source", None), "fit", None)
        kept = None if fit is None else (fit.diagnostics or {}).get("support")
        return kept is None or kept >= 0.0
    return [m for m in found if held(m)]
