"""Benchmark the CKF/ACKF hot paths and a whole simulated trial through the side-by-side runner.

Prints, side by side in one run (medians of repeats):

1. one ACKF range update (prediction, innovation, adaptive factor, gain,
   state and covariance) on the scalar fast path against the general numpy
   CKF functions, and one dead-reckoning time update likewise;
2. the sample lake trial (``samples.simulate_trial``, seed 0, 1700 s, two
   leaders) pushed through ``CooperativeRunner``: wall time per trial with the
   methods of this module alone and with all eight methods (ANFIS included),
   at the simulator's DVL rate and with the DVL resampled to 5 Hz;
3. the trial's scores per method (600-1700 s), for orientation only.

Run: ``.venv/bin/python bench/bench_ckf.py``.
"""

from __future__ import annotations

import math
import statistics
import time
import timeit
from collections.abc import Callable

import numpy as np

from formats.geodesy import metric_scales_scalar
from replay.stack import model
from replay.stack.config import StackConfig
from replay.stack.filters import ckf
from replay.stack.filters.ckf import State2
from replay.stack.methods import default_names
from replay.stack.runner import CooperativeRunner, RunResults, Start

LAT, LON = math.radians(45.7), math.radians(126.6)
OWN = ("dead_reckoning", "ckf", "ackf", "chi_square", "dual_threshold")


def median_us(fn: Callable[[], object], number: int = 20000, repeat: int = 7) -> float:
    """Median over repeats of the mean time per call, in microseconds."""
    return statistics.median(timeit.repeat(fn, number=number, repeat=repeat)) / number * 1e6


def micro() -> None:
    """One ACKF range update and one DR time update: scalar fast path vs general numpy CKF."""
    b, a = metric_scales_scalar(LAT, 0.0)
    s = State2(LAT, LON, 2.0 / b ** 2, 0.3 / (a * b), 1.5 / a ** 2)
    leader = (LAT + 300.0 / b, LON + 400.0 / a, 1.5)
    z, r_var = 512.0, 9.0
    r_mat = np.array([[r_var]])
    h = lambda pts: model.horizontal_range(pts, 2.5, *leader)[..., None]          # noqa: E731
    x, p = s.x, s.p

    def fast_update() -> State2:
        return ckf.range_update(s, ckf.range_innovation(s, z, leader, 2.5, r_var), r_var, adaptive=True)

    def general_update() -> tuple[np.ndarray, np.ndarray]:
        inn = ckf.ckf_innovation(x, p, np.array([z]), h, r_mat)
        return ckf.ckf_update(x, p, inn, r_mat, ckf.adaptive_factor(inn.residual, inn.pzz))

    q = ckf.process_noise(x, 0.2, (1.0, 1.0), 2.5)
    f = lambda pts: model.dead_reckon_step(pts, 0.2, 1.5, 0.05, 0.7, 2.5)         # noqa: E731
    rows = [
        ("ACKF range update", median_us(fast_update), median_us(general_update, number=4000)),
        ("DR time update", median_us(lambda: ckf.dr_predict(s, 0.2, 1.5, 0.05, 0.7, 2.5, (1.0, 1.0))),
         median_us(lambda: ckf.ckf_predict(x, p, f, q), number=4000)),
    ]
    print("one filter step (µs, median of 7 repeats)")
    print(f"  {'step':<20}{'scalar path':>12}{'numpy CKF':>12}{'ratio':>8}")
    for name, fast, slow in rows:
        print(f"  {name:<20}{fast:>12.2f}{slow:>12.2f}{slow / fast:>8.1f}x")


def load_trial() -> object:
    """The simulated lake trial (seed 0)."""
    from samples.scenario import Scenario
    from samples.simulator import simulate_trial
    return simulate_trial(Scenario(), 0)


def dr_samples(trial: object, rate_hz: float | None) -> np.ndarray:
    """Follower DR samples (t, forward, lateral, heading rad, depth), optionally resampled to rate_hz."""
    fol = next(v for v in trial.vehicles if v.role == "follower")
    d = fol.dvl
    t = d.t_s if rate_hz is None else np.arange(d.t_s[0], d.t_s[-1] + 1e-9, 1.0 / rate_hz)
    heading = np.unwrap(np.radians(d.heading_deg))
    cols = [np.interp(t, d.t_s, v) for v in (d.forward_mps, d.starboard_mps, heading)]
    depth = np.interp(t, fol.ins.t_s, fol.ins.depth_m)
    return np.c_[t, cols[0], cols[1], cols[2], depth]


def drive(trial: object, samples: np.ndarray, methods: tuple[str, ...]) -> tuple[float, RunResults]:
    """Push DR samples and range epochs in time order; returns wall seconds and the results."""
    r = trial.ranges
    fol = next(v for v in trial.vehicles if v.role == "follower")
    epochs = list(zip(r.t_s.tolist(), [str(x) for x in r.leader], np.radians(r.leader_ins_lat_deg).tolist(),
                      np.radians(r.leader_ins_lon_deg).tolist(), r.leader_depth_m.tolist(), r.range_m.tolist(),
                      r.z_gps_m.tolist()))
    rows = samples.tolist()
    cfg = StackConfig(methods=methods)
    start = time.perf_counter()
    runner = CooperativeRunner(cfg, "follower", ["leader1", "leader2"], Start(
        rows[0][0], math.radians(fol.gps.lat_deg[0]), math.radians(fol.gps.lon_deg[0]), rows[0][4]))
    k = 0
    for row in rows[1:]:
        while k < len(epochs) and epochs[k][0] <= row[0]:
            runner.range_epoch(*epochs[k])
            k += 1
        runner.dead_reckon(*row)
    results = runner.finish()
    return time.perf_counter() - start, results


def whole_trial(trial: object) -> RunResults:
    """Wall time of whole trials at two DVL rates, own methods vs all eight."""
    print("\nwhole trial through CooperativeRunner (s, median of 3 runs)")
    print(f"  {'DVL rate':<12}{'DR samples':>11}{'epochs':>8}{'5 methods':>11}{'8 methods':>11}{'ratio':>8}")
    keep = None
    for rate in (None, 5.0):
        samples = dr_samples(trial, rate)
        own = statistics.median(drive(trial, samples, OWN)[0] for _ in range(3))
        runs = [drive(trial, samples, default_names()) for _ in range(3)]
        full = statistics.median(t for t, _ in runs)
        keep = keep or runs[0][1]
        label = "sim (1 Hz)" if rate is None else f"{rate:g} Hz"
        print(f"  {label:<12}{len(samples) - 1:>11}{trial.ranges.t_s.size:>8}{own:>11.3f}{full:>11.3f}"
              f"{full / own:>8.1f}x")
    samples = dr_samples(trial, None)
    base = statistics.median(drive(trial, samples, ("ackf",))[0] for _ in range(3))
    print(f"\n  cost of each detecting method at the sim rate (s; ackf alone = {base:.3f}, training included)")
    for m in default_names()[3:]:
        t = statistics.median(drive(trial, samples, ("ackf", m))[0] for _ in range(3))
        print(f"  {m:<20}{t - base:>8.3f}")
    return keep


def score_table(trial: object, results: RunResults) -> None:
    """The trial's scores per method after t_a (orientation only; the reproduction is elsewhere)."""
    from replay.stack.scoring import score_run
    fol = next(v for v in trial.vehicles if v.role == "follower")
    scores = score_run(results, fol.gps.t_s, np.radians(fol.gps.lat_deg), np.radians(fol.gps.lon_deg))
    print("\nsample trial seed 0, 600-1700 s (closed loop; AUC / recall@5% open loop on ackf features)")
    print(f"  {'method':<20}{'TP':>4}{'TN':>5}{'FP':>4}{'FN':>4}{'FPR':>7}{'FNR':>7}{'AUC':>7}{'R@5%':>7}"
          f"{'p50 m':>8}{'p90 m':>8}{'RMS m':>8}{'capped':>7}")
    fmt = lambda v, w, p: f"{'-':>{w}}" if v is None else f"{v:>{w}.{p}f}"           # noqa: E731
    for m, s in scores.items():
        counts = "".join(f"{'-' if s[k] is None else s[k]:>{w}}" for k, w in (("tp", 4), ("tn", 5), ("fp", 4),
                                                                               ("fn", 4)))
        print(f"  {m:<20}{counts}{fmt(s['fpr'], 7, 3)}{fmt(s['fnr'], 7, 3)}{fmt(s['auc'], 7, 3)}"
              f"{fmt(s['recall_at_fpr_5'], 7, 3)}{fmt(s['error_p50_m'], 8, 2)}{fmt(s['error_p90_m'], 8, 2)}"
              f"{fmt(s['error_rms_m'], 8, 2)}{s['capped']:>7}")
    print(f"  rejected: {results.rejected or 'none'}; clamped ranges: {results.clamped_ranges}; "
          f"training errors: {results.training_errors or 'none'}")


def main() -> None:
    """Run every section."""
    micro()
    trial = load_trial()
    score_table(trial, whole_trial(trial))


if __name__ == "__main__":
    main()
