"""EAR's grid votes: the separable per-row/column path gives exactly `_ring_hits` summed over references."""

from __future__ import annotations

import numpy as np

from replay.stack.positioning.toa_baselines import _grid_ring_votes, _ring_hits


def _reference(nodes: np.ndarray, ranges: np.ndarray, base: np.ndarray, step: np.ndarray, half: float,
               w: float) -> np.ndarray:
    sub = np.stack(np.meshgrid(step, step, indexing="ij"), -1).reshape(-1, 2)
    return np.sum(_ring_hits(nodes, ranges, base[:, None, :] + sub, half, w), -1)


def test_grid_votes_equal_ring_hits() -> None:
    rng = np.random.default_rng(7)
    grid = (np.arange(10) + 0.5) / 10 - 0.5
    for size in (2000.0, 200.0, 20.0):
        base = rng.normal(0.0, 300.0, (40, 2))
        ranges = np.abs(rng.normal(400.0, 300.0, (40, 4)))
        ranges[0, 1] = np.nan                                          # a missing range votes nowhere
        for nodes in (rng.normal(0.0, 500.0, (40, 4, 2)), rng.normal(0.0, 500.0, (4, 2))):
            got = _grid_ring_votes(nodes, ranges, base, size * grid, size / 20, 1.5)
            want = _reference(nodes, ranges, base, size * grid, size / 20, 1.5)
            assert got.shape == want.shape and np.array_equal(got, want)
