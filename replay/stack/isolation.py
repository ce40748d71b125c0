"""What a method does with a range its detector flagged: isolate it (capped per leader) or compensate it.

After t_a a flagged epoch is isolated (A.33-A.35) unless the leader's cap
of consecutive isolations is reached; past the cap it is used with R* and
counted as capped. A compensation detector's correction replaces isolation:
the range Z - correction is used. See docs/design.md.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import NamedTuple

from replay.stack.detectors.base import Decision
from replay.stack.filters.ckf import RangeInnovation, State2, isolation_action, range_innovation


class Ranging(NamedTuple):
    """One usable range epoch as every method sees it: time, leader, horizontal range, leader position, depth."""

    t_s: float
    leader: str
    z: float                             # horizontal range (m)
    geo: tuple[float, float, float]      # the leader's lat, lon (rad), depth (m)
    depth_m: float                       # the follower's depth


class Isolation:
    """Per method and leader, the consecutive isolations against their cap; per method, the capped epochs."""

    def __init__(self, cap: int, r_var: float) -> None:
        """``cap``: consecutive isolations per leader before a range is used anyway; ``r_var``: R (m²)."""
        self.cap = cap
        self.r_var = r_var
        self.capped: Counter[str] = Counter()
        self._streaks: dict[str, Counter[str]] = {}

    def gate(self, name: str, leader: str, flagged: bool, cap: int) -> str:
        """The action ("update", "isolate" or "capped") for a method's verdict on a leader's range, with a cap."""
        streak = self._streaks.setdefault(name, Counter())
        action, streak[leader] = isolation_action(flagged, streak[leader], cap)
        return action

    def act(self, name: str, state: State2, decision: Decision, inn: RangeInnovation,
            ep: Ranging) -> tuple[str, RangeInnovation, bool]:
        """Isolation with the cap, or compensation: (action, innovation to use, compensated)."""
        if decision.flagged and decision.correction_m != 0.0 and math.isfinite(decision.correction_m):
            self._streaks.setdefault(name, Counter())[ep.leader] = 0
            fixed = range_innovation(state, ep.z - decision.correction_m, ep.geo, ep.depth_m, self.r_var)
            return "update", fixed if fixed is not None else inn, fixed is not None
        action = self.gate(name, ep.leader, decision.flagged, self.cap)
        self.capped[name] += action == "capped"
        return action, inn, False
