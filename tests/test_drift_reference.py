"""The stiff reference (features.StiffReference, drift_source "stiff"), the drift_reference detector and the run id of a given training set."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from recorders.manifest import load_manifest
from recorders.record import record
from replay.run.config import load_config
from replay.run.evaluate import TrialScores, TrialSpec, closed_loop_fpr
from replay.run.pipeline import replay_archive
from replay.stack.config import FeatureConfig, StackConfig
from replay.stack.detectors.drift_reference import DriftReferenceDetector
from replay.stack.features import EXTRA_FEATURES, FEATURE_NAMES, FeatureTracker, StiffReference
from replay.stack.methods import METHOD_TABLE
from replay.stack.training import TrainingSet

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
COL = FEATURE_NAMES.index("drift_residual_m")
ZCOL = FEATURE_NAMES.index("drift_z")
METRES = StackConfig(drift_reference_input="drift_residual_m")     # the first form (586eecb): |residual| in metres
LAT, LON = math.radians(45.7), math.radians(126.6)


class MatrixReference:
    """The slow obvious Kalman filter (numpy matrices) the scalar StiffReference must equal."""

    def __init__(self, q: float, r_m: float, p0_m: tuple[float, float]) -> None:
        self.q, self.r = q, r_m ** 2
        self.x = np.zeros(2)
        self.p = np.diag(np.square(p0_m)).astype(float)

    def propagate(self, dt: float) -> None:
        self.p = self.p + self.q * dt * np.eye(2)

    def range(self, z: float, north: float, east: float, use: bool) -> float:
        rng = math.hypot(north, east)
        h = -np.array([north, east]) / rng
        v = z - rng - h @ self.x
        if use:
            s = h @ self.p @ h + self.r
            k = self.p @ h / s
            self.x = self.x + k * v
            self.p = (np.eye(2) - np.outer(k, h)) @ self.p
        return float(v)

    def fix(self, north: float, east: float, cov: np.ndarray) -> None:
        k = self.p @ np.linalg.inv(self.p + cov)
        self.x = self.x + k @ (np.array([north, east]) - self.x)
        self.p = (np.eye(2) - k) @ self.p


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(0.5, 5.0), st.floats(-400, 400), st.floats(-400, 400), st.floats(-20, 20),
                          st.booleans(), st.booleans()), min_size=1, max_size=40),
       st.floats(1e-5, 1e-1), st.floats(0.5, 10.0))
def test_stiff_reference_is_the_matrix_kalman_filter(steps: list[tuple[float, float, float, float, bool, bool]],
                                                     q: float, r_m: float) -> None:
    fast, slow = StiffReference(q, r_m, (1.0, 2.0), cap=3), MatrixReference(q, r_m, (1.0, 2.0))
    skipped = 0
    for dt, north, east, err, repeated, is_fix in steps:
        if math.hypot(north, east) < 1.0:
            continue
        fast.propagate(dt)
        slow.propagate(dt)
        if is_fix:
            cov = np.array([[4.0, 0.5], [0.5, 2.0]])
            fast.fix(north / 100, east / 100, (4.0, 0.5, 2.0))
            slow.fix(north / 100, east / 100, cov)
            continue
        z = math.hypot(north, east) + err
        use = not (repeated and skipped < 3)
        skipped = skipped + 1 if not use else 0
        assert fast.range("leader1", z, north, east, repeated) == pytest.approx(slow.range(z, north, east, use),
                                                                                  abs=1e-9)
        np.testing.assert_allclose(fast.d, slow.x, atol=1e-9)
        np.testing.assert_allclose([fast.p[0], fast.p[1], fast.p[2]], [slow.p[0, 0], slow.p[0, 1], slow.p[1, 1]],
                                   atol=1e-9)


def _geometry(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times and the follower-minus-leader vectors of two leaders ranged alternately every 2.4 s (orthogonal)."""
    t = 2.4 * np.arange(n)
    leader = np.arange(n) % 2
    north = np.where(leader == 0, 300.0, 20.0 * np.sin(t / 200.0))
    east = np.where(leader == 0, 20.0 * np.cos(t / 200.0), 300.0)
    return t, north, east


def test_stiff_reference_learns_a_dr_offset_but_not_a_minute_long_drift() -> None:
    """Noise-free ranges with a constant DR error: the innovation vanishes; then a 0.3 m/s ramp on one link shows.

    The filter's gain along a line of sight is about 1 % per range, so over
    60 s (12 ranges of that leader) it takes in only a small part of the
    ramp: the innovation stays above 85 % of it.
    """
    ref = StiffReference(3e-4, 3.0, (1.0, 1.0), cap=20)
    t, north, east = _geometry(900)
    offset = np.array([6.0, -4.0])       # DR minus truth (m)
    innov, before_onset = [], None
    onset = t[-1] - 60.0
    for k in range(t.size):
        if before_onset is None and t[k] > onset:
            before_onset = list(ref.d)
        if k:
            ref.propagate(t[k] - t[k - 1])
        u = np.array([north[k], east[k]]) / math.hypot(north[k], east[k])
        z = math.hypot(north[k], east[k]) - u @ offset
        drift = 0.3 * (t[k] - onset) if (k % 2 == 0 and t[k] > onset) else 0.0
        innov.append(ref.range(f"leader{k % 2 + 1}", z + drift, north[k], east[k], False))
    innov = np.array(innov)
    before = innov[(t > 1200.0) & (t <= t[-1] - 60.0)]
    assert np.max(np.abs(before)) < 0.5
    np.testing.assert_allclose(before_onset, offset, atol=0.1)
    last = innov[-2] if (t.size - 2) % 2 == 0 else innov[-1]
    ramp = 0.3 * 60.0
    assert 0.85 * ramp < last <= ramp + 0.5


def _rows(residual: np.ndarray, z: np.ndarray | None = None) -> np.ndarray:
    x = np.zeros((residual.size, len(FEATURE_NAMES)))
    x[:, COL] = residual
    x[:, ZCOL] = np.nan if z is None else z
    return x


@pytest.mark.parametrize(("pooled", "by_model"), [(True, True), (True, False), (False, False)])
def test_drift_z_is_the_residual_against_both_leaders_recent_non_repeated_residuals(pooled: bool,
                                                                                     by_model: bool) -> None:
    """drift_z against a slow reference: (x - median) / max(1.4826 MAD, floor) of the pooled drift residuals.

    Pooled (the default): the epochs aged lag_s..scale_pooled_window_s of both
    leaders with a finite residual and no repeated range; per leader
    (``scale_pooled`` False): that leader's aged lag_s..scale_window_s, repeated or not. NaN with fewer
    than scale_min_samples of them. Ranges are noisy, a fifth repeated. With ``scale_by_model`` (the
    default) x is first scaled to the range noise by the model's predicted sigma: x·r / sqrt(var). The
    range-scale state's share k·r is in x but not in the values remembered for the median (it is put back
    after the median).
    """
    cfg = replace(FeatureConfig(), scale_pooled=pooled, scale_by_model=by_model)
    tracker = FeatureTracker(cfg, ("leader1", "leader2"), (LAT, LON))
    assert tracker.model is not None
    model_range = tracker.model.range
    var: list[float] = []
    shares: list[float] = []

    def spied(*args: Any, **kwargs: Any) -> Any:
        res = model_range(*args, **kwargs)
        var.append(res.lagged_var_m2 if math.isfinite(res.lagged_m) else res.innovation_var_m2)
        shares.append(res.scale_m)
        return res

    tracker.model.range = spied  # type: ignore[method-assign]
    rng = np.random.default_rng(5)
    geos = {"leader1": (LAT + 4e-5, LON, 0.0), "leader2": (LAT, LON + 6e-5, 0.0)}
    ix, iz, irep = (EXTRA_FEATURES.index(n) for n in ("drift_residual_m", "drift_z", "repeat_count"))
    seen: list[tuple[float, str, float, bool]] = []
    last: dict[str, float] = {}
    t, checked = 0.0, 0
    for k in range(520):
        t += 2.4
        tracker.propagate(2.4, 0.0, 0.0, 0.0, 0.0)
        leader = f"leader{k % 2 + 1}"
        slant = last[leader] if leader in last and rng.random() < 0.2 else 250.0 + float(rng.normal(0, 3.0))
        last[leader] = slant
        out = tracker.epoch(t, leader, slant, slant, 0.0, geos[leader])
        x = out[ix] * 3.0 / math.sqrt(var[-1]) if by_model else out[ix]
        clean = (out[ix] - shares[-1]) * (3.0 / math.sqrt(var[-1]) if by_model else 1.0)
        window = cfg.scale_pooled_window_s if pooled else cfg.scale_window_s
        old = [x for s, ld, x, rep in seen if t - window <= s <= t - cfg.lag_s
               and (not rep if pooled else ld == leader)]
        if len(old) < cfg.scale_min_samples:
            assert math.isnan(out[iz])
        else:
            med = float(np.median(old))
            scale = max(1.4826 * float(np.median(np.abs(np.array(old) - med))), cfg.scale_floor_m)
            assert out[iz] == pytest.approx((x - med) / scale, rel=1e-9, abs=1e-9)
            checked += 1
        seen.append((t, leader, clean, out[irep] > 0))
    assert checked > 400 and sum(rep for *_, rep in seen) > 50
    assert max(abs(s) for s in shares) > 0.0


def test_z_threshold_is_configured_and_keeps_the_t1_floor() -> None:
    """An epoch flags only with |drift_z| > drift_reference_z and |x| > T1; training sets only the metres fallback."""
    rng = np.random.default_rng(4)
    n = 4000
    z = rng.normal(0.0, 1.0, n)
    x = 6.0 * z
    det = DriftReferenceDetector(StackConfig(drift_reference_z=2.5))
    assert det.threshold == det.threshold_z == 2.5
    det.train(_rows(x, z), x, np.zeros(n, int))
    assert det.threshold == det.threshold_z == 2.5
    flags = det.scores(_rows(x, z)) > det.threshold
    np.testing.assert_array_equal(flags, (np.abs(z) > 2.5) & (np.abs(x) > 9.0))
    assert flags.sum() > 20
    # a large z on a residual under T1 is not flagged; the same z beyond T1 is
    assert not det.decide(_rows(np.array([8.0]), np.array([9.0]))[0]).flagged
    assert det.decide(_rows(np.array([9.5]), np.array([9.0]))[0]).flagged
    # where drift_z is NaN the trained metres threshold (98 % of |N(0, 6)|) decides
    h_m = det.threshold_m
    assert h_m == pytest.approx(6.0 * 2.326, rel=0.08)
    assert not det.decide(_rows(np.array([h_m - 0.1]))[0]).flagged
    fallback = det.decide(_rows(np.array([h_m + 0.1]))[0])
    assert fallback.flagged and fallback.score == pytest.approx(h_m + 0.1) and fallback.threshold == h_m
    # the open-loop score ranks it on the z scale: above h_z exactly when beyond h_m
    assert det.scores(_rows(np.array([h_m + 0.1])))[0] == pytest.approx(2.5 * (h_m + 0.1) / h_m)
    with pytest.raises(ValueError, match="drift_reference_z"):
        DriftReferenceDetector(StackConfig(drift_reference_z=0.0))


def test_threshold_gives_the_target_false_alarm_rate_on_training() -> None:
    rng = np.random.default_rng(3)
    n = 4000
    residual = rng.normal(0.0, 6.0, n)
    labels = (rng.random(n) < 0.1).astype(int)
    residual[labels == 1] += 30.0
    det = DriftReferenceDetector(METRES)
    det.train(_rows(residual), residual, labels)
    normal = np.abs(residual[labels == 0])
    rate = float(np.mean(normal > det.threshold))
    assert abs(rate - 0.02) <= 3 * math.sqrt(0.02 * 0.98 / normal.size)
    # the quantile of |N(0, 6)| at 98 % is 6 * 2.326
    assert det.threshold == pytest.approx(6.0 * 2.326, rel=0.08)
    assert det.thresholds["training_alarm_rate"] == pytest.approx(rate)
    # a spread far under T1: the threshold stays at T1 (9 m)
    quiet = DriftReferenceDetector(METRES)
    quiet.train(_rows(rng.normal(0, 1.0, 500)), np.zeros(500), np.zeros(500, int))
    assert quiet.threshold == 9.0


@pytest.mark.parametrize("rate", [0.1, 0.3, 0.5, 1.0])
def test_detection_delay_on_a_ramp_is_threshold_over_rate(rate: float) -> None:
    """A residual rate·t sampled every 4.8 s is first flagged at the first sample past h / rate, then every one."""
    det = DriftReferenceDetector(METRES)
    det.threshold = 13.0
    t = 4.8 * np.arange(1, 200)
    flags = np.array([det.decide(row).flagged for row in _rows(rate * t)])
    first = t[np.argmax(flags)]
    assert first == pytest.approx(4.8 * math.floor(13.0 / rate / 4.8 + 1.0))
    assert first - 13.0 / rate <= 4.8
    assert flags[t >= first].all() and not flags[t < first].any()
    np.testing.assert_allclose(det.scores(_rows(-rate * t)), rate * t)


def test_drift_reference_is_registered_as_a_new_method() -> None:
    entry = METHOD_TABLE["drift_reference"]
    assert entry.kind == "detector" and entry.wide and not entry.default and entry.pooled_training
    assert entry.factory is not None
    det = entry.factory(StackConfig())
    assert isinstance(det, DriftReferenceDetector) and det.wide
    with pytest.raises(ValueError, match="drift_reference_input"):
        DriftReferenceDetector(StackConfig(drift_reference_input="f2"))
    why = det.explain(_rows(np.array([12.0]))[0])
    assert why.residual_m == 12.0 and why.flagged


def test_training_set_digest_follows_the_content() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(20, len(FEATURE_NAMES)))
    a = TrainingSet(x, np.zeros(20), np.zeros(20, int), ["leader1"] * 20, FEATURE_NAMES)
    b = TrainingSet(x.copy(), np.zeros(20), np.zeros(20, int), ["leader1"] * 20, FEATURE_NAMES)
    assert a.digest() == b.digest()
    x2 = x.copy()
    x2[3, 4] += 1e-9
    assert TrainingSet(x2, np.zeros(20), np.zeros(20, int), ["leader1"] * 20, FEATURE_NAMES).digest() != a.digest()
    assert TrainingSet(x, np.zeros(20), np.zeros(20, int), ["leader2"] * 20, FEATURE_NAMES).digest() != a.digest()
    assert a.select(np.arange(20) < 10).digest() != a.digest()


def test_a_given_training_set_is_part_of_the_run_id(tmp_path: Path) -> None:
    """Two runs of one archive and configuration trained on different given sets get different run ids."""
    archive = tmp_path / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), archive)
    fast = ["methods=ackf,chi_square"]
    own = replay_archive(archive, load_config(None, fast), write_output=False)
    ts = own.results["follower"].training_set
    assert ts is not None and len(ts) > 20
    given = load_config(None, [*fast, "training_source=given"])
    a = replay_archive(archive, given, write_output=False, training_set=ts)
    again = replay_archive(archive, given, write_output=False, training_set=replace(ts))
    b = replay_archive(archive, given, write_output=False, training_set=ts.select(np.arange(len(ts)) % 2 == 0))
    assert a.run_id == again.run_id
    assert len({own.run_id, a.run_id, b.run_id}) == 3


def test_closed_loop_fpr_is_the_share_of_normal_epochs_flagged() -> None:
    def trial(flagged: list[bool], labels: list[int]) -> TrialScores:
        f, lab = np.array(flagged), np.array(labels, dtype=np.int8)
        kinds = np.zeros(lab.size, dtype=np.int16)
        return TrialScores(TrialSpec(0), ("ackf", "drift_reference"), ("drift_reference",),
                           {"drift_reference": f, "ackf": np.zeros(f.size, bool)},
                           {"drift_reference": lab, "ackf": lab}, {"drift_reference": kinds, "ackf": kinds},
                           {}, {}, {})
    trials = [trial([True, False, True, False], [0, 0, 1, 0]), trial([True, True], [0, 1])]
    assert closed_loop_fpr(trials, "drift_reference") == pytest.approx(2 / 4)
    assert closed_loop_fpr(trials, "ackf") is None
