"""Leader-exclusion consistency: per leader j, an ACKF on dead reckoning and the OTHER leaders' ranges only.

The filter excluding j (state [L, λ], the ACKF of replay.stack.filters.ckf)
predicts j's range, and ``exclusion_residual_m`` of j's epoch is the range
minus that prediction. A drift or a stale value on link j does not move the
filter excluding j (it never sees j's ranges), so the residual grows with
the fault, while the follower's dead-reckoning error is corrected by the
other links. The ranges a filter does use are gated as the reference
filter's are (replay.stack.features): a repeated range, or f2 above the
chi-square gate on that filter's own innovation, or a range whose own
exclusion residual exceeds ``gate_m`` (the link disagrees with the
others), is left out, at most ``gate_cap`` epochs in a row per link, so one
faulty link contaminates the filters testing the others as little as
possible.

With one leader there is no other link: the residual is NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from formats.geodesy import metric_scales_scalar
from replay.stack.filters.ckf import (
    State2,
    dr_predict,
    isolation_action,
    position_update,
    range_innovation,
    range_update,
)

NAN = float("nan")


@dataclass(frozen=True)
class ExclusionParams:
    """The exclusion filters' tuning: the runner's P0, Q and R, and their gate (f2 and metres) with its cap."""

    p0_m: tuple[float, float]
    q_m_per_s: tuple[float, float]
    r_m: float
    gate_f2: float
    gate_cap: int
    gate_m: float = math.inf


class LeaderExclusion:
    """One ACKF per leader, each fed every leader's ranges but its own; `epoch` gives the excluded leader's residual."""

    def __init__(self, leaders: tuple[str, ...], start: tuple[float, float, float], params: ExclusionParams) -> None:
        """Every filter starts at `start` (lat rad, lon rad, depth m) with P0 = diag(p0_m)², as the runner's methods."""
        lat_rad, lon_rad, depth_m = start
        c = params
        b, a = metric_scales_scalar(lat_rad, depth_m)
        s0 = State2(float(lat_rad), float(lon_rad), (c.p0_m[0] / b) ** 2, 0.0, (c.p0_m[1] / a) ** 2)
        self.leaders = tuple(leaders)
        self.states: dict[str, State2] = dict.fromkeys(self.leaders, s0)
        self.q = c.q_m_per_s
        self.r_var = float(c.r_m) ** 2
        self.gate_f2 = float(c.gate_f2)
        self.gate_cap = int(c.gate_cap)
        self.gate_m = float(c.gate_m)
        self._streak: dict[tuple[str, str], int] = {}

    def propagate(self, dt_s: float, forward_mps: float, lateral_mps: float, heading_rad: float,
                  depth_m: float) -> None:
        """Time update of every filter by one DR step (filters with equal states are predicted once)."""
        done: dict[State2, State2] = {}
        for ld, s in self.states.items():
            nxt = done.get(s)
            if nxt is None:
                nxt = done[s] = dr_predict(s, dt_s, forward_mps, lateral_mps, heading_rad, depth_m, self.q)
            self.states[ld] = nxt

    def fix(self, lat_rad: float, lon_rad: float, r11: float, r12: float, r22: float) -> None:
        """A position fix (covariance in rad²) updates every filter: it is no leader's range."""
        for ld, s in self.states.items():
            self.states[ld] = position_update(s, lat_rad, lon_rad, r11, r12, r22) or s

    def epoch(self, leader: str, z_m: float, geo: tuple[float, float, float], depth_m: float,
              repeated: bool) -> float:
        """Leader's range z (horizontal): its residual against the filter excluding it; the others take z.

        NaN for an unknown or only leader, or a degenerate prediction.
        """
        if leader not in self.states or len(self.states) < 2:
            return NAN
        own = range_innovation(self.states[leader], z_m, geo, depth_m, self.r_var)
        residual = own.residual if own is not None else NAN
        for ld, s in self.states.items():
            if ld == leader:
                continue
            inn = range_innovation(s, z_m, geo, depth_m, self.r_var)
            if inn is None:
                continue
            key = (ld, leader)
            gate = (repeated or inn.residual * inn.residual / inn.pzz > self.gate_f2
                    or abs(residual) > self.gate_m)      # this link disagrees with the others: NaN is False
            action, self._streak[key] = isolation_action(gate, self._streak.get(key, 0), self.gate_cap)
            if action != "isolate":
                self.states[ld] = range_update(s, inn, self.r_var, adaptive=True)
        return residual if math.isfinite(residual) else NAN
