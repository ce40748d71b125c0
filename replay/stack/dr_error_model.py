"""A Kalman filter of the follower's dead-reckoning error with heading and DVL-scale states, and its lagged prediction.

Dead reckoning integrates DVL body velocities rotated by the INS heading. Its
error d (DR minus truth, north-east metres) grows mostly through two slow
terms of the sensors, which the 2-D random walk of `features.StiffReference`
cannot follow: a heading error psi turns every step's displacement (n, e)
by psi, adding psi·(-e, n), and a DVL scale-factor error s stretches it,
adding s·(n, e). The state is x = (d_n, d_e, psi, s):

    d <- d + psi·(-e, n) + s·(n, e)  at every DR step, psi and s random walks,
    d gets a random walk of ``q_m2_per_s`` too (the DVL's white noise),

so the filter predicts how the error moves as the vehicle turns, and a range
to a leader at distance r along the unit vector u (leader to DR position)
measures z ~ r - u·d. Over seeds 0-19 its innovation on normal ranges has a
spread (MAD-sigma) of 3.3 m against the stiff reference's 6.0 m (ranging
noise 3 m), and the lagged residual 3.8 m.

A filter that follows the DR error follows a drifting range too (a drift is
an error ramp on one line of sight, which the heading state can take for a
turn). So the residual a detector tests is the range against the filter's
state of ``lag_s`` ago, carried forward by the model over the DR
displacement since (`DrErrorModel.range`'s ``lagged_m``): a drift younger than the lag is
in none of it. The filter never takes a repeated range (a stale
modem repeats its last value, which says nothing of the DR error now,
however long the run: issue 26 found a 13-epoch stale run that, under a
shared cap of 10, entered the model and raised 43 false alarms). It also
leaves out a range whose lagged residual is beyond ``gate_sigma`` of its
predicted spread, at most ``gate_cap`` in a row per leader, so a longer
drift does not pull the state either, while a real change of the DR error
(which every leader sees) is taken after ``gate_cap`` ranges.

Propagation is lazy: the DR displacement and time are summed between
events, and the state moves by F = I + G(sums) at the next range or fix,
exact for the mean (psi and s are constant between updates; G·G = 0); the
process noise of the interval is added at its start.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

NAN = float("nan")


class LaggedResidual(NamedTuple):
    """One range against the model: now and from ``lag_s`` ago (NaN before a lagged state exists)."""

    innovation_m: float     # z - the current state's predicted range (before this range's update)
    innovation_var_m2: float
    lagged_m: float         # z - the predicted range from the state of lag_s ago carried forward
    lagged_var_m2: float


def _moved(x: list[float], a0: float, a1: float, b0: float, b1: float) -> list[float]:
    """F·x for the F of an interval whose DR steps sum to (n, e): (a0, a1) = (-e, n), (b0, b1) = (n, e)."""
    return [x[0] + a0 * x[2] + b0 * x[3], x[1] + a1 * x[2] + b1 * x[3], x[2], x[3]]


@dataclass(frozen=True)
class DrErrorParams:
    """The DR error model's tuning: process noise, range noise, initial sigmas, the lag and the gate.

    q_m2_per_s: the DR position random walk (m²/s); heading_walk_rad_per_sqrt_s and scale_walk_per_sqrt_s:
    the heading and DVL scale error walks; range_sigma_m: ranging sigma; p0_m: initial position sigmas north,
    east; heading_sigma_rad, scale_sigma: initial sigmas; lag_s: age of the lagged state; gate_sigma and
    gate_cap: ranges beyond this many sigmas are left out, at most gate_cap in a row per leader.
    """

    q_m2_per_s: float
    heading_walk_rad_per_sqrt_s: float
    scale_walk_per_sqrt_s: float
    range_sigma_m: float
    p0_m: tuple[float, float]
    heading_sigma_rad: float
    scale_sigma: float
    lag_s: float
    gate_sigma: float
    gate_cap: int


class DrErrorModel:
    """The DR error (d_n, d_e, heading error, scale error) of one follower, updated by ranges and fixes.

    Plain floats rather than numpy matrices: it runs once per range epoch, where
    a 4x4 numpy product costs more in call overhead than in arithmetic
    (tests/test_dr_error_model.py checks it against the matrix filter).
    """

    def __init__(self, params: DrErrorParams) -> None:
        """Start at x = 0 with P = diag(p0_m², heading_sigma², scale_sigma²); no lagged state yet."""
        c = params
        self.q = (float(c.q_m2_per_s), float(c.q_m2_per_s), float(c.heading_walk_rad_per_sqrt_s) ** 2,
                  float(c.scale_walk_per_sqrt_s) ** 2)
        self.r_var = float(c.range_sigma_m) ** 2
        self.lag_s = float(c.lag_s)
        self.gate_sigma = float(c.gate_sigma)
        self.gate_cap = int(c.gate_cap)
        self.x = [0.0, 0.0, 0.0, 0.0]
        diag = (float(c.p0_m[0]) ** 2, float(c.p0_m[1]) ** 2, float(c.heading_sigma_rad) ** 2,
                float(c.scale_sigma) ** 2)
        self.p = [[diag[i] if i == j else 0.0 for j in range(4)] for i in range(4)]
        self._pending = [0.0, 0.0, 0.0]                 # n, e, dt since the last propagation
        self._cum = (0.0, 0.0, 0.0, 0.0, 0.0)           # sums of (-e, n), (n, e) and dt since the start
        # t, x, P, cum: the states of the last lag_s and the newest older one
        self._snaps: deque[tuple[float, list[float], list[list[float]], tuple[float, ...]]] = deque()
        self._gated_out: dict[str, int] = {}          # gated ranges left out in a row, per leader
        self.last_fix_s = -math.inf                     # time of the last position fix taken

    def step(self, dt_s: float, north_m: float, east_m: float) -> None:
        """One DR step of dt_s seconds that moved the DR position by (north_m, east_m)."""
        self._pending[0] += north_m
        self._pending[1] += east_m
        self._pending[2] += dt_s

    def _propagate(self) -> None:
        n, e, dt = self._pending
        if dt == 0.0 and n == 0.0 and e == 0.0:
            return
        p, q = self.p, self.q
        for i in range(4):
            p[i][i] += q[i] * dt
        a0, a1, b0, b1 = -e, n, n, e
        self.x = _moved(self.x, a0, a1, b0, b1)
        # F·P·Fᵀ with F = I + G: G adds rows 2 and 3 into rows 0 and 1, then the same for the columns
        r2, r3 = p[2], p[3]
        p[0] = [p[0][j] + a0 * r2[j] + b0 * r3[j] for j in range(4)]
        p[1] = [p[1][j] + a1 * r2[j] + b1 * r3[j] for j in range(4)]
        for row in p:
            row[0], row[1] = row[0] + a0 * row[2] + b0 * row[3], row[1] + a1 * row[2] + b1 * row[3]
        c = self._cum
        self._cum = (c[0] + a0, c[1] + a1, c[2] + b0, c[3] + b1, c[4] + dt)
        self._pending = [0.0, 0.0, 0.0]

    def _forget(self, t_s: float) -> None:
        """Drop the states that a newer one at least lag_s old (at t_s) replaces."""
        snaps, cutoff = self._snaps, t_s - self.lag_s
        while len(snaps) > 1 and snaps[1][0] <= cutoff:
            snaps.popleft()

    def _remember(self, t_s: float) -> None:
        """Keep this state for the lagged prediction (memory bounded even if only fixes come)."""
        self._snaps.append((float(t_s), list(self.x), [list(row) for row in self.p], self._cum))
        self._forget(t_s)

    def _lagged(self, t_s: float, h0: float, h1: float) -> tuple[float, float] | None:
        """h·x and h·P·hᵀ of the state of lag_s ago (the newest at least that old) carried forward, or None."""
        self._forget(t_s)
        snaps = self._snaps
        if not snaps or snaps[0][0] > t_s - self.lag_s:
            return None
        _, x, p, cum = snaps[0]
        c = self._cum
        a0, a1, b0, b1, dt = (c[k] - cum[k] for k in range(5))
        hx = h0 * (x[0] + a0 * x[2] + b0 * x[3]) + h1 * (x[1] + a1 * x[2] + b1 * x[3])
        # h·F·(P + Q dt)·Fᵀ·hᵀ = g·(P + Q dt)·gᵀ with g = Fᵀ·hᵀ
        g = (h0, h1, a0 * h0 + a1 * h1, b0 * h0 + b1 * h1)
        q = self.q
        var = sum(g[i] * (sum(p[i][j] * g[j] for j in range(4)) + q[i] * dt * g[i]) for i in range(4))
        return hx, var

    def range(self, t_s: float, leader: str, z_m: float, north_m: float, east_m: float,
              repeated: bool) -> LaggedResidual:
        """Range z (m) to a leader, the DR position minus the leader being (north_m, east_m): residuals, then update."""
        self._propagate()
        r = math.hypot(north_m, east_m)
        if not r > 0.0 or not math.isfinite(z_m):
            return LaggedResidual(NAN, NAN, NAN, NAN)
        h0, h1 = -north_m / r, -east_m / r
        x, p = self.x, self.p
        ph = [p[i][0] * h0 + p[i][1] * h1 for i in range(4)]
        s = h0 * ph[0] + h1 * ph[1] + self.r_var
        v = z_m - r - (h0 * x[0] + h1 * x[1])
        lagged = self._lagged(t_s, h0, h1)
        vl = sl = NAN
        if lagged is not None:
            vl = z_m - r - lagged[0]
            sl = lagged[1] + self.r_var
        out = LaggedResidual(v, s, vl, sl)
        gated = math.isfinite(vl) and abs(vl) > self.gate_sigma * math.sqrt(sl)
        gated_out = self._gated_out.get(leader, 0)
        # a repeated range leaves the gate's count (of fresh ranges) as it was
        if not repeated and gated and gated_out < self.gate_cap:
            self._gated_out[leader] = gated_out + 1
        elif not repeated:
            self._gated_out[leader] = 0
            k = [ph[i] / s for i in range(4)]
            self.x = [x[i] + k[i] * v for i in range(4)]
            self.p = [[p[i][j] - k[i] * ph[j] for j in range(4)] for i in range(4)]
        self._remember(t_s)
        return out

    def fix(self, t_s: float, north_m: float, east_m: float, cov_m2: tuple[float, float, float]) -> None:
        """A position fix: d measured as (north_m, east_m), DR minus the fix, with covariance (nn, ne, ee) m²."""
        self._propagate()
        p, x = self.p, self.x
        snn, sne, see = p[0][0] + cov_m2[0], p[0][1] + cov_m2[1], p[1][1] + cov_m2[2]
        det = snn * see - sne * sne
        if not det > 0.0:
            return
        inn, ine, iee = see / det, -sne / det, snn / det
        # K = P[:, :2]·S⁻¹ (4 x 2); x += K·(fix - d); P -= K·P[:2, :]
        k = [(p[i][0] * inn + p[i][1] * ine, p[i][0] * ine + p[i][1] * iee) for i in range(4)]
        rn, re = north_m - x[0], east_m - x[1]
        self.x = [x[i] + k[i][0] * rn + k[i][1] * re for i in range(4)]
        new = [[p[i][j] - k[i][0] * p[0][j] - k[i][1] * p[1][j] for j in range(4)] for i in range(4)]
        self.p = [[0.5 * (new[i][j] + new[j][i]) for j in range(4)] for i in range(4)]
        self.last_fix_s = float(t_s)
        self._remember(t_s)
