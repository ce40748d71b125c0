"""ANFIS range-anomaly detector (seed 000, A section 3.2, A.32) and range compensation (patent P step 4).

Training window (``0 < t <= t_a``): the three features [f1, f2, f3] are
normalized to [0, 1] by the window's min/max and the ANFIS learns the range
error. Detection mode learns ``|Z - Z_gps|`` and flags an epoch when the
output exceeds ``T2`` (``3 sigma`` of the training RMSE by default, A.32).
Compensation mode learns the signed ``Z - Z_gps`` and, when the predicted
error exceeds the compensation threshold (9 m), returns it as the range
correction instead of isolating the epoch (docs/design.md sections 10 and 12).

One instance per leader (``per_leader``, as A does) or one instance fed every
leader's epochs (``shared``): :func:`detectors_for` builds either mapping.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from replay.events import EpochResult
from replay.stack.config import ConfigError, StackConfig
from replay.stack.detectors.anfis import (
    _S_FLOOR,
    AnfisModel,
    PointPredictor,
    TrainingHistory,
    TrainingResult,
    firing_from,
    initial_model,
    memberships,
    minmax_bounds,
    normalize,
    output_surface,
    predict,
    rule_outputs,
    train_hybrid,
)
from replay.stack.detectors.aqpso import AqpsoSettings, train_aqpso_ga
from replay.stack.detectors.base import Decision
from replay.stack.detectors.why_text import cmp, num
from replay.stack.training import TrainingSet

TRAINERS: tuple[str, ...] = ("hybrid", "aqpso_ga")
_SIGMA_RULE = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*sigma\s*$")


def threshold_from_rule(rule: str, sigma: float, t1_m: float) -> float:
    """T2 from the threshold rule: "3sigma" (A.32), "t1" (the label threshold), or "<k>sigma"."""
    text = rule.strip().lower()
    if text == "t1":
        return float(t1_m)
    match = _SIGMA_RULE.match(text)
    if match is None:
        raise ConfigError(f"unknown ANFIS threshold rule {rule!r}; expected '3sigma', 't1' or '<k>sigma'")
    return float(match.group(1)) * float(sigma)


@dataclass(frozen=True)
class Explanation:
    """Why the model said what it said for one epoch (or many: a leading sample axis)."""

    normalized_inputs: np.ndarray   # (..., D) in [0, 1] after clipping
    memberships: np.ndarray         # (..., D, M) grade of each input in each MF
    firing: np.ndarray              # (..., R) rule firing strengths w (A.22)
    normalized_firing: np.ndarray   # (..., R) w / sum w (A.23)
    rule_outputs: np.ndarray        # (..., R) each rule's linear output f_r
    output: np.ndarray              # (...) the ANFIS output (A.25)


@dataclass(frozen=True)
class ModelSnapshot:
    """One model state in the terms of the ``auvreplay.AnfisSnapshot`` message (time and leader added by the caller)."""

    epoch: int
    a: np.ndarray                  # (D, M)
    b: np.ndarray
    c: np.ndarray
    consequents: np.ndarray        # (R, D+1), columns [p_1 .. p_D, r]
    input_min: np.ndarray          # (D,)
    input_max: np.ndarray
    training_rmse: float
    mfs_per_input: int
    rule_structure: str
    threshold: float               # NaN until training is done
    trainer: str

    @property
    def inputs(self) -> int:
        """Number of inputs D."""
        return int(self.a.shape[0])


class AnfisDetector:
    """ANFIS detector (``anfis``, ``anfis_aqpso``) or range compensator (``anfis_compensation``)."""

    name: str

    def __init__(self, config: StackConfig, trainer: str = "hybrid", compensation: bool = False) -> None:
        """Configure from ``config.anfis``; nothing is trained until :meth:`train`."""
        if trainer not in TRAINERS:
            raise ConfigError(f"unknown ANFIS trainer {trainer!r}; expected one of {TRAINERS}")
        threshold_from_rule(config.anfis.threshold_rule, 1.0, config.t1_m)  # fail early on a bad rule
        self.config = config
        self.trainer = trainer
        self.compensation = compensation
        if compensation:
            self.name = "anfis_compensation"
        else:
            self.name = "anfis_aqpso" if trainer == "aqpso_ga" else "anfis"
        self.result: TrainingResult | None = None
        self.input_min = np.zeros(3)
        self.input_max = np.ones(3)
        self.sigma = float("nan")
        self.threshold = float("nan")
        self.training_samples = 0
        self.training_anomalies = 0
        self._point: PointPredictor | None = None   # one-epoch predictor of the trained model

    @property
    def trained(self) -> bool:
        """Whether a model exists (training saw at least one usable epoch)."""
        return self.result is not None

    @property
    def model(self) -> AnfisModel | None:
        """The trained model (best epoch), or None before training."""
        return None if self.result is None else self.result.model

    @property
    def history(self) -> TrainingHistory | None:
        """Per-epoch (hybrid) or per-iteration (AQPSO-GA) parameters and training RMSE."""
        return None if self.result is None else self.result.history

    def train_on(self, ts: TrainingSet) -> None:
        """`train` on the rows' features, range errors and labels."""
        self.train(ts.features, ts.range_error, ts.labels)

    def train(self, features: np.ndarray, range_error: np.ndarray, labels: np.ndarray) -> None:
        """Fit on the training window: features (n, 3), signed error Z - Z_gps (n,), labels (n,).

        Epochs with a non-finite feature or error are left out. The labels are
        not a training target; their count of anomalies is kept because a
        window without one cannot teach the model to see one (docs/design.md section 10).
        """
        x = np.atleast_2d(np.asarray(features, dtype=float))
        err = np.asarray(range_error, dtype=float).ravel()
        ok = np.isfinite(x).all(axis=1) & np.isfinite(err)
        x, err = x[ok], err[ok]
        lab = np.asarray(labels).ravel()
        self.training_anomalies = int(np.sum(lab[ok] == 1)) if lab.shape == ok.shape else 0
        self.training_samples = int(x.shape[0])
        self._point = None
        if x.shape[0] == 0:
            self.result = None
            return
        self.input_min, self.input_max = minmax_bounds(x)
        target = err if self.compensation else np.abs(err)
        self.result = self._fit(normalize(x, self.input_min, self.input_max), target)
        self.sigma = self.result.rmse
        if self.compensation:
            self.threshold = float(self.config.anfis.compensation_threshold_m)
        else:
            self.threshold = threshold_from_rule(self.config.anfis.threshold_rule, self.sigma,
                                                 self.config.t1_m)

    def _fit(self, x: np.ndarray, y: np.ndarray) -> TrainingResult:
        """Run the configured trainer on normalized inputs."""
        cfg = self.config.anfis
        if self.trainer == "aqpso_ga":
            settings = AqpsoSettings(particles=cfg.particles, iterations=cfg.iterations,
                                     ridge=cfg.ridge, seed=cfg.seed)
            return train_aqpso_ga(x, y, mfs=cfg.mfs_per_input, structure=cfg.rule_structure,
                                  settings=settings, lo=np.zeros(x.shape[1]), hi=np.ones(x.shape[1]))
        return train_hybrid(x, y, mfs=cfg.mfs_per_input, structure=cfg.rule_structure,
                            epochs=cfg.epochs, initial_step=cfg.initial_step,
                            step_increase=cfg.step_increase, step_decrease=cfg.step_decrease,
                            ridge=cfg.ridge, init=self._genfis1_init(x))

    def _genfis1_init(self, x: np.ndarray) -> AnfisModel:
        """genfis1 MFs over the normalized range [0, 1], the same for every model whatever its data."""
        d = x.shape[1]
        return initial_model(x, self.config.anfis.mfs_per_input, self.config.anfis.rule_structure,
                             lo=np.zeros(d), hi=np.ones(d))

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Model output for epochs (n, 3) -> (n,): predicted |error| (detection) or signed error (compensation)."""
        x = np.atleast_2d(np.asarray(features, dtype=float))
        if self.result is None:
            return np.full(x.shape[0], np.nan)
        return predict(self.result.model, normalize(x, self.input_min, self.input_max))

    def scores(self, features: np.ndarray) -> np.ndarray:
        """Open-loop scores (n,) compared with the threshold: the output, or |output| when compensating."""
        out = self.predict(features)
        return np.abs(out) if self.compensation else out

    def decide(self, features: np.ndarray) -> Decision:
        """One epoch: flagged when the score exceeds the threshold; NaN features are never flagged."""
        if self.result is None:
            out = float("nan")
        else:
            if self._point is None:
                self._point = PointPredictor(self.result.model, self.input_min, self.input_max)
            out = self._point([float(v) for v in np.ravel(features)])
        score = abs(out) if self.compensation else out
        flagged = bool(score > self.threshold)      # NaN compares False
        correction = out if (self.compensation and flagged) else 0.0
        return Decision(flagged=flagged, score=score, threshold=self.threshold, correction_m=correction)

    def reset(self) -> None:
        """Nothing to forget: the ANFIS decision has no memory between epochs."""

    def explain(self, features: np.ndarray) -> Explanation:
        """Memberships, firing strengths and rule outputs behind the output, for the views."""
        if self.result is None:
            raise RuntimeError("explain() needs a trained model")
        feats = np.asarray(features, dtype=float)
        x = normalize(np.atleast_2d(feats), self.input_min, self.input_max)
        m = self.result.model
        mu = memberships(x, m.a, m.b, m.c)
        w, wbar = firing_from(mu, m.rules)
        f = rule_outputs(x, m.consequents)
        parts = (x, mu, w, wbar, f, (wbar * f).sum(axis=-1))
        if feats.ndim == 1:
            parts = tuple(p[0] for p in parts)
        return Explanation(*parts)

    def explain_rows(self, features: np.ndarray) -> Explanation:
        """`explain` of each row of features (n, 3), stacked: element for element what it gives one row at a
        time (the tests check). Every layer runs over all rows at once; the rule outputs as a stack of one-row
        products, because a plain (n, D) product takes another BLAS kernel than one row's (the last bits would
        change), while a stack of (1, D) rows takes one row's kernel row by row. The sums over the rules run along
        C-ordered rows, the same pairwise order as one row alone."""
        if self.result is None:
            raise RuntimeError("explain_rows() needs a trained model")
        x = normalize(np.atleast_2d(np.asarray(features, dtype=float)), self.input_min, self.input_max)
        m = self.result.model
        mu = memberships(x, m.a, m.b, m.c)
        w = mu[..., 0, m.rules[:, 0]]     # the product over inputs, as `firing_from` takes it
        for d in range(1, m.rules.shape[1]):
            w = w * mu[..., d, m.rules[:, d]]
        total = np.maximum(np.ascontiguousarray(w).sum(axis=-1, keepdims=True), _S_FLOOR)
        f = rule_outputs(x[:, None, :], m.consequents)[:, 0, :]
        wbar = w / total
        out = np.ascontiguousarray(wbar * f).sum(axis=-1)
        return Explanation(x, mu, w, wbar, f, out)

    def surface(self, pair: tuple[int, int] = (0, 1), fixed: float | np.ndarray = 0.5,
                resolution: int = 25) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Output surface over two normalized inputs (others at ``fixed``), for the mesh view (A Fig. 12)."""
        if self.result is None:
            raise RuntimeError("surface() needs a trained model")
        return output_surface(self.result.model, pair, fixed, resolution)

    def snapshot(self, epoch: int | None = None) -> ModelSnapshot:
        """The final model (``epoch=None``: the best epoch, with its threshold) or one history row."""
        if self.result is None:
            raise RuntimeError("snapshot() needs a trained model")
        if epoch is None:
            m, k, rmse, thr = self.result.model, self.result.best_epoch, self.result.rmse, self.threshold
        else:
            h = self.result.history
            m = h.model_at(epoch, self.result.model.rules, self.result.model.structure)
            k, rmse, thr = epoch, float(h.rmse[epoch]), float("nan")
        return ModelSnapshot(k, m.a, m.b, m.c, m.consequents, self.input_min, self.input_max, rmse,
                             m.mfs_per_input, m.structure, thr, self.trainer)

    def snapshots(self) -> list[ModelSnapshot]:
        """Every training epoch's model in order (empty before training), for the MF-per-epoch views."""
        if self.result is None:
            return []
        return [self.snapshot(k) for k in range(self.result.history.epochs)]


def detectors_for(config: StackConfig, leaders: list[str], trainer: str = "hybrid",
                  compensation: bool = False) -> dict[str, AnfisDetector]:
    """Leader -> detector: one each (``per_leader``) or the same instance for all (``shared``)."""
    if config.anfis.model == "shared":
        shared = AnfisDetector(config, trainer, compensation)
        return {leader: shared for leader in leaders}
    if config.anfis.model != "per_leader":
        raise ConfigError(f"unknown ANFIS model mode {config.anfis.model!r}; expected 'per_leader' or 'shared'")
    return {leader: AnfisDetector(config, trainer, compensation) for leader in leaders}


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """The ANFIS output against T2 (metres), and what the runner did with the range."""
    extra = ", range corrected" if r.compensated else ", isolated" if r.isolated else ", capped" if r.capped else ""
    return f"output {num(r.score)} m {cmp(r.flagged)} T2 {num(r.threshold)} m{extra}"
