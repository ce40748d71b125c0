"""First-order Takagi-Sugeno ANFIS with generalized bell MFs and Jang's hybrid learning.

Layers (seed 000, Xu et al. 2023, eqs. A.21-A.25): bell memberships, product
firing strengths, normalization, linear consequents, weighted sum. Rule bases:
``grid`` (every combination of one MF per input, n^D rules, what MATLAB's
``genfis1``/``anfis`` build) or ``diagonal`` (the literal A.22 form: rule i uses
MF i of every input, n rules). docs/design.md section 10 fixes the training choices.

Shapes: inputs ``X`` (n, D); premise ``a, b, c`` (..., D, M) where the leading
axes, if any, are a batch of models (AQPSO-GA evaluates a whole population this
way); consequents (..., R, D + 1) with the columns ``[p_1 .. p_D, r]`` so that
``f_r = p . x + r``. All functions are vectorized over samples, rules and the
batch axes.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

RULE_STRUCTURES: tuple[str, ...] = ("grid", "diagonal")
_A_FLOOR = 1e-9      # |a| never reaches 0: the bell would divide by it
_S_FLOOR = 1e-300    # total firing floor for inputs far outside every MF


@dataclass(frozen=True)
class AnfisModel:
    """One ANFIS: bell parameters (D, M) each, consequents (R, D+1), rule table (R, D) of MF indices."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    consequents: np.ndarray
    rules: np.ndarray
    structure: str = "grid"

    @property
    def inputs(self) -> int:
        """Number of inputs D."""
        return int(self.a.shape[-2])

    @property
    def mfs_per_input(self) -> int:
        """Number of membership functions per input M."""
        return int(self.a.shape[-1])

    @property
    def n_rules(self) -> int:
        """Number of rules R."""
        return int(self.rules.shape[0])

    def with_premise(self, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> AnfisModel:
        """The same model with other bell parameters."""
        return AnfisModel(a, b, c, self.consequents, self.rules, self.structure)

    def with_consequents(self, consequents: np.ndarray) -> AnfisModel:
        """The same model with other consequents."""
        return AnfisModel(self.a, self.b, self.c, consequents, self.rules, self.structure)


@dataclass(frozen=True)
class TrainingHistory:
    """Per-epoch (or per-iteration) parameters and training RMSE, for views and snapshots.

    Row ``k`` holds the model whose training error is ``rmse[k]``; ``step`` is
    the gradient step size used after that epoch (NaN for trainers without one).
    """

    a: np.ndarray            # (E, D, M)
    b: np.ndarray            # (E, D, M)
    c: np.ndarray            # (E, D, M)
    consequents: np.ndarray  # (E, R, D+1)
    rmse: np.ndarray         # (E,)
    step: np.ndarray         # (E,)

    @property
    def epochs(self) -> int:
        """Number of recorded epochs."""
        return int(self.rmse.shape[0])

    def model_at(self, epoch: int, rules: np.ndarray, structure: str = "grid") -> AnfisModel:
        """The model recorded at one epoch (0-based)."""
        return AnfisModel(self.a[epoch], self.b[epoch], self.c[epoch],
                          self.consequents[epoch], rules, structure)


@dataclass(frozen=True)
class TrainingResult:
    """A trained model (the best epoch's), its training RMSE, which epoch, and the history."""

    model: AnfisModel
    rmse: float
    best_epoch: int
    history: TrainingHistory


def rule_table(inputs: int, mfs: int, structure: str = "grid") -> np.ndarray:
    """MF index per input for every rule, (R, D): grid = all n^D combinations, diagonal = n rules (A.22)."""
    if structure == "grid":
        # first input varies slowest, as in MATLAB's genfis1 rule list
        return np.array(list(itertools.product(range(mfs), repeat=inputs)), dtype=np.intp)
    if structure == "diagonal":
        return np.repeat(np.arange(mfs, dtype=np.intp)[:, None], inputs, axis=1)
    raise ValueError(f"unknown rule structure {structure!r}; expected one of {RULE_STRUCTURES}")


def genfis1_premise(lo: np.ndarray, hi: np.ndarray, mfs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Evenly spaced bells over [lo, hi] per input as MATLAB's genfis1 lays them: a = half spacing, b = 2."""
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    span = np.where(hi > lo, hi - lo, 1.0)
    if mfs == 1:
        c = ((lo + hi) / 2.0)[:, None]
        a = span[:, None] / 2.0
    else:
        c = lo[:, None] + span[:, None] * np.linspace(0.0, 1.0, mfs)[None, :]
        a = np.repeat(span[:, None] / (2.0 * (mfs - 1)), mfs, axis=1)
    return a, np.full_like(a, 2.0), c


def initial_model(x: np.ndarray, mfs: int = 2, structure: str = "grid",
                  lo: np.ndarray | None = None, hi: np.ndarray | None = None) -> AnfisModel:
    """A genfis1-style starting model over the data's range (or the given bounds), zero consequents."""
    x = np.asarray(x, dtype=float)
    lo = x.min(axis=0) if lo is None else np.asarray(lo, dtype=float)
    hi = x.max(axis=0) if hi is None else np.asarray(hi, dtype=float)
    a, b, c = genfis1_premise(lo, hi, mfs)
    rules = rule_table(x.shape[1], mfs, structure)
    return AnfisModel(a, b, c, np.zeros((rules.shape[0], x.shape[1] + 1)), rules, structure)


def minmax_bounds(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-input min and max of a training set (n, D), NaNs ignored; a flat or empty input gets [0, 1]."""
    x = np.asarray(x, dtype=float)
    finite = np.isfinite(x)
    if x.shape[0] == 0 or not finite.any():
        return np.zeros(x.shape[1]), np.ones(x.shape[1])
    lo = np.where(finite, x, np.inf).min(axis=0)
    hi = np.where(finite, x, -np.inf).max(axis=0)
    empty = ~np.isfinite(lo)
    lo, hi = np.where(empty, 0.0, lo), np.where(empty, 1.0, hi)
    return lo, np.where(hi > lo, hi, lo + 1.0)


def normalize(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, clip: bool = True) -> np.ndarray:
    """Scale inputs to [0, 1] by training bounds; values outside clipped to the edge (docs/design.md section 10)."""
    z = (np.asarray(x, dtype=float) - lo) / (hi - lo)
    return np.clip(z, 0.0, 1.0) if clip else z


def bell(x: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Generalized bell mu = 1 / (1 + |(x - c)/a|^(2b)) (A.21), broadcasting."""
    t = np.subtract(x, c)
    if not (isinstance(t, np.ndarray) and t.dtype == np.float64
            and np.broadcast_shapes(t.shape, np.shape(a), np.shape(b)) == t.shape):
        with np.errstate(over="ignore", divide="ignore"):
            return 1.0 / (1.0 + np.abs((x - c) / _safe_a(a)) ** (2.0 * b))
    # the same operations as the formula, in place: one temporary instead of six
    with np.errstate(over="ignore", divide="ignore"):
        np.divide(t, _safe_a(a), out=t)
        np.abs(t, out=t)
        np.power(t, 2.0 * b, out=t)
        t += 1.0
        return np.divide(1.0, t, out=t)


def memberships(x: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Membership grades of every sample in every MF: (..., n, D, M) for premise (..., D, M)."""
    return bell(x[:, :, None], a[..., None, :, :], b[..., None, :, :], c[..., None, :, :])


def rule_grades(mu: np.ndarray, rules: np.ndarray) -> np.ndarray:
    """Each rule's membership per input, (..., n, R, D), picked from grades (..., n, D, M)."""
    dims = np.broadcast_to(np.arange(rules.shape[1]), rules.shape)
    return mu[..., dims, rules]


def normalized_firing(x: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                      rules: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Firing strengths w (A.22) and their normalization w / sum(w) (A.23), each (..., n, R)."""
    return firing_from(memberships(x, a, b, c), rules)


def firing_from(mu: np.ndarray, rules: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`normalized_firing` from membership grades already computed (..., n, D, M)."""
    # the product over inputs, left to right as prod() does, without gathering (..., n, R, D) first
    w = mu[..., 0, rules[:, 0]]
    for d in range(1, rules.shape[1]):
        w = w * mu[..., d, rules[:, d]]
    total = np.maximum(w.sum(axis=-1, keepdims=True), _S_FLOOR)
    return w, w / total


def design_matrix(x: np.ndarray, wbar: np.ndarray) -> np.ndarray:
    """Least-squares regressors wbar_r * [x, 1] per rule (A.24): (..., n, R*(D+1)), rule-major."""
    d = x.shape[1]
    # written C-ordered so the reshape below is a view, not a copy of the whole matrix; one multiply per input
    # column (long inner loops, not D+1 at a time), the last column wbar itself (wbar * 1 is wbar)
    phi = np.empty(wbar.shape + (d + 1,))
    for k in range(d):
        np.multiply(wbar, x[:, k, None], out=phi[..., k])
    phi[..., d] = wbar
    return phi.reshape(*phi.shape[:-2], -1)


def fit_consequents(x: np.ndarray, wbar: np.ndarray, y: np.ndarray, ridge: float = 1e-6) -> np.ndarray:
    """Consequents by ridge least squares on the whole set, (..., R, D+1); batched over leading axes.

    MATLAB's recursive estimator starts from 1e6 I, about a 1e-6 ridge; the
    plain normal equations are near-singular on lake-like data (docs/design.md section 10).
    """
    phi = design_matrix(x, wbar)
    gram = np.swapaxes(phi, -1, -2) @ phi
    gram = gram + ridge * np.eye(gram.shape[-1])
    rhs = np.swapaxes(phi, -1, -2) @ y
    try:
        theta = np.linalg.solve(gram, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        theta = (np.linalg.pinv(gram) @ rhs[..., None])[..., 0]
    return theta.reshape(*wbar.shape[:-2], wbar.shape[-1], x.shape[1] + 1)


def rule_outputs(x: np.ndarray, consequents: np.ndarray) -> np.ndarray:
    """Each rule's linear output f_r = p_r . x + r_r, (..., n, R)."""
    return x @ np.swapaxes(consequents[..., :-1], -1, -2) + consequents[..., None, :, -1]


def predict(model: AnfisModel, x: np.ndarray) -> np.ndarray:
    """ANFIS output sum_r wbar_r f_r (A.25) for every sample, (n,)."""
    x = np.asarray(x, dtype=float)
    _, wbar = normalized_firing(x, model.a, model.b, model.c, model.rules)
    return (wbar * rule_outputs(x, model.consequents)).sum(axis=-1)


class PointPredictor:
    """``predict`` on one sample in plain floats, inputs normalized by (lo, hi) and clipped as ``normalize`` does.

    The online detector decides one epoch at a time, where numpy's per-call
    overhead (~60 µs) dwarfs the arithmetic of 8 rules; the tests check it
    against ``predict``.
    """

    def __init__(self, model: AnfisModel, lo: np.ndarray, hi: np.ndarray) -> None:
        """Copy the model's parameters (and the normalization bounds) into Python lists."""
        self._a = _safe_a(np.asarray(model.a, dtype=float)).tolist()
        self._b2 = (2.0 * np.asarray(model.b, dtype=float)).tolist()
        self._c = np.asarray(model.c, dtype=float).tolist()
        self._rules = [tuple(r) for r in np.asarray(model.rules).tolist()]
        self._cons = np.asarray(model.consequents, dtype=float).tolist()
        self._lo = np.asarray(lo, dtype=float).tolist()
        self._span = (np.asarray(hi, dtype=float) - np.asarray(lo, dtype=float)).tolist()

    def __call__(self, features: list[float] | tuple[float, ...]) -> float:
        """Output for raw (unnormalized) features; NaN if any feature is NaN."""
        x = []
        for f, lo, span in zip(features, self._lo, self._span):
            z = (f - lo) / span
            if z != z:
                return math.nan
            x.append(0.0 if z < 0.0 else 1.0 if z > 1.0 else z)
        mu = []
        for xd, ad, bd, cd in zip(x, self._a, self._b2, self._c):
            row = []
            for a, b2, c in zip(ad, bd, cd):
                try:
                    row.append(1.0 / (1.0 + abs((xd - c) / a) ** b2))
                except (OverflowError, ZeroDivisionError):
                    row.append(0.0)     # numpy's inf: the bell's tail
            mu.append(row)
        total, acc = 0.0, 0.0
        for rule, cons in zip(self._rules, self._cons):
            w = 1.0
            for d, k in enumerate(rule):
                w *= mu[d][k]
            total += w
            acc += w * (sum(p * xd for p, xd in zip(cons, x)) + cons[-1])
        return acc / max(total, _S_FLOOR)


def output_surface(model: AnfisModel, pair: tuple[int, int] = (0, 1), fixed: float | np.ndarray = 0.5,
                   resolution: int = 25, lo: float = 0.0, hi: float = 1.0
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Output over a grid of two inputs, the others held at ``fixed``: u (K,), v (K,), z (K, K), z[i, j] at u[i], v[j].

    The ANFIS input-output surface of A Fig. 12, for the mesh view.
    """
    u = np.linspace(lo, hi, resolution)
    uu, vv = np.meshgrid(u, u, indexing="ij")
    x = np.empty((uu.size, model.inputs))
    x[:] = np.broadcast_to(np.asarray(fixed, dtype=float), (model.inputs,))
    x[:, pair[0]], x[:, pair[1]] = uu.ravel(), vv.ravel()
    return u, u.copy(), predict(model, x).reshape(resolution, resolution)


def rmse(model: AnfisModel, x: np.ndarray, y: np.ndarray) -> float:
    """Root-mean-square error of the model on (x, y)."""
    return float(np.sqrt(np.mean((predict(model, x) - y) ** 2)))


def bell_derivatives(x: np.ndarray, a: np.ndarray, b: np.ndarray,
                     c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """mu and d mu / d(a, b, c) of the bell, all (n, D, M) for premise (D, M).

    With u = |(x-c)/a|^(2b) and mu = 1/(1+u), u mu^2 = mu (1 - mu), which stays
    finite where u overflows: dmu/da = 2b mu(1-mu)/a, dmu/db = -2 ln|t| mu(1-mu),
    dmu/dc = 2b mu(1-mu)/(x-c) (zero at t = 0, its limit for b > 1/2).
    """
    sa = _safe_a(a)
    diff = x[:, :, None] - c[None]
    t = np.abs(diff / sa[None])
    b2 = 2.0 * b[None]
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        u = t ** b2
        mu = 1.0 / (1.0 + u)
        one_minus = np.where(u > 1.0, 1.0 - mu, u * mu)
        s = mu * one_minus
        b2s = b2 * s        # 2b mu(1-mu), shared by d_a and d_c
        d_a = b2s / sa[None]
        positive, moved = t > 0.0, diff != 0.0
        d_b = np.where(positive, -2.0 * np.log(np.where(positive, t, 1.0)) * s, 0.0)
        d_c = np.where(moved, b2s / np.where(moved, diff, 1.0), 0.0)
    return mu, d_a, d_b, d_c


def sse(model: AnfisModel, x: np.ndarray, y: np.ndarray) -> float:
    """Sum of squared errors E = sum (y - o)^2, the quantity the premise gradient descends."""
    return float(np.sum((y - predict(model, x)) ** 2))


def premise_gradient(model: AnfisModel, x: np.ndarray,
                     y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """dE/d(a, b, c), each (D, M), of E = sum (y - o)^2 with the consequents held fixed.

    Chain: dE/do = -2 (y - o); do/dw_r = (f_r - o) / S; dw_r/dmu_{d,m} = product
    of the rule's other grades when rule r uses MF m on input d (Jang 1993).
    """
    terms = bell_derivatives(x, model.a, model.b, model.c)
    return _premise_gradient(x, y, terms, rule_grades(terms[0], model.rules), model)


def _premise_gradient(x: np.ndarray, y: np.ndarray, terms: tuple[np.ndarray, ...],
                      sel: np.ndarray, model: AnfisModel,
                      forward: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The premise gradient from precomputed bell terms and rule grades (shared with the forward pass);
    `forward`: the firing w, its floored sum and the rule outputs f of `model`, when the caller has them."""
    _, d_a, d_b, d_c = terms
    if forward is None:
        w = sel.prod(axis=-1)
        total = np.maximum(w.sum(axis=-1, keepdims=True), _S_FLOOR)
        f = rule_outputs(x, model.consequents)                    # (n, R)
    else:
        w, total, f = forward
    out = (w * f).sum(axis=-1, keepdims=True) / total
    g_w = (-2.0 * (y[:, None] - out)) * (f - out) / total     # dE/dw_r, (n, R)
    g_mu = _scatter_to_mfs(g_w[None] * _leave_one_out(sel), model.rules, model.mfs_per_input)
    return ((g_mu * d_a).sum(axis=0), (g_mu * d_b).sum(axis=0), (g_mu * d_c).sum(axis=0))


def _leave_one_out(sel: np.ndarray) -> np.ndarray:
    """Product of every factor but one, (D, n, R) from grades (n, R, D), without dividing (grades can be 0)."""
    factors = np.ascontiguousarray(np.moveaxis(sel, -1, 0))
    d = factors.shape[0]
    before = np.ones_like(factors)
    after = np.ones_like(factors)
    for k in range(1, d):
        before[k] = before[k - 1] * factors[k - 1]
        after[d - 1 - k] = after[d - k] * factors[d - k]
    return before * after


def _scatter_to_mfs(per_rule: np.ndarray, rules: np.ndarray, mfs: int) -> np.ndarray:
    """Sum (D, n, R) per-rule terms into the MF each rule uses: (n, D, M)."""
    onehot = (rules.T[:, :, None] == np.arange(mfs)[None, None, :]).astype(float)  # (D, R, M)
    return np.moveaxis(per_rule @ onehot, 0, 1)


def _safe_a(a: np.ndarray) -> np.ndarray:
    """a with its magnitude floored, sign kept (the bell depends on |a| only)."""
    return np.where(a >= 0.0, np.maximum(a, _A_FLOOR), np.minimum(a, -_A_FLOOR))


def step_size_update(errors: list[float], step: float, last_inc: int, last_dec: int,
                     increase: float, decrease: float) -> tuple[float, int, int]:
    """MATLAB anfis step rule: x decrease after down-up-down-up, x increase after 4 straight drops.

    Either change waits at least 4 epochs after the previous change of the
    same kind; a decrease takes precedence.
    """
    i = len(errors) - 1
    if i < 4:
        return step, last_inc, last_dec
    e = errors
    if i - last_dec >= 4 and e[i] < e[i - 1] > e[i - 2] < e[i - 3] > e[i - 4] and decrease != 1.0:
        return step * decrease, last_inc, i
    if i - last_inc >= 4 and e[i] < e[i - 1] < e[i - 2] < e[i - 3] < e[i - 4] and increase != 1.0:
        return step * increase, i, last_dec
    return step, last_inc, last_dec


def train_hybrid(x: np.ndarray, y: np.ndarray, *, mfs: int = 2, structure: str = "grid",
                 epochs: int = 100, initial_step: float = 0.01, step_increase: float = 1.1,
                 step_decrease: float = 0.9, ridge: float = 1e-6,
                 init: AnfisModel | None = None) -> TrainingResult:
    """Jang's hybrid learning: LS consequents forward, normalized gradient step on the premise backward.

    Each epoch solves the consequents for the current premise, records that
    model and its RMSE, then moves (a, b, c) by ``step * g / |g|``. The step
    follows MATLAB's rule; the returned model is the epoch of lowest RMSE.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    model = init if init is not None else initial_model(x, mfs, structure)
    shape_e = (epochs,) + model.a.shape
    hist_a, hist_b, hist_c = np.empty(shape_e), np.empty(shape_e), np.empty(shape_e)
    hist_q = np.empty((epochs,) + (model.n_rules, model.inputs + 1))
    hist_rmse, hist_step = np.empty(epochs), np.empty(epochs)
    errors: list[float] = []
    step, last_inc, last_dec = initial_step, -1, -1
    for k in range(epochs):
        terms = bell_derivatives(x, model.a, model.b, model.c)
        sel = rule_grades(terms[0], model.rules)
        w = sel.prod(axis=-1)
        total = np.maximum(w.sum(axis=-1, keepdims=True), _S_FLOOR)
        wbar = w / total
        model = model.with_consequents(fit_consequents(x, wbar, y, ridge))
        f = rule_outputs(x, model.consequents)
        resid = y - (wbar * f).sum(axis=-1)
        errors.append(float(np.sqrt(np.mean(resid ** 2))))
        hist_a[k], hist_b[k], hist_c[k], hist_q[k] = model.a, model.b, model.c, model.consequents
        hist_rmse[k] = errors[-1]
        model = _gradient_step(model, _premise_gradient(x, y, terms, sel, model, (w, total, f)), step)
        step, last_inc, last_dec = step_size_update(errors, step, last_inc, last_dec,
                                                    step_increase, step_decrease)
        hist_step[k] = step
    history = TrainingHistory(hist_a, hist_b, hist_c, hist_q, hist_rmse, hist_step)
    best = int(np.argmin(hist_rmse))
    return TrainingResult(history.model_at(best, model.rules, model.structure),
                          float(hist_rmse[best]), best, history)


def _gradient_step(model: AnfisModel, grad: tuple[np.ndarray, np.ndarray, np.ndarray],
                   step: float) -> AnfisModel:
    """Move the premise by ``step`` along the negative gradient direction (Jang's normalized step)."""
    ga, gb, gc = grad
    norm = float(np.sqrt(np.sum(ga ** 2) + np.sum(gb ** 2) + np.sum(gc ** 2)))
    if not np.isfinite(norm) or norm == 0.0:
        return model
    k = step / norm
    return model.with_premise(model.a - k * ga, model.b - k * gb, model.c - k * gc)
