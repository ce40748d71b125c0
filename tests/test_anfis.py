"""ANFIS: layers against slow references, analytic gradients against finite differences, training."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.detectors import anfis as A


def jang(x: np.ndarray) -> np.ndarray:
    """Jang's 3-input benchmark (1 + x^0.5 + y^-1 + z^-1.5)^2 on [1, 6]^3."""
    return (1.0 + x[:, 0] ** 0.5 + x[:, 1] ** -1.0 + x[:, 2] ** -1.5) ** 2


def random_model(rng: np.random.Generator, mfs: int = 2, structure: str = "grid",
                 inputs: int = 3) -> A.AnfisModel:
    """A genfis1 model over [0, 1] with every parameter jittered, random consequents."""
    m = A.initial_model(np.zeros((1, inputs)), mfs, structure, lo=np.zeros(inputs), hi=np.ones(inputs))
    shape = m.a.shape
    m = m.with_premise(m.a * rng.uniform(0.6, 1.4, shape), m.b * rng.uniform(0.6, 1.4, shape),
                       m.c + rng.normal(0.0, 0.15, shape))
    return m.with_consequents(rng.normal(0.0, 2.0, m.consequents.shape))


def slow_predict(m: A.AnfisModel, x: np.ndarray) -> np.ndarray:
    """Layer-by-layer reference with explicit loops over samples and rules (A.21-A.25)."""
    out = np.empty(x.shape[0])
    for n, row in enumerate(x):
        w = np.empty(m.n_rules)
        f = np.empty(m.n_rules)
        for r, mf in enumerate(m.rules):
            grades = [1.0 / (1.0 + abs((row[d] - m.c[d, k]) / m.a[d, k]) ** (2 * m.b[d, k]))
                      for d, k in enumerate(mf)]
            w[r] = np.prod(grades)
            f[r] = m.consequents[r, :-1] @ row + m.consequents[r, -1]
        out[n] = (w * f).sum() / w.sum()
    return out


def finite_difference(m: A.AnfisModel, x: np.ndarray, y: np.ndarray, h: float = 1e-6) -> list[np.ndarray]:
    """Central differences of the SSE with respect to every a, b, c."""
    params = [m.a, m.b, m.c]
    grads = []
    for i, p in enumerate(params):
        g = np.zeros_like(p)
        for idx in np.ndindex(p.shape):
            plus = [q.copy() for q in params]
            minus = [q.copy() for q in params]
            plus[i][idx] += h
            minus[i][idx] -= h
            g[idx] = (A.sse(m.with_premise(*plus), x, y) - A.sse(m.with_premise(*minus), x, y)) / (2 * h)
        grads.append(g)
    return grads


def test_bell_values_at_centre_and_crossover() -> None:
    a, b, c = np.array(0.5), np.array(2.0), np.array(0.3)
    assert A.bell(np.array(0.3), a, b, c) == 1.0
    assert A.bell(np.array(0.8), a, b, c) == pytest.approx(0.5)
    assert A.bell(np.array(-0.2), a, b, c) == pytest.approx(0.5)
    # |t| = 2, 2b = 4: 1 / (1 + 16)
    assert A.bell(np.array(1.3), a, b, c) == pytest.approx(1.0 / 17.0)


def test_rule_tables() -> None:
    grid = A.rule_table(3, 2, "grid")
    assert grid.shape == (8, 3)
    assert len({tuple(r) for r in grid}) == 8
    assert grid[0].tolist() == [0, 0, 0] and grid[1].tolist() == [0, 0, 1]
    assert A.rule_table(3, 3, "grid").shape == (27, 3)
    assert A.rule_table(3, 3, "diagonal").tolist() == [[0, 0, 0], [1, 1, 1], [2, 2, 2]]
    with pytest.raises(ValueError):
        A.rule_table(3, 2, "scatter")


def test_genfis1_layout() -> None:
    a, b, c = A.genfis1_premise(np.array([0.0, 1.0]), np.array([1.0, 6.0]), 3)
    np.testing.assert_allclose(c, [[0.0, 0.5, 1.0], [1.0, 3.5, 6.0]])
    np.testing.assert_allclose(a, [[0.25] * 3, [1.25] * 3])
    np.testing.assert_allclose(b, 2.0)
    a2, _, c2 = A.genfis1_premise(np.zeros(1), np.ones(1), 2)
    np.testing.assert_allclose(a2, [[0.5, 0.5]])
    np.testing.assert_allclose(c2, [[0.0, 1.0]])


@pytest.mark.parametrize("structure,mfs", [("grid", 2), ("grid", 3), ("diagonal", 3)])
def test_predict_matches_slow_reference(structure: str, mfs: int) -> None:
    rng = np.random.default_rng(7)
    m = random_model(rng, mfs, structure)
    x = rng.uniform(-0.2, 1.2, (40, 3))
    np.testing.assert_allclose(A.predict(m, x), slow_predict(m, x), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("structure,mfs,seed", [("grid", 2, 0), ("grid", 3, 1), ("diagonal", 3, 2),
                                                 ("grid", 2, 3)])
def test_gradient_agrees_with_finite_differences(structure: str, mfs: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    m = random_model(rng, mfs, structure)
    x = rng.uniform(0.0, 1.0, (60, 3))
    y = rng.normal(0.0, 3.0, 60)
    analytic = A.premise_gradient(m, x, y)
    for got, want in zip(analytic, finite_difference(m, x, y)):
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6 * np.abs(want).max())


def test_gradient_finite_at_a_centre_and_far_away() -> None:
    m = A.initial_model(np.zeros((1, 3)), 2, lo=np.zeros(3), hi=np.ones(3))
    m = m.with_consequents(np.arange(32, dtype=float).reshape(8, 4))
    x = np.array([[0.0, 1.0, 0.0], [1e6, -1e6, 0.5], [0.5, 0.5, 0.5]])
    grads = A.premise_gradient(m, x, np.array([1.0, 2.0, 3.0]))
    assert all(np.isfinite(g).all() for g in grads)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-1e3, 1e3), st.floats(0.05, 10.0))
def test_normalized_firing_sums_to_one(seed: int, shift: float, slope: float) -> None:
    rng = np.random.default_rng(seed)
    m = random_model(rng)
    b = np.full_like(m.b, slope)
    x = rng.uniform(0.0, 1.0, (5, 3)) + shift
    w, wbar = A.normalized_firing(x, m.a, b, m.c, m.rules)
    assert np.all(w >= 0.0) and np.all(np.isfinite(wbar))
    sums = wbar.sum(axis=-1)
    # far outside every MF all grades underflow to 0: then nothing fires at all
    assert np.all((np.abs(sums - 1.0) < 1e-9) | (sums == 0.0))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_bell_derivatives_are_finite(seed: int) -> None:
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.01, 2.0, (3, 2)) * rng.choice([-1.0, 1.0], (3, 2))
    b = rng.uniform(0.1, 20.0, (3, 2))
    c = rng.uniform(-1.0, 2.0, (3, 2))
    x = np.concatenate([rng.uniform(-1e4, 1e4, (4, 3)), c.T[:1].repeat(1, axis=0)])
    for arr in A.bell_derivatives(x, a, b, c):
        assert np.isfinite(arr).all()


def test_least_squares_reproduces_a_linear_target_exactly() -> None:
    rng = np.random.default_rng(3)
    x = rng.uniform(0.0, 1.0, (200, 3))
    y = 2.0 * x[:, 0] - 5.0 * x[:, 1] + 0.5 * x[:, 2] + 7.0
    m = random_model(rng)
    _, wbar = A.normalized_firing(x, m.a, m.b, m.c, m.rules)
    fitted = m.with_consequents(A.fit_consequents(x, wbar, y, ridge=1e-10))
    assert A.rmse(fitted, x, y) < 1e-6


def test_batched_consequents_equal_one_by_one() -> None:
    rng = np.random.default_rng(4)
    x = rng.uniform(0.0, 1.0, (80, 3))
    y = np.sin(3 * x[:, 0]) + x[:, 1] * x[:, 2]
    models = [random_model(rng) for _ in range(5)]
    a = np.stack([m.a for m in models])
    b = np.stack([m.b for m in models])
    c = np.stack([m.c for m in models])
    _, wbar = A.normalized_firing(x, a, b, c, models[0].rules)
    batched = A.fit_consequents(x, wbar, y)
    assert batched.shape == (5, 8, 4)
    for k, m in enumerate(models):
        _, wb = A.normalized_firing(x, m.a, m.b, m.c, m.rules)
        np.testing.assert_allclose(batched[k], A.fit_consequents(x, wb, y), rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("errors,expected", [
    ([5.0, 4.0, 3.0, 2.0, 1.0], "up"),          # four straight decreases
    ([5.0, 6.0, 4.0, 5.0, 3.0], "down"),        # up-down twice
    ([5.0, 4.0, 3.0, 3.5, 2.0], "same"),
    ([1.0, 2.0, 3.0], "same"),                  # too short to judge
])
def test_matlab_step_rule(errors: list[float], expected: str) -> None:
    step, _, _ = A.step_size_update(errors, 0.01, -1, -1, 1.1, 0.9)
    assert step == pytest.approx({"up": 0.011, "down": 0.009, "same": 0.01}[expected])


def test_step_rule_waits_four_epochs_between_changes() -> None:
    errors = [10.0 - k for k in range(8)]
    step, inc, dec = 0.01, -1, -1
    steps = []
    for k in range(1, len(errors) + 1):
        step, inc, dec = A.step_size_update(errors[:k], step, inc, dec, 1.1, 0.9)
        steps.append(step)
    # increases after epochs 4 and 8 (0-based index 4, then 4 epochs later would be 8)
    assert steps[4] == pytest.approx(0.011)
    assert steps[5] == steps[6] == steps[7] == pytest.approx(0.011)


def test_training_keeps_the_best_epoch_and_records_history() -> None:
    rng = np.random.default_rng(5)
    x = rng.uniform(0.0, 1.0, (150, 3))
    y = np.abs(10 * x[:, 0] + rng.normal(0.0, 1.0, 150))
    res = A.train_hybrid(x, y, epochs=30)
    h = res.history
    assert h.epochs == 30 and h.a.shape == (30, 3, 2) and h.consequents.shape == (30, 8, 4)
    assert res.rmse == h.rmse.min() and res.best_epoch == int(np.argmin(h.rmse))
    assert A.rmse(res.model, x, y) == pytest.approx(res.rmse, rel=1e-9)
    np.testing.assert_array_equal(res.model.c, h.c[res.best_epoch])
    assert h.rmse[-1] < h.rmse[0]


def test_training_is_deterministic() -> None:
    rng = np.random.default_rng(6)
    x = rng.uniform(0.0, 1.0, (100, 3))
    y = x.sum(axis=1) ** 2
    r1 = A.train_hybrid(x, y, epochs=20)
    r2 = A.train_hybrid(x, y, epochs=20)
    np.testing.assert_array_equal(r1.history.rmse, r2.history.rmse)


@pytest.fixture(scope="module")
def jang_data() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """1000 training and 1000 test points uniform on [1, 6]^3, scaled to [0, 1] as the detector does."""
    rng = np.random.default_rng(2023)
    xtr = rng.uniform(1.0, 6.0, (1000, 3))
    xte = rng.uniform(1.0, 6.0, (1000, 3))
    lo, hi = np.ones(3), np.full(3, 6.0)
    return A.normalize(xtr, lo, hi), jang(xtr), A.normalize(xte, lo, hi), jang(xte)


@pytest.mark.parametrize("mfs,limit", [(2, 0.07), (3, 0.02)])
def test_jang_function(jang_data: tuple[np.ndarray, ...], mfs: int, limit: float) -> None:
    xtr, ytr, xte, yte = jang_data
    res = A.train_hybrid(xtr, ytr, mfs=mfs, epochs=100)
    assert res.model.n_rules == mfs ** 3
    assert A.rmse(res.model, xte, yte) <= limit


def test_minmax_and_normalize() -> None:
    x = np.array([[0.0, 5.0, np.nan], [10.0, 5.0, np.nan], [5.0, 5.0, np.nan]])
    lo, hi = A.minmax_bounds(x)
    np.testing.assert_allclose(lo, [0.0, 5.0, 0.0])
    np.testing.assert_allclose(hi, [10.0, 6.0, 1.0])     # flat and empty columns get a unit span
    z = A.normalize(np.array([[-5.0, 5.5, 2.0], [20.0, 5.0, 0.5]]), lo, hi)
    np.testing.assert_allclose(z, [[0.0, 0.5, 1.0], [1.0, 0.0, 0.5]])


def test_output_surface_matches_predict() -> None:
    m = random_model(np.random.default_rng(11))
    u, v, z = A.output_surface(m, pair=(0, 2), fixed=0.3, resolution=7)
    assert u.shape == (7,) and z.shape == (7, 7)
    assert z[2, 5] == pytest.approx(A.predict(m, np.array([[u[2], 0.3, v[5]]]))[0], rel=1e-12)


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([("grid", 2), ("grid", 3), ("diagonal", 3)]),
       st.lists(st.one_of(st.floats(-50.0, 150.0), st.sampled_from([float("inf"), -float("inf"), 1e300])),
                min_size=3, max_size=3))
def test_point_predictor_equals_predict(seed: int, layout: tuple[str, int], feats: list[float]) -> None:
    """The one-epoch predictor gives predict()'s output on normalized, clipped inputs."""
    structure, mfs = layout
    rng = np.random.default_rng(seed)
    m = random_model(rng, mfs, structure)
    lo, hi = np.array([0.0, 1.0, 9.0]), np.array([40.0, 60.0, 900.0])
    point = A.PointPredictor(m, lo, hi)
    want = A.predict(m, A.normalize(np.array([feats]), lo, hi))[0]
    assert point(feats) == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_point_predictor_nan_and_far_tails() -> None:
    rng = np.random.default_rng(3)
    m = random_model(rng)
    point = A.PointPredictor(m, np.zeros(3), np.ones(3))
    assert np.isnan(point([0.5, float("nan"), 0.5]))
    steep = m.with_premise(m.a * 1e-3, m.b * 400.0, m.c)      # |t|^(2b) overflows a Python float
    got = A.PointPredictor(steep, np.zeros(3), np.ones(3))([1.0, 0.0, 0.37])
    assert got == pytest.approx(A.predict(steep, np.array([[1.0, 0.0, 0.37]]))[0], rel=1e-9, abs=1e-12)
