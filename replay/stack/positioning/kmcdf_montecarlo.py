"""The Monte Carlo simulation of seed 003 section 4, vectorized over trials and seeded.

`N` nodes at `l [cos(2 pi i/N), sin(2 pi i/N)]` (N = 6) or
`sqrt(2) l [cos(2 pi i/N + pi/4), sin(...)]` (N = 4), `l = 800 m`; the target
uniform in the +-1000 m square; abnormal nodes drawn at random per trial.
KMCDF1: abnormal nodes have abnormal delays; KMCDF2: abnormal delays and
phases. Abnormal delays are uniform on (0, Rmax/c), abnormal phases on (-pi,
pi); normal errors Gaussian (eq. (4)). A trial succeeds when every parameter
state is estimated right: all 3N for KMCDF, the N delays for the delay-only
baselines (docs/design.md section 13).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from replay.stack.positioning.kmcdf import KmcdfParams, kmcdf_batch
from replay.stack.positioning.toa_baselines import BASELINES, BaselineResult, ear, gar, lhc, lms

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

METHODS: tuple[str, ...] = ("kmcdf1", "kmcdf2") + BASELINES
FIELD_HALF_WIDTH_M = 1000.0
LAYOUT_SCALE_M = 800.0


def node_layout(n_nodes: int, scale_m: float = LAYOUT_SCALE_M) -> FloatArray:
    """Node positions (N, 2) of seed 003 section 4: the N = 4 layout is the rotated sqrt(2) l square."""
    i = np.arange(n_nodes)
    angle = 2.0 * np.pi * i / n_nodes
    radius = scale_m
    if n_nodes == 4:
        angle, radius = angle + np.pi / 4.0, np.sqrt(2.0) * scale_m
    return radius * np.stack([np.cos(angle), np.sin(angle)], axis=-1)


@dataclass(frozen=True)
class SimBatch:
    """T simulated epochs with their truth."""

    node_xy: FloatArray          # (N, 2)
    target_xy: FloatArray        # (T, 2)
    delays_s: FloatArray         # (T, N)
    phase_x: FloatArray          # (T, N)
    phase_y: FloatArray          # (T, N)
    delay_abnormal: BoolArray    # (T, N)
    phase_abnormal: BoolArray    # (T, N) both phases of the node

    def truth_normal(self) -> BoolArray:
        """True parameter states (T, 3N) in the KMCDF order: delays, x phases, y phases."""
        return ~np.concatenate([self.delay_abnormal, self.phase_abnormal, self.phase_abnormal], -1)


def simulate(
    node_xy: FloatArray, n_abnormal: int, trials: int, abnormal_phases: bool,
    rng: np.random.Generator, params: KmcdfParams = KmcdfParams(),
) -> SimBatch:
    """Draw `trials` epochs with `n_abnormal` abnormal nodes each (eq. (1)-(4)).

    Every random array is drawn at full size whatever `n_abnormal` is, so the
    normal part of a seeded point does not depend on how many nodes go bad.
    """
    t, n = trials, node_xy.shape[0]
    c, kd0 = params.sound_speed_mps, params.kappa_d0
    target = rng.uniform(-FIELD_HALF_WIDTH_M, FIELD_HALF_WIDTH_M, size=(t, 2))
    d = target[:, None, :] - node_xy
    r = np.hypot(d[..., 0], d[..., 1])
    noise = rng.standard_normal(size=(3, t, n))
    delays = r / c + params.sigma_delay_s * noise[0]
    psi = kd0 * d[..., 0] / r + params.sigma_phase_rad * noise[1]
    phi = kd0 * d[..., 1] / r + params.sigma_phase_rad * noise[2]
    rank = np.argsort(np.argsort(rng.random(size=(t, n)), axis=-1), axis=-1)
    bad = rank < n_abnormal
    wild_delay = rng.uniform(0.0, params.max_range_m / c, size=(t, n))
    wild_phase = rng.uniform(-np.pi, np.pi, size=(2, t, n))
    delays = np.where(bad, wild_delay, delays)
    bad_phase = bad if abnormal_phases else np.zeros_like(bad)
    psi = np.where(bad_phase, wild_phase[0], psi)
    phi = np.where(bad_phase, wild_phase[1], phi)
    return SimBatch(node_xy, target, delays, psi, phi, bad, bad_phase)


def kmcdf_success(sim: SimBatch, params: KmcdfParams = KmcdfParams()) -> BoolArray:
    """Per trial: KMCDF judged all 3N parameter states right, (T,)."""
    batch = kmcdf_batch(sim.node_xy, sim.delays_s, sim.phase_x, sim.phase_y, params)
    return np.all(batch.normal == sim.truth_normal(), axis=-1)


def run_baseline(name: str, sim: SimBatch, params: KmcdfParams = KmcdfParams()) -> BaselineResult:
    """One delay-only baseline with the constants of seed 003 section 4, on the paper's field."""
    return delay_baseline(name, sim.node_xy, sim.delays_s, params)


def delay_baseline(
    name: str, node_xy: FloatArray, delays_s: FloatArray, params: KmcdfParams = KmcdfParams(), *,
    field_centre_xy: tuple[float, float] = (0.0, 0.0), field_half_width_m: float = FIELD_HALF_WIDTH_M,
    lhc_tolerance_m: float = 1e-6, lhc_max_iterations: int = 20000,
) -> BaselineResult:
    """One delay-only baseline on nodes (N, 2) and delays (T, N): GAR, EAR, LMS or LHC (seed 003 constants).

    The replay engine gives EAR a field around its own nodes and LHC a looser
    stopping rule (1 mm is plenty for a position; the Monte Carlo keeps 1e-6 m).
    """
    c, st = params.sound_speed_mps, params.sigma_delay_s
    ranges = c * delays_s
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        if name == "gar":
            return gar(node_xy, ranges, threshold_m2=5.76 * (c * st) ** 2)
        if name == "ear":
            return ear(node_xy, ranges, ring_width_m=6.0 * c * st, field_half_width_m=field_half_width_m,
                       field_centre_xy=field_centre_xy)
        if name == "lms":
            return lms(node_xy, ranges)
        if name == "lhc":
            return lhc(node_xy, ranges, huber_k_m=c * 1e-3, tolerance_m=lhc_tolerance_m,
                       max_iterations=lhc_max_iterations)
    raise ValueError(f"unknown baseline {name!r}")


def baseline_success(name: str, sim: SimBatch, params: KmcdfParams = KmcdfParams()) -> BoolArray:
    """Per trial: the baseline reached a decision and judged all N delay states right, (T,)."""
    result = run_baseline(name, sim, params)
    return result.resolved & np.all(result.normal == ~sim.delay_abnormal, axis=-1)


def point_rng(seed: int, n_nodes: int, n_abnormal: int, scenario: int) -> np.random.Generator:
    """An independent, reproducible stream per (layout, abnormal count, scenario)."""
    return np.random.default_rng(np.random.SeedSequence([seed, n_nodes, n_abnormal, scenario]))


def success_point(
    n_nodes: int, n_abnormal: int, method: str, trials: int, seed: int = 0,
    params: KmcdfParams = KmcdfParams(),
) -> float:
    """Success rate of one method at one abnormal-node count, from its own seeded draws.

    KMCDF1 and the baselines see the same draws (abnormal delays only);
    KMCDF2 sees draws with abnormal delays and phases.
    """
    node_xy = node_layout(n_nodes)
    scenario = 2 if method == "kmcdf2" else 1
    rng = point_rng(seed, n_nodes, n_abnormal, scenario)
    sim = simulate(node_xy, n_abnormal, trials, scenario == 2, rng, params)
    if method in ("kmcdf1", "kmcdf2"):
        return float(np.mean(kmcdf_success(sim, params)))
    return float(np.mean(baseline_success(method, sim, params)))


def success_curves(
    n_nodes: int, trials: int, seed: int = 0, params: KmcdfParams = KmcdfParams(),
    methods: tuple[str, ...] = METHODS,
) -> dict[str, dict[int, float]]:
    """Success rate per method and abnormal-node count 0..N for one layout, in this process."""
    return {m: {k: success_point(n_nodes, k, m, trials, seed, params) for k in range(n_nodes + 1)}
            for m in methods}
