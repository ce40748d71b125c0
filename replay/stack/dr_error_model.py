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
(which every leader sees) is taken after ``gate_cap`` ranges. A position
fix (USBL) is gated the same way, on its Mahalanobis distance.

With ``range_scale_sigma`` > 0 a last state k, shared by every link, is a
range-scale error (a sound-speed error: each range is (1 + k) times the
true one), so a range measures z ~ r - u·d + k·r and d no longer takes a
bias that points away from every leader at once; ``LaggedResidual.scale_m``
is its share k·r of the current prediction.

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
    scale_m: float = 0.0    # the range-scale state's share of the current prediction, k·r (0 without it)


def _moved(x: list[float], g: list[float]) -> list[float]:
    """F·x for the F of an interval: d gains the sum over states k >= 2 of (g[2k-4], g[2k-3])·x[k]."""
    out = list(x)
    for k in range(2, len(x)):
        out[0] += g[2 * k - 4] * x[k]
        out[1] += g[2 * k - 3] * x[k]
    return out


@dataclass(frozen=True)
class DrErrorParams:
    """The DR error model's tuning: process noise, range noise, initial sigmas, the lag and the gate.

    q_m2_per_s: the DR position random walk (m²/s); heading_walk_rad_per_sqrt_s and scale_walk_per_sqrt_s:
    the heading and DVL scale error walks; range_sigma_m: ranging sigma; p0_m: initial position sigmas north,
    east; heading_sigma_rad, scale_sigma: initial sigmas; lag_s: age of the lagged state; gate_sigma and
    gate_cap: ranges beyond this many sigmas are left out, at most gate_cap in a row per leader;
    hold_q_m2_per_s3: the velocity random walk of a held DR step (no DVL sample for more than hold_grace_s, so
    the last velocity is carried on: bottom lock lost); deviation_sigma_rad: the initial sigma of each of the
    four coefficients of a compass deviation with heading (0: no such states); turn_sigma_rad_per_sqrt_rad: the
    heading error's walk per square root of a radian turned (a deviation with heading, without states: after
    a turn the heading error is less known, so the filter learns the new one from the ranges);
    range_scale_sigma: the initial sigma of a range-scale error k shared by every link, each range measuring
    (1 + k) times the true one (a sound-speed error of 0.1-1 %; 0: no such state); deviation_link_gate: with the
    deviation states, a range leaves them as they are (a Schmidt update: they are considered, not estimated)
    while its link's running mean of standardized innovations is beyond this many sigmas more than every other
    link's (a bias on one link, multipath, is not a property of the heading; 0: no such gate).
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
    hold_q_m2_per_s3: float = 0.0
    hold_grace_s: float = 2.0
    deviation_sigma_rad: float = 0.0
    turn_sigma_rad_per_sqrt_rad: float = 0.0
    range_scale_sigma: float = 0.0
    deviation_link_gate: float = 0.0


class DrErrorModel:
    """The DR error (d_n, d_e, heading error, scale error[, deviation]) of one follower, updated by ranges and fixes.

    With ``deviation_sigma_rad`` > 0 the heading error is psi + a1·sin h + b1·cos h + a2·sin 2h + b2·cos 2h
    at heading h: a compass's deviation, one- and two-cycle with heading, whose constant coefficients are
    four more states (so the filter learns the deviation over the turns instead of taking each turn's change
    of heading error as a new error). Plain floats rather than numpy matrices: it runs once per range epoch,
    where a small numpy product costs more in call overhead than in arithmetic
    (tests/test_dr_error_model.py checks it against the matrix filter).
    """

    def __init__(self, params: DrErrorParams) -> None:
        """Start at x = 0 with P = diag(p0_m², heading_sigma², scale_sigma²[, deviation_sigma² x 4])."""
        c = params
        self.deviation = float(c.deviation_sigma_rad) > 0.0
        scaled = float(c.range_scale_sigma) > 0.0
        self.n = (8 if self.deviation else 4) + scaled
        # the range-scale state is the last; it does not move d (its columns of G stay 0)
        self.ks = self.n - 1 if scaled else -1
        self.q = (float(c.q_m2_per_s), float(c.q_m2_per_s), float(c.heading_walk_rad_per_sqrt_s) ** 2,
                  float(c.scale_walk_per_sqrt_s) ** 2) + (0.0,) * (self.n - 4)
        self.hold_q = float(c.hold_q_m2_per_s3)
        self.hold_grace_s = float(c.hold_grace_s)
        self.turn_q = float(c.turn_sigma_rad_per_sqrt_rad) ** 2
        self._heading: float | None = None
        self.r_var = float(c.range_sigma_m) ** 2
        self.lag_s = float(c.lag_s)
        self.gate_sigma = float(c.gate_sigma)
        self.gate_cap = int(c.gate_cap)
        self.link_gate = float(c.deviation_link_gate) if self.deviation else 0.0
        self._link_mean: dict[str, float] = {}          # running mean of standardized innovations, per leader
        self.x = [0.0] * self.n
        diag = (float(c.p0_m[0]) ** 2, float(c.p0_m[1]) ** 2, float(c.heading_sigma_rad) ** 2,
                float(c.scale_sigma) ** 2) + (float(c.deviation_sigma_rad) ** 2,) * (4 * self.deviation) \
            + (float(c.range_scale_sigma) ** 2,) * scaled
        self.p = [[diag[i] if i == j else 0.0 for j in range(self.n)] for i in range(self.n)]
        # since the last propagation: G's entries (rows 0, 1 of the columns of states 2..n-1), dt, the
        # held position variance (m²) and the heading turned (rad)
        self._g = [0.0] * (2 * self.n - 4)
        self._dt = self._held = self._turned = 0.0
        # the same summed since the start (G's entries, dt, held variance, turned), for the lagged prediction
        self._cum: tuple[float, ...] = (0.0,) * (2 * self.n - 1)
        # t, x, P, cum: the states of the last lag_s and the newest older one
        self._snaps: deque[tuple[float, list[float], list[list[float]], tuple[float, ...]]] = deque()
        self._gated_out: dict[str, int] = {}          # gated ranges left out in a row, per leader
        self._fixes_out = 0                             # gated fixes left out in a row
        self.last_fix_s = -math.inf                     # time of the last position fix taken

    def step(self, dt_s: float, north_m: float, east_m: float, age_s: float = 0.0, heading_rad: float = 0.0) -> None:
        """One DR step of dt_s seconds that moved the DR position by (north_m, east_m).

        ``age_s``: the age, at the step's end, of the DR sample whose velocity it carried (beyond
        ``hold_grace_s`` the step is held: the velocity error walks, its position variance grows as age³);
        ``heading_rad``: the step's heading (the deviation states' sines and cosines).
        """
        g = self._g
        # a heading error psi turns the step (n, e) by psi: psi·(-e, n); a scale error s stretches it: s·(n, e)
        g[0] -= east_m
        g[1] += north_m
        g[2] += north_m
        g[3] += east_m
        if self.turn_q > 0.0:
            if self._heading is not None:
                self._turned += abs(math.remainder(heading_rad - self._heading, math.tau))
            self._heading = heading_rad
        if self.deviation:
            s1, c1 = math.sin(heading_rad), math.cos(heading_rad)
            for k, f in enumerate((s1, c1, 2.0 * s1 * c1, c1 * c1 - s1 * s1)):
                g[4 + 2 * k] -= f * east_m
                g[5 + 2 * k] += f * north_m
        self._dt += dt_s
        if self.hold_q > 0.0 and age_s > self.hold_grace_s:
            a1 = age_s - self.hold_grace_s
            a0 = max(a1 - dt_s, 0.0)
            self._held += self.hold_q * (a1 ** 3 - a0 ** 3) / 3.0

    def _propagate(self) -> None:
        g, dt, held = self._g, self._dt, self._held
        if dt == 0.0 and held == 0.0 and self._turned == 0.0 and not any(g):
            return
        p, q, n = self.p, self.q, self.n
        for i in range(n):
            p[i][i] += q[i] * dt
        p[0][0] += held
        p[1][1] += held
        p[2][2] += self.turn_q * self._turned
        self.x = _moved(self.x, g)
        # F·P·Fᵀ with F = I + G: G adds rows 2..n-1 into rows 0 and 1, then the same for the columns
        row0, row1 = list(p[0]), list(p[1])
        for k in range(2, n):
            rk, g0, g1 = p[k], g[2 * k - 4], g[2 * k - 3]
            for j in range(n):
                row0[j] += g0 * rk[j]
                row1[j] += g1 * rk[j]
        p[0], p[1] = row0, row1
        for row in p:
            a = b = 0.0
            for k in range(2, n):
                a += g[2 * k - 4] * row[k]
                b += g[2 * k - 3] * row[k]
            row[0] += a
            row[1] += b
        c = self._cum
        self._cum = tuple(c[i] + g[i] for i in range(len(g))) + (c[-3] + dt, c[-2] + held, c[-1] + self._turned)
        self._g = [0.0] * len(g)
        self._dt = self._held = self._turned = 0.0

    def _forget(self, t_s: float) -> None:
        """Drop the states that a newer one at least lag_s old (at t_s) replaces."""
        snaps, cutoff = self._snaps, t_s - self.lag_s
        while len(snaps) > 1 and snaps[1][0] <= cutoff:
            snaps.popleft()

    def _remember(self, t_s: float) -> None:
        """Keep this state for the lagged prediction (memory bounded even if only fixes come)."""
        self._snaps.append((float(t_s), list(self.x), [list(row) for row in self.p], self._cum))
        self._forget(t_s)

    def _lagged(self, t_s: float, h0: float, h1: float, r: float) -> tuple[float, float] | None:
        """h·x and h·P·hᵀ of the state of lag_s ago (the newest at least that old) carried forward, or None."""
        self._forget(t_s)
        snaps = self._snaps
        if not snaps or snaps[0][0] > t_s - self.lag_s:
            return None
        _, x, p, cum = snaps[0]
        c, n = self._cum, self.n
        d = [c[i] - cum[i] for i in range(len(c))]
        dt, held, turned = d[-3], d[-2], d[-1]
        # g = Fᵀ·hᵀ: h on d, and on each state k >= 2 the sum of h along its column of G
        g = [h0, h1] + [h0 * d[2 * k - 4] + h1 * d[2 * k - 3] for k in range(2, n)]
        if self.ks >= 0:
            g[self.ks] = r
        hx = sum(g[i] * x[i] for i in range(n))
        # h·F·(P + Q dt)·Fᵀ·hᵀ = g·(P + Q dt)·gᵀ (the noise of the whole interval put at its start, the held
        # variance too: a bound rather than the exact sum over the steps)
        q = self.q
        var = sum(g[i] * (sum(p[i][j] * g[j] for j in range(n)) + q[i] * dt * g[i]) for i in range(n))
        # the turns' heading walk too, at the interval's start: it turns the whole displacement
        var += held * (h0 * h0 + h1 * h1) + self.turn_q * turned * g[2] * g[2]
        return hx, var

    def range(self, t_s: float, leader: str, z_m: float, north_m: float, east_m: float,
              repeated: bool) -> LaggedResidual:
        """Range z (m) to a leader, the DR position minus the leader being (north_m, east_m): residuals, then update."""
        self._propagate()
        r = math.hypot(north_m, east_m)
        if not r > 0.0 or not math.isfinite(z_m):
            return LaggedResidual(NAN, NAN, NAN, NAN)
        h0, h1 = -north_m / r, -east_m / r
        x, p, n, ks = self.x, self.p, self.n, self.ks
        # z ~ (1 + k)·(r + h·d) ~ r + h·d + k·r: the range-scale state's row of H is r
        ph = [p[i][0] * h0 + p[i][1] * h1 + (p[i][ks] * r if ks >= 0 else 0.0) for i in range(n)]
        s = h0 * ph[0] + h1 * ph[1] + (r * ph[ks] if ks >= 0 else 0.0) + self.r_var
        scale = r * x[ks] if ks >= 0 else 0.0
        v = z_m - r - (h0 * x[0] + h1 * x[1]) - scale
        lagged = self._lagged(t_s, h0, h1, r)
        vl = sl = NAN
        if lagged is not None:
            vl = z_m - r - lagged[0]
            sl = lagged[1] + self.r_var
        out = LaggedResidual(v, s, vl, sl, scale)
        gated = math.isfinite(vl) and abs(vl) > self.gate_sigma * math.sqrt(sl)
        gated_out = self._gated_out.get(leader, 0)
        considered = not repeated and self.link_gate > 0.0 and self._one_link(leader, v / math.sqrt(s))
        # a repeated range leaves the gate's count (of fresh ranges) as it was
        if not repeated and gated and gated_out < self.gate_cap:
            self._gated_out[leader] = gated_out + 1
        elif not repeated:
            self._gated_out[leader] = 0
            k = [ph[i] / s for i in range(n)]
            if considered:
                # Schmidt update: the deviation states (4-7) keep their value and covariance; the others take the
                # range with their optimal gain, and their cross-covariance with the deviation as usual
                for i in range(4, 8):
                    k[i] = 0.0
                self.x = [x[i] + k[i] * v for i in range(n)]
                self.p = [[p[i][j] if 4 <= i < 8 and 4 <= j < 8 else p[i][j] - (ph[i] * ph[j]) / s
                           for j in range(n)] for i in range(n)]
            else:
                self.x = [x[i] + k[i] * v for i in range(n)]
                self.p = [[p[i][j] - k[i] * ph[j] for j in range(n)] for i in range(n)]
        self._remember(t_s)
        return out

    def _one_link(self, leader: str, w: float) -> bool:
        """Take standardized innovation w into the leader's running mean: True if it stands out from every other link's.

        A compass deviation moves the DR error, which every link sees; a multipath bias is on one link and lasts
        30-300 s. The mean's weight 0.2 (about five ranges, 25 s of one leader) follows a bias within a minute
        and keeps a normal link's mean within about 0.35 sigma.
        """
        m = self._link_mean.get(leader, 0.0)
        m += 0.2 * (w - m)
        self._link_mean[leader] = m
        others = [abs(v) for ld, v in self._link_mean.items() if ld != leader]
        return abs(m) > self.link_gate + (max(others) if others else 0.0)

    def fix(self, t_s: float, north_m: float, east_m: float, cov_m2: tuple[float, float, float]) -> None:
        """A position fix: d measured as (north_m, east_m), DR minus the fix, with covariance (nn, ne, ee) m²."""
        self._propagate()
        p, x, n = self.p, self.x, self.n
        snn, sne, see = p[0][0] + cov_m2[0], p[0][1] + cov_m2[1], p[1][1] + cov_m2[2]
        det = snn * see - sne * sne
        if not det > 0.0:
            return
        inn, ine, iee = see / det, -sne / det, snn / det
        rn, re = north_m - x[0], east_m - x[1]
        # a fix beyond the gate (its Mahalanobis distance, 2 dof) is left out as a range is, at most gate_cap
        # in a row: one bad USBL fix taken moved the state 200 m and raised two minutes of false alarms on
        # both leaders (issue 26, docs/detection.md section 5); a real jump of the DR error is taken later
        d2 = rn * rn * inn + 2.0 * rn * re * ine + re * re * iee
        if d2 > self.gate_sigma ** 2 and self._fixes_out < self.gate_cap:
            self._fixes_out += 1
            return
        self._fixes_out = 0
        # K = P[:, :2]·S⁻¹ (n x 2); x += K·(fix - d); P -= K·P[:2, :]
        k = [(p[i][0] * inn + p[i][1] * ine, p[i][0] * ine + p[i][1] * iee) for i in range(n)]
        self.x = [x[i] + k[i][0] * rn + k[i][1] * re for i in range(n)]
        new = [[p[i][j] - k[i][0] * p[0][j] - k[i][1] * p[1][j] for j in range(n)] for i in range(n)]
        self.p = [[0.5 * (new[i][j] + new[j][i]) for j in range(n)] for i in range(n)]
        self.last_fix_s = float(t_s)
        self._remember(t_s)
