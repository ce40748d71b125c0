"""Dual-threshold test assisted by a BP neural network (seed A ref. 21 baseline, docs/design.md section 11).

The seed names the method (Zhao et al., Control and Decision 2020) but gives
no detail, so this is our exact form:

* **BP network** (numpy only): inputs u = (log(1 + f_i) - μ_i) / σ_i for the
  three features, with μ, σ from the training window (log because f2 and f3
  are heavy-tailed; no clipping, so values beyond the window still move the
  output); one hidden layer of ``config.dual_threshold_hidden`` tanh units;
  a linear output ê = σ_y · (w2ᵀ tanh(W1 u + b1) + b2) + μ_y predicting the
  range error magnitude |Z - Z_gps| (m). Trained by back-propagation on the
  mean squared error, full batch, Adam (step 0.01, 1500 iterations, L2 weight
  decay 1e-4), weights initialized from ``config.seed`` (Glorot uniform).
* **Threshold 1, abrupt faults**: f2 > χ²₁(1 - α) (the chi-square test).
* **Threshold 2, slow drift**: CUSUM of the predicted error,
  S_k = max(0, S_{k-1} + ê_k - k), alarm when S_k > h, with
  k = ``dual_threshold_cusum_k_m`` (the ranging sigma) and
  h = ``dual_threshold_cusum_h_m``. The CUSUM restarts after each alarm
  (the runner calls ``reset``).
* **Score** = max(f2 / χ²₁(1 - α), S_k / h), threshold 1: flagged when either
  test fires. Scaling both thresholds by one factor c is the same as
  comparing the score with c, which is what the ROC sweep does. Open-loop
  ``scores`` run the same sequence as closed loop (the CUSUM restarts
  whenever the score exceeds 1, i.e. at the configured alarm), only without
  isolation feeding back into the features; so the sweep moves the alarm
  threshold but not the restart level (without restarts, one outlier keeps
  the CUSUM high for tens of epochs and the curve says little).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from replay.events import EpochResult
from replay.stack.config import StackConfig
from replay.stack.detectors.base import Decision
from replay.stack.detectors.chi_square import chi_square_threshold
from replay.stack.detectors.why_text import cmp, num
from replay.stack.training import TrainingSet

BP_ITERATIONS: int = 1500
BP_STEP: float = 0.01
BP_WEIGHT_DECAY: float = 1e-4


@dataclass(frozen=True)
class BpNetwork:
    """A trained one-hidden-layer network and its input/output scaling."""

    w1: np.ndarray        # (3, hidden)
    b1: np.ndarray        # (hidden,)
    w2: np.ndarray        # (hidden,)
    b2: float
    in_mean: np.ndarray   # (3,) of log(1 + f)
    in_std: np.ndarray    # (3,)
    out_mean: float
    out_std: float

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Predicted range error magnitude (m) for features (n, 3); non-finite rows give NaN."""
        u = (np.log1p(np.maximum(np.asarray(features, float), 0.0)) - self.in_mean) / self.in_std
        y = np.tanh(u @ self.w1 + self.b1) @ self.w2 + self.b2
        return y * self.out_std + self.out_mean


def _scaling(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Column means and standard deviations, with σ = 1 for constant columns."""
    mean = x.mean(axis=0)
    std = x.std(axis=0)
    return mean, np.where(std > 1e-12, std, 1.0)


def train_bp(features: np.ndarray, target: np.ndarray, hidden: int, seed: int) -> BpNetwork:
    """Fit the network to (features (n, 3), target (n,)) by full-batch Adam on the MSE; rows with NaN dropped."""
    f = np.asarray(features, float).reshape(-1, 3)
    y = np.asarray(target, float).reshape(-1)
    ok = np.all(np.isfinite(f), axis=1) & np.isfinite(y)
    f, y = f[ok], y[ok]
    rng = np.random.default_rng(seed)
    limit = math.sqrt(6.0 / (3 + hidden))
    w1 = rng.uniform(-limit, limit, (3, hidden))
    if f.shape[0] < 2:
        zero = np.zeros(3)
        return BpNetwork(w1, np.zeros(hidden), np.zeros(hidden), 0.0, zero, np.ones(3),
                         float(y.mean()) if y.size else 0.0, 1.0)
    u_raw = np.log1p(np.maximum(f, 0.0))
    in_mean, in_std = _scaling(u_raw)
    u = (u_raw - in_mean) / in_std
    out_mean, out_std = float(y.mean()), float(y.std()) if y.std() > 1e-12 else 1.0
    flat = np.concatenate([w1.ravel(), np.zeros(hidden), rng.uniform(-limit, limit, hidden), np.zeros(1)])
    flat = _adam(flat, u, (y - out_mean) / out_std, hidden)
    w1, b1, w2, b2 = _unpack(flat, hidden)
    return BpNetwork(w1, b1, w2, float(b2[0]), in_mean, in_std, out_mean, out_std)


def _unpack(flat: np.ndarray, hidden: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Views (W1 (3, H), b1, w2, b2) into one flat parameter vector."""
    n1 = 3 * hidden
    return (flat[:n1].reshape(3, hidden), flat[n1:n1 + hidden], flat[n1 + hidden:n1 + 2 * hidden],
            flat[n1 + 2 * hidden:])


def _gradient(flat: np.ndarray, u: np.ndarray, t: np.ndarray, hidden: int) -> np.ndarray:
    """Back-propagated gradient of the mean squared error plus L2 decay on the weights, flat."""
    w1, b1, w2, b2 = _unpack(flat, hidden)
    hid = np.tanh(u @ w1 + b1)                  # (n, H)
    g_out = (2.0 / t.size) * (hid @ w2 + b2[0] - t)
    g_hid = np.outer(g_out, w2) * (1.0 - hid * hid)
    return np.concatenate([(u.T @ g_hid + BP_WEIGHT_DECAY * w1).ravel(), g_hid.sum(axis=0),
                           hid.T @ g_out + BP_WEIGHT_DECAY * w2, [g_out.sum()]])


def _adam(flat: np.ndarray, u: np.ndarray, t: np.ndarray, hidden: int) -> np.ndarray:
    """Adam (β1 0.9, β2 0.999) for BP_ITERATIONS full-batch steps on the flat parameters.

    The operations of `_gradient` and of the update below, in the same order, written into buffers made
    once (1500 steps of a few dozen tiny arrays: allocation was a good part of the time); the tests check
    it against them.
    """
    flat = flat.copy()
    w1, b1, w2, b2 = _unpack(flat, hidden)
    g = np.empty_like(flat)
    gw1, gb1, gw2, gb2 = _unpack(g, hidden)
    n = t.size
    scale = 2.0 / n
    hid = np.empty((n, hidden))
    hid2 = np.empty((n, hidden))
    g_hid = np.empty((n, hidden))
    g_out = np.empty(n)
    dw1 = np.empty_like(w1)
    dw2 = np.empty_like(w2)
    m = np.zeros_like(flat)
    v = np.zeros_like(flat)
    tmp = np.empty_like(flat)
    den = np.empty_like(flat)
    for it in range(1, BP_ITERATIONS + 1):
        # _gradient
        np.matmul(u, w1, out=hid)
        hid += b1
        np.tanh(hid, out=hid)
        np.matmul(hid, w2, out=g_out)
        g_out += b2[0]
        g_out -= t
        g_out *= scale
        np.multiply.outer(g_out, w2, out=g_hid)
        np.multiply(hid, hid, out=hid2)
        np.subtract(1.0, hid2, out=hid2)
        g_hid *= hid2
        np.matmul(u.T, g_hid, out=gw1)
        np.multiply(w1, BP_WEIGHT_DECAY, out=dw1)
        gw1 += dw1
        np.sum(g_hid, axis=0, out=gb1)
        np.matmul(hid.T, g_out, out=gw2)
        np.multiply(w2, BP_WEIGHT_DECAY, out=dw2)
        gw2 += dw2
        gb2[0] = g_out.sum()
        # m = 0.9 m + 0.1 g; v = 0.999 v + 0.001 g g;
        # flat -= (step / (1 - 0.9^it)) m / (sqrt(v / (1 - 0.999^it)) + 1e-8)
        m *= 0.9
        np.multiply(g, 0.1, out=tmp)
        m += tmp
        v *= 0.999
        np.multiply(g, 0.001, out=tmp)
        tmp *= g
        v += tmp
        np.divide(v, 1.0 - 0.999 ** it, out=den)
        np.sqrt(den, out=den)
        den += 1e-8
        np.multiply(m, BP_STEP / (1.0 - 0.9 ** it), out=tmp)
        tmp /= den
        flat -= tmp
    return flat


def cusum(increments: np.ndarray, h: float = math.inf, alarm: np.ndarray | None = None) -> np.ndarray:
    """One-sided CUSUM S_k = max(0, S_{k-1} + x_k), restarted after each alarm (S_k > h or alarm[k]).

    The returned S_k is the value before the restart (what was compared);
    NaN increments leave S unchanged.
    """
    out = np.empty(len(increments))
    s = 0.0
    for i, x in enumerate(increments):
        if math.isfinite(x):
            s = max(0.0, s + x)
        out[i] = s
        if s > h or (alarm is not None and alarm[i]):
            s = 0.0
    return out


class DualThresholdDetector:
    """Chi-square threshold for abrupt faults plus a CUSUM of the BP-predicted range error for drift."""

    name = "dual_threshold"

    def __init__(self, config: StackConfig) -> None:
        """Thresholds from the config; the network is fitted by ``train``."""
        self.chi2_threshold = chi_square_threshold(config.chi_square_alpha)
        self.cusum_k = config.dual_threshold_cusum_k_m
        self.cusum_h = config.dual_threshold_cusum_h_m
        self.hidden = config.dual_threshold_hidden
        self.seed = config.seed
        self.network: BpNetwork | None = None
        self.cusum_state = 0.0

    def train_on(self, ts: TrainingSet) -> None:
        """`train` on the rows' features, range errors and labels."""
        self.train(ts.features, ts.range_error, ts.labels)

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Fit the BP network on the window's features and |signed range error|."""
        self.network = train_bp(features, np.abs(np.asarray(range_error, float)), self.hidden, self.seed)
        self.cusum_state = 0.0

    def predicted_error(self, features: np.ndarray) -> np.ndarray:
        """The network's predicted range error magnitude (m) for features (n, 3); 0 before training."""
        f = np.asarray(features, float).reshape(-1, 3)
        return np.zeros(f.shape[0]) if self.network is None else self.network.predict(f)

    def decide(self, features: np.ndarray) -> Decision:
        """Advance this leader's CUSUM and flag when either threshold is crossed."""
        f = np.asarray(features, float).reshape(3)
        if not np.all(np.isfinite(f)):
            return Decision(flagged=False, score=float("nan"), threshold=1.0)
        e_hat = float(self.predicted_error(f)[0])
        self.cusum_state = max(0.0, self.cusum_state + e_hat - self.cusum_k)
        score = max(float(f[1]) / self.chi2_threshold, self.cusum_state / self.cusum_h)
        return Decision(flagged=bool(score > 1.0), score=score, threshold=1.0)

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores max(f2/χ², S/h) over a time-ordered sequence (n, 3), restarting at alarms."""
        f = np.asarray(features, float).reshape(-1, 3)
        abrupt = f[:, 1] / self.chi2_threshold
        s = cusum(self.predicted_error(f) - self.cusum_k, self.cusum_h, abrupt > 1.0)
        return np.maximum(abrupt, s / self.cusum_h)

    def reset(self) -> None:
        """Restart the CUSUM (after an alarm)."""
        self.cusum_state = 0.0


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """The two tests: f2 over the gate and the CUSUM of the predicted error over h; flagged when either exceeds 1."""
    chi2 = float(getattr(detector, "chi2_threshold", math.nan))
    abrupt = r.f2 / chi2 if chi2 > 0 else math.nan
    if r.flagged or not isinstance(detector, DualThresholdDetector):
        # after an alarm the runner restarted the CUSUM: the score is the larger of the two ratios
        drift = r.score if not (abrupt >= r.score - 1e-12) else math.nan
        drift_text = num(drift) if math.isfinite(drift) else f"<= {num(r.score)}"
    else:
        drift_text = num(float(detector.cusum_state) / float(detector.cusum_h))
    which = (" (abrupt)" if abrupt > 1.0 else " (drift)") if r.flagged else ""
    return f"f2/gate {num(abrupt)}, drift S/h {drift_text}; max {cmp(r.flagged)} 1{which}"
