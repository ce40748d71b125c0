"""A closed-loop threshold that holds its false-alarm rate per trial: a running quantile of the trial's own scores.

A threshold set once on the training trial (`replay.stack.calibration`) does
not carry across trials: a trial's false-alarm rate is mostly whether the
DR error model had bursts (a compass turn, a lost bottom lock), and one
training trial's 98 % quantile is decided by whether *it* had one
(docs/detection.md section 5). So the methods marked ``calibrated`` decide
closed loop against a threshold that follows the trial's own scores,
causally, reading no truth (CFAR-style, as a radar holds its false-alarm
rate on the clutter around each cell):

- the threshold is the detector's own times a multiplier g, one per method
  and runner (every leader's epochs together: a burst of the DR error is
  the follower's, seen on every link);
- after each decided epoch g moves by Robbins-Monro's quantile step,
  ``log g += gain * (marginal - share)``, where *marginal* is an
  exceedance by less than ``band`` times the threshold: g settles where
  ``share`` of the epochs are marginal exceedances, so it rises within a
  few epochs of a burst of near-threshold scores and falls slowly
  (``gain * share`` per epoch) while there is none;
- an exceedance beyond ``band`` (1.3) times the threshold (an outlier, a
  grown drift) does not move it, so an anomaly does not mask itself; the
  share of marginal exceedances counts the anomalies' marginal starts
  too, so ``share`` (2.5 % of every epoch) is set on development trials
  for a false-alarm rate near 2 % (3.5 % with a band of 1.5 put it at the
  band's upper edge, 3 %);
- an epoch whose decision does not step down (``Decision.steps_down``
  False: `stale_aware`'s stale ranges, cut at T1 whatever g is, as their
  score is h·(|e|/T1)^8) raises g when it is a marginal exceedance and
  never lowers it: their false alarms (0.4-1.0 % of the normal epochs on
  development seeds) then hold g up as the drift test's do, where before
  each stale range lowered g by ``gain * share`` (docs/detection.md
  section 5, "Stale ranges in the running threshold's share");
- it starts at the lower of the calibrated threshold and the configured
  multiple (``drift_reference_z``) and never falls under ``floor`` times
  that: it rises in a few epochs but falls over hundreds, so starting
  high (a bursty training trial) would cost a whole trial's recall.

What it does not reach (docs/detection.md section 5): near its fixed
point g moves by ``gain * (p - share)`` per epoch, so a training
threshold 20 % too low takes most of a trial to correct; a stale range
judged by `stale_aware` against T1 moves with g^(1/8) only; under a
fresh USBL fix the label noise (ranges past T1 with no injected anomaly)
holds g up as an anomaly does.

It changes only the closed-loop decisions: the open-loop scores (ROC, FNR
at 1/2/5 %) are the detector's own. ``gain`` 0 turns it off (the calibrated
threshold, as before). Figures: docs/detection.md section 5.
"""

from __future__ import annotations

import math
from dataclasses import replace

from replay.stack.config import StackConfig
from replay.stack.detectors.base import Decision


class RunningThreshold:
    """One method's running threshold multiplier over a run's epochs (module docstring)."""

    def __init__(self, config: StackConfig, start: float = 1.0) -> None:
        """g starts at ``start`` (a multiple of the detector's threshold); the rest from the config."""
        self.gain = float(config.running_threshold_gain)
        self.share = float(config.running_threshold_share)
        self.band = float(config.running_threshold_band)
        self.low = float(config.running_threshold_floor) * float(start)
        self.g = float(start)
        self.decided = 0

    @classmethod
    def for_detector(cls, config: StackConfig, threshold: float) -> RunningThreshold:
        """Started at min(threshold, ``drift_reference_z``) / threshold: the lower of calibrated and configured."""
        z0 = float(config.drift_reference_z)
        start = min(1.0, z0 / threshold) if math.isfinite(threshold) and threshold > 0.0 else 1.0
        return cls(config, start)

    def decide(self, decision: Decision) -> Decision:
        """The decision against g times its threshold, then g's step (up only where ``steps_down`` is False);
        a NaN score is not flagged and moves nothing."""
        score, base = decision.score, decision.threshold
        if not (math.isfinite(score) and math.isfinite(base)):
            return decision
        h = self.g * base
        flagged = score > h
        marginal = flagged and score < self.band * h
        if marginal or decision.steps_down:
            self.g = max(self.low, self.g * math.exp(self.gain * (float(marginal) - self.share)))
        self.decided += 1
        return replace(decision, flagged=flagged, threshold=h)
