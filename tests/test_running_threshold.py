"""The running closed-loop threshold (replay.stack.running_threshold): it holds a false-alarm rate per stream."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.config import StackConfig
from replay.stack.detectors.base import Decision
from replay.stack.running_threshold import RunningThreshold

H = 2.5
CFG = StackConfig()
GAIN, SHARE, BAND = CFG.running_threshold_gain, CFG.running_threshold_share, CFG.running_threshold_band


def _run(scores: np.ndarray, config: StackConfig | None = None, start: float = 1.0) -> tuple[np.ndarray, RunningThreshold]:
    """Each score decided against H through one running threshold: the flags and the tracker."""
    rt = RunningThreshold(config or StackConfig(), start)
    flags = np.array([rt.decide(Decision(bool(s > H), float(s), H)).flagged for s in scores])
    return flags, rt


def _half_normal(n: int, sigma: float, seed: int) -> np.ndarray:
    return np.abs(np.random.default_rng(seed).normal(0.0, sigma, n))


def test_a_heavier_trial_than_the_threshold_assumed_is_brought_back_near_the_share() -> None:
    """Scores 1.3x wider than H's 2 % (|N(0, 1.3 * 1.0)| > 2.5: 5.4 %): the running threshold flags 2-3 % instead."""
    assert (SHARE, BAND) == (0.025, 1.3)
    s = _half_normal(3000, 1.3 * H / 2.326, seed=1)
    fixed = np.mean(s > H)
    flags, rt = _run(s)
    assert fixed > 0.045
    assert 0.015 < np.mean(flags[500:]) < 0.035 and rt.g > 1.1


def test_a_trial_whose_threshold_is_too_high_comes_down_slowly_and_not_under_its_floor() -> None:
    """Scores half as wide: no marginal exceedance, so g falls by gain * share per epoch, then rests on its floor."""
    s = _half_normal(2000, 0.5 * H / 2.326, seed=2)
    assert not np.any(s > H)
    _, rt = _run(s[:200])
    assert rt.g == pytest.approx(math.exp(-GAIN * SHARE * 200))
    _, rt = _run(s)
    assert rt.g == rt.low == pytest.approx(0.6)


def test_an_anomaly_far_beyond_the_threshold_does_not_mask_itself() -> None:
    """A run of scores beyond band * h (a grown drift) is flagged throughout and moves g only by its slow fall."""
    rt = RunningThreshold(StackConfig(), 1.0)
    g0 = rt.g
    out = [rt.decide(Decision(True, 20.0, H)) for _ in range(50)]
    assert all(d.flagged for d in out)
    assert rt.g == pytest.approx(g0 * math.exp(-GAIN * SHARE * 50))


def test_a_burst_of_marginal_exceedances_raises_it_within_a_few_epochs() -> None:
    """Ten scores just over the threshold in a row: g rises by exp(gain * (1 - share)) each; the tenth is not flagged."""
    rt = RunningThreshold(StackConfig(), 1.0)
    out = [rt.decide(Decision(True, 1.1 * H, H)) for _ in range(10)]
    assert out[0].flagged and not out[-1].flagged
    assert out[1].threshold == pytest.approx(H * math.exp(GAIN * (1 - SHARE)))


def test_an_epoch_that_does_not_step_down_raises_it_when_marginal_and_never_lowers_it() -> None:
    """``steps_down`` False (stale_aware's stale ranges, cut at T1 whatever g is): only a marginal flag moves g."""
    rt = RunningThreshold(StackConfig(), 1.0)
    for s in (0.5, 3 * H, 0.0, 20.0):           # under the threshold and beyond the band: g stays
        rt.decide(Decision(bool(s > H), s, H, steps_down=False))
        assert rt.g == 1.0
    rt.decide(Decision(True, 1.1 * H, H, steps_down=False))
    assert rt.g == pytest.approx(math.exp(GAIN * (1 - SHARE)))
    g = rt.g
    rt.decide(Decision(False, 0.5, H))          # an ordinary epoch steps down as before
    assert rt.g == pytest.approx(g * math.exp(-GAIN * SHARE))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.one_of(st.floats(0, 50), st.just(math.nan)), min_size=1, max_size=60))
def test_off_it_is_the_detectors_decision_and_a_nan_score_moves_nothing(scores: list[float]) -> None:
    off = RunningThreshold(replace(StackConfig(), running_threshold_gain=0.0), 1.0)
    on = RunningThreshold(StackConfig(), 1.0)
    for s in scores:
        d = Decision(bool(s > H), s, H)      # NaN compares False: not flagged
        assert off.decide(d) == d
        g = on.g
        got = on.decide(d)
        if math.isnan(s):
            assert got == d and on.g == g
        else:
            assert got.flagged == (s > got.threshold) and got.threshold == pytest.approx(g * H)


def test_it_starts_at_the_lower_of_calibrated_and_configured() -> None:
    cfg = StackConfig()
    assert RunningThreshold.for_detector(cfg, 4.0).g == pytest.approx(2.5 / 4.0)
    assert RunningThreshold.for_detector(cfg, 2.2).g == 1.0
    assert RunningThreshold.for_detector(cfg, math.nan).g == 1.0
