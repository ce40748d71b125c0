"""The side-by-side runner on small simulated trials: methods, training, isolation, cap, rejects, scoring."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest

from formats.geodesy import metric_scales_scalar
from replay.stack.config import AnfisConfig, StackConfig
from replay.stack.detectors.base import Decision
from replay.stack.runner import CooperativeRunner, EpochResult, RunnerOptions, RunResults, Start
from replay.stack.scoring import RESULT_KEYS, score_run
from replay.stack.training import TrainingSet

LAT, LON = math.radians(45.7), math.radians(126.6)
B0, A0 = metric_scales_scalar(LAT, 0.0)
OWN = ("dead_reckoning", "ckf", "ackf", "chi_square", "dual_threshold")
CONFIG = StackConfig(methods=OWN, training_window_s=300.0)


@dataclass
class Trial:
    """A simulated follower with two moving leaders (local metres), DR samples and range epochs."""

    t: np.ndarray
    north: np.ndarray
    east: np.ndarray
    dr: np.ndarray                          # (n, 3): forward, lateral, heading as measured
    epochs: list[tuple]                      # range_epoch arguments


def make_trial(seed: int = 0, duration: float = 700.0, stale: tuple = ((120, 160), (450, 500)),
               outlier_rate: float = 0.03) -> Trial:
    """Follower on a slow S-curve with a DVL bias; leaders 300-600 m away; stale ranges and outliers."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 0.5, 1.0)
    heading = 0.4 + 0.6 * np.sin(t / 120.0)
    speed = 1.5 + 0.2 * np.sin(t / 70.0)
    north = np.cumsum(np.r_[0.0, (speed * np.cos(heading))[1:]])
    east = np.cumsum(np.r_[0.0, (speed * np.sin(heading))[1:]])
    dr = np.c_[speed * 1.01 + rng.normal(0, 0.05, t.size), 0.04 + rng.normal(0, 0.05, t.size),
               heading + 0.004 + rng.normal(0, 0.002, t.size)]
    leaders = {"leader1": (450.0 + 0.5 * t, -200.0 + 0.8 * t), "leader2": (-300.0 + 1.0 * t, 500.0 + 0.2 * t)}
    epochs, held = [], {}
    for k, tk in enumerate(np.arange(2.5, duration, 2.5)):
        leader = "leader1" if k % 2 == 0 else "leader2"
        ln, le = (float(np.interp(tk, t, a)) for a in leaders[leader])
        truth = math.hypot(ln - np.interp(tk, t, north), le - np.interp(tk, t, east))
        z = truth + rng.normal(0.0, 3.0)
        for a, b in stale:                  # the modem repeats an old range: both leaders
            if a <= tk < b:
                z = held.setdefault((leader, a), z)
        if rng.random() < outlier_rate:
            z += rng.choice([-1.0, 1.0]) * rng.uniform(15.0, 40.0)
        slant = math.hypot(max(z, 0.0), 4.0)  # follower 4 m deep, leaders at the surface
        epochs.append((float(tk), leader, LAT + ln / B0, LON + le / A0, 0.0, slant, truth + rng.normal(0, 1.0)))
    return Trial(t, north, east, dr, epochs)


def run_trial(trial: Trial, config: StackConfig = CONFIG, **kwargs) -> tuple[CooperativeRunner, list]:
    """Push the trial through a runner in time order; returns the runner and every epoch's results."""
    runner = CooperativeRunner(config, "follower", ["leader1", "leader2"], Start(0.0, LAT, LON, 4.0),
                               RunnerOptions(**kwargs))
    out, k = [], 0
    for i in range(1, trial.t.size):
        while k < len(trial.epochs) and trial.epochs[k][0] <= trial.t[i]:
            out.append(runner.range_epoch(*trial.epochs[k]))
            k += 1
        runner.dead_reckon(trial.t[i], *trial.dr[i], 4.0)
    return runner, out


def gps(trial: Trial) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The follower's GPS track in radians."""
    return trial.t, LAT + trial.north / B0, LON + trial.east / A0


def test_side_by_side_run() -> None:
    trial = make_trial()
    runner, out = run_trial(trial)
    res = runner.finish()
    assert res.rejected == {} and res.trained and res.training_errors == {}
    assert all([r.method for r in rows] == list(OWN) for rows in out)
    assert len(out) == len(trial.epochs) and all(isinstance(r, EpochResult) for r in out[0])
    for rows in out:
        by = {r.method: r for r in rows}
        assert all(math.isnan(getattr(by["dead_reckoning"], f)) for f in ("f1", "f2", "f3"))
        if rows[0].time_s <= res.training_end_s:     # detectors silent, their ACKFs equal the plain ACKF
            for m in ("chi_square", "dual_threshold"):
                assert not by[m].flagged and (by[m].lat_rad, by[m].lon_rad) == (by["ackf"].lat_rad, by["ackf"].lon_rad)
        for r in rows:
            assert not (r.isolated or r.capped) or r.flagged
            assert r.cov_nn_m2 > 0 and r.cov_ee_m2 > 0 and r.label in (-1, 0, 1)
    ep = res.epochs
    assert ep["flagged"][(ep["method"] == "chi_square") & (ep["time_s"] > 300)].sum() > 0
    assert res.capped["chi_square"] == int(ep["capped"][ep["method"] == "chi_square"].sum())
    frame = res.epochs_frame()
    assert len(frame) == len(OWN) * len(trial.epochs)

    scores = score_run(res, *gps(trial))
    assert set(scores) == set(OWN) and all(set(RESULT_KEYS) <= set(v) for v in scores.values())
    dr, ackf, chi = scores["dead_reckoning"], scores["ackf"], scores["chi_square"]
    assert ackf["error_rms_m"] < dr["error_rms_m"]
    assert chi["error_rms_m"] < scores["ckf"]["error_rms_m"]
    assert chi["recall"] > 0.4 and chi["fpr"] < 0.1 and chi["auc"] > 0.75      # seed 0: 0.55, 0.043, 0.93
    assert scores["dual_threshold"]["recall"] >= chi["recall"] - 0.1


def test_tracks_cover_every_step() -> None:
    trial = make_trial(duration=120.0)
    runner, _ = run_trial(trial, replace(CONFIG, training_window_s=60.0))
    res = runner.finish()
    for track in res.tracks.values():
        # one record at the start, one per DR step, one per epoch; an epoch at a DR instant
        # (t = 5, 10, ...) already carried the state there, so that DR sample adds no record
        between = sum(e[0] not in set(trial.t) for e in trial.epochs)
        assert track.t_s.size == 1 + (trial.t.size - 1) + between
        assert np.all(np.diff(track.t_s) >= 0) and np.all(track.cov_m2[:, 0, 0] > 0)
    dr = res.tracks["dead_reckoning"]
    assert np.all(np.diff(dr.cov_m2[:, 0, 0]) >= -1e-9)          # DR only: uncertainty never shrinks


def test_range_epoch_carries_the_last_dr_sample() -> None:
    runner = CooperativeRunner(replace(CONFIG, methods=("dead_reckoning",)), "f", ["leader1"], Start(0.0, LAT, LON))
    assert runner.dead_reckon(1.0, 1.0, 0.0, 0.0, 0.0)           # 1 m north over (0, 1]
    (r,) = runner.range_epoch(3.0, "leader1", LAT + 300 / B0, LON + 400 / A0, 0.0, 500.0)
    assert abs((r.lat_rad - LAT) * B0 - 3.0) < 1e-6               # carried to t = 3 at 1 m/s
    assert runner.dead_reckon(3.0, 1.0, 0.0, 0.0, 0.0)           # same instant as the epoch: accepted
    assert runner.rejected == {}


def test_bad_inputs_are_rejected_and_counted() -> None:
    runner = CooperativeRunner(CONFIG, "f", ["leader1", "leader2"], Start(0.0, LAT, LON))
    leader = (LAT + 300 / B0, LON + 400 / A0, 0.0)
    assert runner.dead_reckon(1.0, 1.0, 0.0, 0.0, 0.0)
    assert not runner.dead_reckon(1.0, 1.0, 0.0, 0.0, 0.0)       # Δt = 0
    assert not runner.dead_reckon(0.5, 1.0, 0.0, 0.0, 0.0)       # Δt < 0
    assert not runner.dead_reckon(2.0, float("nan"), 0.0, 0.0, 0.0)
    assert not runner.dead_reckon(2.0, 1.0, 0.0, float("inf"), 0.0)
    assert runner.range_epoch(2.0, "leader1", *leader, float("nan")) == []
    assert runner.range_epoch(2.0, "leader1", *leader, float("inf")) == []
    assert runner.range_epoch(2.0, "leader1", *leader, 0.0) == []
    assert runner.range_epoch(2.0, "leader1", *leader, -20.0) == []
    assert runner.range_epoch(2.0, "leader1", float("nan"), LON, 0.0, 500.0) == []
    assert runner.range_epoch(2.0, "leader9", *leader, 500.0) == []
    assert runner.range_epoch(0.5, "leader1", *leader, 500.0) == []              # before the last sample
    assert runner.range_epoch(2.0, "leader1", LAT + 2.2 / B0, LON, 0.0, 3.0) == []  # leader on top (follower 2 m N)
    assert runner.range_epoch(2.0, "leader1", *leader[:2], 5.0, 2.0) != []         # |Δh| > r: clamped to 0, used
    assert runner.range_epoch(2.0, "leader1", *leader, 500.0, float("inf")) != []  # no truth: label -1
    res = runner.finish()
    assert res.rejected == {"dr_time_step_not_positive": 2, "dr_non_finite": 2, "range_non_finite": 3,
                            "range_not_positive": 2, "unknown_leader": 1, "range_time_backwards": 1,
                            "degenerate_geometry": 1}
    assert res.clamped_ranges == 1 and res.epochs["label"][-1] == -1
    for track in res.tracks.values():
        assert np.all(np.isfinite(track.lat_rad)) and np.all(np.isfinite(track.cov_m2))


def test_missed_slow_drift_recovers_with_the_isolation_cap() -> None:
    """A slow drift on both links is followed (missed); after it ends every range looks wrong.

    Without a cap the chi-square test rejects everything and the filter stays
    blind; with the cap (6) it re-acquires.
    """
    def final_errors(cap: int) -> tuple[float, float, int]:
        cfg = StackConfig(methods=("ackf", "chi_square"), training_window_s=100.0, q_m_per_s=(0.3, 0.3),
                          isolation_cap=cap)
        rng = np.random.default_rng(5)
        runner = CooperativeRunner(cfg, "f", ["l1", "l2"], Start(0.0, LAT, LON))
        n = e = 0.0
        errors = {}
        for k in range(1, 1201):
            t = float(k)
            heading = 0.5 * math.sin(t / 100)
            n, e = n + math.cos(heading), e + math.sin(heading)
            runner.dead_reckon(t, 1.0 + rng.normal(0, 0.05), 0.05 * math.cos(heading),
                               heading + rng.normal(0, 0.002), 0.0)
            if k % 5 == 0:
                leader, (ln, le) = ("l1", (400.0, 0.0)) if k % 10 == 0 else ("l2", (0.0, 400.0))
                truth = math.hypot(ln - n, le - e)
                z = truth + rng.normal(0, 1.0) + (0.06 * (t - 150) if 150 <= t < 650 else 0.0)
                r = runner.range_epoch(t, leader, LAT + ln / B0, LON + le / A0, 0.0, z, truth)[1]
                errors[t] = (math.hypot((r.lat_rad - LAT) * B0 - n, (r.lon_rad - LON) * A0 - e), r.flagged)
        flagged_in_drift = sum(f for t, (_, f) in errors.items() if 150 <= t < 600)
        return errors[600.0][0], errors[1200.0][0], flagged_in_drift
    at_end_of_drift, capped_final, missed = final_errors(6)
    assert at_end_of_drift > 20.0 and missed < 40          # the drift pulled the filter away, mostly unflagged
    blind_drift, blind_final, _ = final_errors(10 ** 6)
    assert blind_final > 40.0                             # blind: dead reckoning from a 30 m error
    assert capped_final < 10.0                            # re-acquired


class _Bias:
    """A compensating test detector: after training it always predicts a +25 m range error."""

    name = "anfis_compensation"

    def __init__(self, config: StackConfig) -> None:
        self.resets = 0

    def train_on(self, ts: TrainingSet) -> None:
        self.trained_on = len(ts)

    def decide(self, features: np.ndarray) -> Decision:
        return Decision(True, 25.0, 9.0, correction_m=25.0)

    def scores(self, features: np.ndarray) -> np.ndarray:
        return np.full(len(features), 25.0)

    def reset(self) -> None:
        self.resets += 1


def test_compensation_corrects_instead_of_isolating() -> None:
    trial = make_trial(stale=(), outlier_rate=0.0)
    trial.epochs = [(*e[:5], math.hypot(math.sqrt(e[5] ** 2 - 16) + (25.0 if e[0] > 300 else 0.0), 4.0), e[6])
                    for e in trial.epochs]                   # every range 25 m long after t_a
    cfg = replace(CONFIG, methods=("ackf", "anfis_compensation"))
    runner, out = run_trial(trial, cfg, factories={"anfis_compensation": _Bias})
    res = runner.finish()
    after = [rows[1] for rows in out if rows[1].time_s > 300]
    assert all(r.compensated and not r.isolated for r in after)
    assert all(abs(r.range_m + 25.0 - rows[0].range_m) < 1e-9 for r, rows in zip(after, [o for o in out if o[1].time_s > 300]))
    assert runner.detectors("anfis_compensation")["leader1"].resets == len([r for r in after if r.leader == "leader1"])
    scores = score_run(res, *gps(trial))
    assert scores["anfis_compensation"]["error_rms_m"] < 0.5 * scores["ackf"]["error_rms_m"]


def test_shared_and_per_leader_training() -> None:
    trial = make_trial(duration=400.0)
    shared_cfg = replace(CONFIG, anfis=AnfisConfig(model="shared"))
    runner, _ = run_trial(trial, shared_cfg)
    dets = runner.detectors("dual_threshold")
    assert dets["leader1"] is not dets["leader2"]
    np.testing.assert_array_equal(dets["leader1"].network.w1, dets["leader2"].network.w1)
    runner, _ = run_trial(trial, CONFIG)
    dets = runner.detectors("dual_threshold")
    assert not np.array_equal(dets["leader1"].network.w1, dets["leader2"].network.w1)


def test_leader_without_training_truth_is_reported_and_run_goes_on() -> None:
    trial = make_trial(duration=400.0)
    trial.epochs = [(*e[:6], float("nan")) if e[1] == "leader2" and e[0] <= 300 else e for e in trial.epochs]
    runner, out = run_trial(trial)
    res: RunResults = runner.finish()
    assert set(res.training_errors) == {"chi_square/leader2", "dual_threshold/leader2"}
    assert runner.detectors("chi_square")["leader2"] is None
    late = [r for rows in out for r in rows if r.leader == "leader2" and r.time_s > 300 and r.method == "chi_square"]
    assert late and not any(r.flagged for r in late)


def test_run_without_epochs_scores_cleanly() -> None:
    runner = CooperativeRunner(CONFIG, "f", ["leader1"], Start(0.0, LAT, LON))
    for k in range(1, 400):
        runner.dead_reckon(float(k), 1.0, 0.0, 0.0, 0.0)
    res = runner.finish()
    assert not res.epochs["time_s"].size and res.trained and set(res.training_errors) == {
        "chi_square/leader1", "dual_threshold/leader1"}
    gps_t = np.arange(0.0, 400.0)
    scores = score_run(res, gps_t, LAT + gps_t / B0, np.full(gps_t.size, LON))
    assert scores["chi_square"]["tp"] == 0 and scores["chi_square"]["auc"] is None
    assert scores["dead_reckoning"]["error_p50_m"] < 1e-3         # radii vary over the 400 m run


def test_factories_come_from_the_method_table_by_default() -> None:
    runner = CooperativeRunner(CONFIG, "f", ["leader1"], Start(0.0, LAT, LON))
    assert runner.parts.trainer._factories == {}


def test_position_fixes_update_every_filter_but_dead_reckoning() -> None:
    """USBL-like fixes pull the filters onto the truth; dead reckoning ignores them; bad fixes are counted."""
    trial = make_trial(seed=4, duration=400.0, stale=(), outlier_rate=0.0)
    runner = CooperativeRunner(CONFIG, "follower", ["leader1", "leader2"], Start(0.0, LAT, LON, 4.0))
    rng = np.random.default_rng(1)
    for i in range(1, trial.t.size):
        runner.dead_reckon(trial.t[i], *trial.dr[i], 4.0)
        if i % 5 == 0:
            n, e = trial.north[i] + rng.normal(0, 2.0), trial.east[i] + rng.normal(0, 2.0)
            assert runner.position_fix(trial.t[i], LAT + n / B0, LON + e / A0, 4.0, 0.0, 4.0)
    assert not runner.position_fix(trial.t[-1], float("nan"), LON, 4.0, 0.0, 4.0)
    assert not runner.position_fix(trial.t[-1], LAT, LON, 4.0, 5.0, 4.0)       # |ne| > sqrt(nn ee)
    assert not runner.position_fix(trial.t[-1] - 10.0, LAT, LON, 4.0, 0.0, 4.0)
    res = runner.finish()
    assert res.position_fixes == (trial.t.size - 1) // 5
    assert res.rejected == {"fix_non_finite": 1, "fix_covariance_not_positive": 1, "fix_time_backwards": 1}
    t, lat, lon = gps(trial)
    err = {}
    for name, track in res.tracks.items():
        dn = (np.interp(t, track.t_s, track.lat_rad) - lat) * B0
        de = (np.interp(t, track.t_s, track.lon_rad) - lon) * A0
        err[name] = float(np.median(np.hypot(dn, de)[t > 100]))
    assert err["ckf"] < 3.0 and err["ackf"] < 3.0 and err["chi_square"] < 3.0
    assert err["dead_reckoning"] > 3 * err["ckf"]          # the 1 % speed bias and heading bias grow
    assert np.all(res.tracks["ckf"].cov_m2[-1].diagonal() < 4.0)


def test_training_side_by_side_gives_the_same_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """Detectors trained side by side (4 forked processes, or 4 threads where there is no fork) give, epoch for
    epoch, what one process gives."""
    from replay.stack import training_window

    trial = make_trial(seed=2)
    config = replace(CONFIG, methods=OWN + ("anfis", "anfis_aqpso", "anfis_compensation"),
                     anfis=replace(CONFIG.anfis, iterations=20, epochs=20))
    runs = []
    for threads, fork in ((1, True), (4, True), (4, False)):
        monkeypatch.setattr(training_window, "can_fork", lambda fork=fork: fork)
        runner, _ = run_trial(trial, config, training_threads=threads)
        assert runner.parts.trainer.threads == threads
        runs.append(runner.finish())
    one = runs[0]
    assert one.trained and not one.training_errors
    for other in runs[1:]:
        assert other.training_errors == one.training_errors and other.thresholds == one.thresholds
        for key in one.epochs:
            np.testing.assert_array_equal(one.epochs[key], other.epochs[key], err_msg=key)
        for name in one.open_loop:
            np.testing.assert_array_equal(one.open_loop[name]["score"], other.open_loop[name]["score"])


def test_features_only_run_for_a_method_that_uses_them() -> None:
    """Without a new method the feature tracker is off: EXTRA_FEATURES NaN, every other field as with one."""
    from replay.stack.features import EXTRA_FEATURES

    trial = make_trial(seed=3)
    paper, _ = run_trial(trial, CONFIG)
    wide, _ = run_trial(trial, replace(CONFIG, methods=OWN + ("cusum_drift",)))
    a, b = paper.finish(), wide.finish()
    assert a.trained and b.trained and not a.training_errors
    keep = np.isin(b.epochs["method"], OWN)
    assert keep.sum() == a.epochs["method"].size > 200
    for key in a.epochs:
        if key in EXTRA_FEATURES:
            assert np.isnan(a.epochs[key].astype(float)).all(), key
        else:
            np.testing.assert_array_equal(a.epochs[key], b.epochs[key][keep], err_msg=key)
    assert np.isfinite(b.epochs["dr_residual_m"].astype(float)).mean() > 0.9
    assert np.isfinite(b.epochs["drift_z"].astype(float)).any()
    for name in a.open_loop:
        np.testing.assert_array_equal(a.open_loop[name]["score"], b.open_loop[name]["score"], err_msg=name)
    assert np.isnan(a.training_set.columns(EXTRA_FEATURES)).all()
