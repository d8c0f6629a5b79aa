"""Re-acquiring a lost target. A confirmed track that coasts while every slot is taken
(`max_tracks` live) cannot be joined by a birth, so a target whose track had lost it (the
track's velocity taken from one wrong first fit, or biased fits that carried it off, so that the
right measurements fall outside its gate) got a new id only once the old track was deleted.

Instead, free measurements (paired with no track, and not one blob of several) start
*candidates* while every slot is taken and some confirmed track coasts: tentative tracks that
are not reported, confirmed by the same M-of-N evidence as a birth (`Lifecycle.confirm`). A
confirmed candidate is a target that persists; with every slot taken it is one of the followed
targets that the tracker has lost, so it continues the coasting track it could have come from,
under that track's id: the candidate's state and covariance replace the track's, and the
filter record starts a new segment there (`Track.smoothed` does not smooth across it).

"Could have come from" is the recovery gate: centred on the track's last *measured* state, with
its covariance there plus (initial_speed_sigma x time since)^2 per axis, i.e. where the target
could be now if the velocity the track coasts on is wrong (the velocity prior of a birth). The
coasted prediction is not the centre: a wrong velocity is what lost the target.
"""
from __future__ import annotations

import numpy as np

from . import association, kalman, warm


class Recovery:
    """Candidates for the coasting confirmed tracks (see the module docstring)."""

    def __init__(self, lifecycle, motion, gate_probability: float):
        self.lifecycle, self.motion, self.gate_probability = lifecycle, motion, gate_probability
        self.candidates: list = []

    def step(self, tracks, paired: set, free: list, t: float, frame_index: int,
             slots_full: bool) -> tuple[set, list]:
        """Advance the candidates with this frame's free measurements and hand each confirmed
        one to a coasting track: (ids of the tracks re-acquired, measurements still free)."""
        coasting = [tr for tr in tracks if tr.status == "confirmed" and id(tr) not in paired]
        if not coasting or not slots_full:  # nothing lost, or a birth can take the target
            self.candidates = []
            return set(), free
        for cand in self.candidates:
            dt, d = t - cand.t_s, cand.dims
            cand.state, cand.covariance = kalman.predict(
                cand.state, cand.covariance, self.motion.transition(dt, d),
                self.motion.process_noise(dt, d))
            cand.t_s = t
        pairs, free = association.associate(self.candidates, free, self.gate_probability)
        for cand, m in pairs:
            cand.state, cand.covariance = kalman.update(cand.state, cand.covariance, m)
            warm.keep(cand, m)
        hit = {id(c) for c, _ in pairs}
        self.candidates = [c for c in self.candidates
                           if not self.lifecycle.account(c, id(c) in hit, frame_index)]
        recovered = set()
        for cand in [c for c in self.candidates if c.status == "confirmed"]:
            track = self._lost_track(cand, [tr for tr in coasting if id(tr) not in recovered], t)
            if track is not None:
                _continue(track, cand)
                recovered.add(id(track))
        # a confirmed candidate is done: handed over, or no lost track could be its target
        self.candidates = [c for c in self.candidates if c.status != "confirmed"]
        left = []
        for m in free:  # evidence for a lost target: at most one candidate per coasting track
            if len(self.candidates) < len(coasting) - len(recovered):
                self.candidates.append(self.lifecycle.birth(m, t, frame_index, numbered=False))
            else:
                left.append(m)
        return recovered, left

    def _lost_track(self, cand, coasting, t):
        """The coasting track whose recovery gate holds the candidate best, or None."""
        best, best_d2, d = None, np.inf, cand.dims
        for track in coasting:
            last = _last_measured(track)
            if last is None or track.dims != d:
                continue
            t_hit, state, cov = last
            spread = (self.motion.initial_speed_sigma * (t - t_hit)) ** 2
            S = cov[:d, :d] + cand.covariance[:d, :d] + spread * np.eye(d)
            gap = cand.state[:d] - state[:d]
            d2 = float(gap @ np.linalg.solve(S, gap))
            if d2 <= kalman.gate_threshold(self.gate_probability, d) and d2 < best_d2:
                best, best_d2 = track, d2
        return best


def _last_measured(track):
    """(t_s, state, covariance) after the track's last measured frame, from its record."""
    n = len(track.state)
    for h, row in zip(reversed(track.history), reversed(track.steps)):
        if h[-1]:
            return h[1], row[:n], row[n:n + n * n].reshape(n, n)
    return None


def _continue(track, cand) -> None:
    """The candidate's estimate becomes the track's; its record starts a new segment."""
    track.state, track.covariance = cand.state.copy(), cand.covariance.copy()
    track.plate, track.extra = cand.plate, cand.extra  # (its remembered sizes: the same)
    track.model = cand.model
    track.late, track.offset = cand.late, cand.offset
    # the model's misfit floor on these data (Prior.misfit) is the object's: a candidate
    # fitted warm brings none, and a reset one sent walk.yaml's next misfit warm fit to a
    # cold fit that landed on the same plate
    track.misfit = track.misfit if cand.misfit is None else cand.misfit
    track.pending = None  # no prediction links this frame to the last one: a restart
