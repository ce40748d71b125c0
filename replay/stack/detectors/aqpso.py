"""AQPSO-GA: ANFIS premise search by adaptive quantum-behaved PSO hybridized with a GA.

Patent P (seed 004, steps 3.2.1-3.2.8, eqs. P.29-P.34; docs/design.md section 12).
A particle is the flattened premise ``[a, b, c]`` of every bell (3 D M values);
each particle's consequents are solved by ridge least squares, and its
fitness is the training RMSE (P.34). The whole population is evaluated at
once: memberships, firing strengths and the normal equations of all
particles are stacked, and one batched ``np.linalg.solve`` gives every
particle's consequents.

The patent's equations survive only as numbers; the parts it leaves open are
read as follows (and are parameters of :class:`AqpsoSettings`):

- P.33, the adaptive contraction-expansion coefficient: with the relative
  fitness gap ``err_f = (f_i - f_gbest) / min(f_i, f_gbest)``,
  ``beta_i = beta_min + (beta_max - beta_min) exp(-err_f)``: small when the
  particle is far from the best (converge faster), large when close (search
  wider), as P section 3.2 describes.
- "particles whose update was insufficient" (step 3.2.5): particles whose
  personal best has not improved for ``stall_iterations`` iterations; they
  are re-seeded by arithmetic crossover of two tournament-selected personal
  bests. Mutation (step 3.2.6) then perturbs every particle's genes with
  probability ``mutation_rate`` by Gaussian noise of ``mutation_scale`` of the
  gene's range.
- Particle 0 starts at the genfis1 premise the gradient trainer starts from;
  the others uniformly in the search box.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replay.stack.detectors.anfis import (
    AnfisModel,
    TrainingHistory,
    TrainingResult,
    fit_consequents,
    genfis1_premise,
    normalized_firing,
    rule_outputs,
    rule_table,
)


@dataclass(frozen=True)
class AqpsoSettings:
    """Search parameters of AQPSO-GA (the patent leaves them open; see the module docstring)."""

    particles: int = 30
    iterations: int = 100
    beta_min: float = 0.5
    beta_max: float = 1.0
    stall_iterations: int = 3
    mutation_rate: float = 0.05
    mutation_scale: float = 0.1
    a_range: tuple[float, float] = (0.02, 1.0)   # bell half-width, fraction of the input span
    b_range: tuple[float, float] = (0.5, 8.0)    # bell slope exponent
    c_margin: float = 0.25                       # centres may leave [lo, hi] by this fraction of the span
    ridge: float = 1e-6
    seed: int = 0


def search_box(lo: np.ndarray, hi: np.ndarray, mfs: int,
               settings: AqpsoSettings) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of the flattened premise [a, b, c] (3 D M,) for inputs in [lo, hi]."""
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    span = np.repeat(np.where(hi > lo, hi - lo, 1.0)[:, None], mfs, axis=1)
    low = np.concatenate([(settings.a_range[0] * span).ravel(),
                          np.full(span.size, settings.b_range[0]),
                          (lo[:, None] - settings.c_margin * span).ravel()])
    high = np.concatenate([(settings.a_range[1] * span).ravel(),
                           np.full(span.size, settings.b_range[1]),
                           (hi[:, None] + settings.c_margin * span).ravel()])
    return low, high


def unflatten(pop: np.ndarray, inputs: int, mfs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split particles (..., 3 D M) into a, b, c each (..., D, M)."""
    parts = pop.reshape(*pop.shape[:-1], 3, inputs, mfs)
    return parts[..., 0, :, :], parts[..., 1, :, :], parts[..., 2, :, :]


def population_fitness(x: np.ndarray, y: np.ndarray, pop: np.ndarray, rules: np.ndarray,
                       ridge: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Training RMSE (P.34) and LS consequents of every particle at once: (P,), (P, R, D+1)."""
    a, b, c = unflatten(pop, x.shape[1], int(rules.max()) + 1)
    _, wbar = normalized_firing(x, a, b, c, rules)           # (P, n, R)
    consequents = fit_consequents(x, wbar, y, ridge)         # batched solve
    out = (wbar * rule_outputs(x, consequents)).sum(axis=-1)
    err = np.sqrt(np.mean((out - y) ** 2, axis=-1))
    return np.where(np.isfinite(err), err, np.inf), consequents


def adaptive_beta(fitness: np.ndarray, best: float, settings: AqpsoSettings) -> np.ndarray:
    """Per-particle contraction-expansion coefficient from the relative fitness gap (our reading of P.33)."""
    denom = np.maximum(np.minimum(np.abs(fitness), abs(best)), 1e-12)
    err_f = np.clip((fitness - best) / denom, 0.0, 50.0)
    return settings.beta_min + (settings.beta_max - settings.beta_min) * np.exp(-err_f)


def qpso_move(pos: np.ndarray, pbest: np.ndarray, gbest: np.ndarray, beta: np.ndarray,
              rng: np.random.Generator) -> np.ndarray:
    """Quantum-behaved move of every particle (P.29-P.31): local attractor plus a log-uniform jump."""
    mbest = pbest.mean(axis=0)
    phi = rng.random(pos.shape)
    attractor = phi * pbest + (1.0 - phi) * gbest
    u = 1.0 - rng.random(pos.shape)                          # in (0, 1]: ln(1/u) finite
    sign = np.where(rng.random(pos.shape) < 0.5, -1.0, 1.0)
    return attractor + sign * beta[:, None] * np.abs(mbest - pos) * np.log(1.0 / u)


def ga_reseed(pos: np.ndarray, stalled: np.ndarray, pbest: np.ndarray, pbest_f: np.ndarray,
              rng: np.random.Generator) -> np.ndarray:
    """Replace stalled particles by arithmetic crossovers of tournament-selected personal bests (step 3.2.5)."""
    k = int(stalled.sum())
    if k == 0:
        return pos
    n = pbest.shape[0]
    duel = rng.integers(0, n, size=(2, k, 2))
    parents = np.where(pbest_f[duel[:, :, 0]] <= pbest_f[duel[:, :, 1]], duel[:, :, 0], duel[:, :, 1])
    lam = rng.random((k, pos.shape[1]))
    out = pos.copy()
    out[stalled] = lam * pbest[parents[0]] + (1.0 - lam) * pbest[parents[1]]
    return out


def ga_mutate(pos: np.ndarray, low: np.ndarray, high: np.ndarray, settings: AqpsoSettings,
              rng: np.random.Generator) -> np.ndarray:
    """Gaussian mutation of each gene with probability mutation_rate (step 3.2.6)."""
    hit = rng.random(pos.shape) < settings.mutation_rate
    noise = rng.normal(0.0, 1.0, pos.shape) * settings.mutation_scale * (high - low)
    return np.where(hit, pos + noise, pos)


def train_aqpso_ga(x: np.ndarray, y: np.ndarray, *, mfs: int = 2, structure: str = "grid",
                   settings: AqpsoSettings | None = None, lo: np.ndarray | None = None,
                   hi: np.ndarray | None = None) -> TrainingResult:
    """Train an ANFIS premise by AQPSO-GA with LS consequents (P steps 3.2.1-3.2.8).

    The history has ``iterations + 1`` rows: the initial population's best,
    then the global best after each iteration (its ``step`` column holds the
    population's mean beta).
    """
    s = settings or AqpsoSettings()
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    d = x.shape[1]
    lo = x.min(axis=0) if lo is None else np.asarray(lo, dtype=float)
    hi = x.max(axis=0) if hi is None else np.asarray(hi, dtype=float)
    rules = rule_table(d, mfs, structure)
    rng = np.random.default_rng(s.seed)
    low, high = search_box(lo, hi, mfs, s)
    pos = low + rng.random((s.particles, low.size)) * (high - low)
    pos[0] = np.clip(np.concatenate([p.ravel() for p in genfis1_premise(lo, hi, mfs)]), low, high)
    fit, cons = population_fitness(x, y, pos, rules, s.ridge)
    pbest, pbest_f, stall = pos.copy(), fit.copy(), np.zeros(s.particles, dtype=int)
    g = int(np.argmin(fit))
    gbest, gbest_f, gbest_q = pos[g].copy(), float(fit[g]), cons[g].copy()
    rows = [(gbest, gbest_q, gbest_f, np.nan)]
    for _ in range(s.iterations):
        beta = adaptive_beta(fit, gbest_f, s)
        pos = qpso_move(pos, pbest, gbest, beta, rng)
        pos = ga_reseed(pos, stall >= s.stall_iterations, pbest, pbest_f, rng)
        stall[stall >= s.stall_iterations] = 0
        pos = np.clip(ga_mutate(pos, low, high, s, rng), low, high)
        fit, cons = population_fitness(x, y, pos, rules, s.ridge)
        better = fit < pbest_f
        pbest[better], pbest_f[better] = pos[better], fit[better]
        stall = np.where(better, 0, stall + 1)
        g = int(np.argmin(pbest_f))
        if pbest_f[g] < gbest_f:
            # a new global best was found this iteration, so cons[g] is its consequents
            gbest, gbest_f, gbest_q = pbest[g].copy(), float(pbest_f[g]), cons[g].copy()
        rows.append((gbest, gbest_q, gbest_f, float(beta.mean())))
    return _result(rows, d, mfs, rules, structure)


def _result(rows: list[tuple[np.ndarray, np.ndarray, float, float]], inputs: int, mfs: int,
            rules: np.ndarray, structure: str) -> TrainingResult:
    """Pack the per-iteration global bests into a TrainingResult."""
    prem = np.stack([r[0] for r in rows])
    a, b, c = unflatten(prem, inputs, mfs)
    history = TrainingHistory(a.copy(), b.copy(), c.copy(), np.stack([r[1] for r in rows]),
                              np.array([r[2] for r in rows]), np.array([r[3] for r in rows]))
    best = int(np.argmin(history.rmse))
    model: AnfisModel = history.model_at(best, rules, structure)
    return TrainingResult(model, float(history.rmse[best]), best, history)
