"""Delay-only anti-outlier positioning baselines compared against KMCDF (seed 003 section 4).

Each follows its published algorithm as seed 003 cites it, with the
constants seed 003 gives; everything is vectorized over a leading trial axis
T. Inputs are ranges `c t_i` in metres (T, N) and node positions (N, 2), or
per trial (T, N, 2) when the nodes move between epochs; each returns a `BaselineResult` with the
delay states (True = judged normal).

- GAR: greedy attack-resistant MMSE, Liu, Ning, Du, IPSN 2005 (seed 003 ref. [5]).
- EAR: voting-based location estimation with iterative refinement, Liu, Ning,
  Liu, Wang, Du, ACM TISSEC 2008 (ref. [6]); seed 003 gives it a candidate
  ring width `W = 6 c sigma_t`, which only the voting scheme has.
- LMS: least median of squares with reweighting, Li, Trappe, Zhang, Nath,
  IPSN 2005 (ref. [7]), after Rousseeuw's LMS.
- LHC: least Huber cost by iterative majorization, Korkmaz and van der Veen,
  ICASSP 2009 (ref. [8]).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

BASELINES: tuple[str, ...] = ("gar", "ear", "lms", "lhc")


@dataclass(frozen=True)
class BaselineResult:
    """Delay states and position estimate of a delay-only method for T trials."""

    normal: BoolArray      # (T, N) delay judged normal
    position: FloatArray   # (T, 2)
    resolved: BoolArray    # (T,) the method reached a decision (GAR: a consistent set)


def toa_linear_fix(node_xy: FloatArray, ranges: FloatArray, weights: FloatArray) -> FloatArray:
    """Weighted linearized range fix (..., 2): circle equations minus their weighted mean.

    `|x|^2 - 2 x_i^T x + |x_i|^2 = r_i^2`; subtracting the weighted mean
    removes `|x|^2` and leaves a 2x2 weighted least-squares problem. NaN when
    the weighted nodes are fewer than three or collinear.
    """
    wsum = np.sum(weights, axis=-1, keepdims=True)
    wn = weights / np.where(wsum > 0, wsum, 1.0)
    b = ranges**2 - np.sum(node_xy**2, axis=-1)
    g = -2.0 * (node_xy - np.einsum("...n,...nk->...k", wn, node_xy)[..., None, :])
    rhs = b - np.sum(wn * b, axis=-1, keepdims=True)
    info = np.einsum("...n,...ni,...nj->...ij", weights, g, g)
    vec = np.einsum("...n,...ni,...n->...i", weights, g, rhs)
    return _solve_2x2(info, vec)


def _solve_2x2(m: FloatArray, v: FloatArray) -> FloatArray:
    """Batched solve of 2x2 systems; NaN where (near) singular."""
    det = m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
    ok = det > 1e-10 * np.maximum(m[..., 0, 0] * m[..., 1, 1], 1e-300)
    safe = np.where(ok, det, 1.0)
    x = (m[..., 1, 1] * v[..., 0] - m[..., 0, 1] * v[..., 1]) / safe
    y = (m[..., 0, 0] * v[..., 1] - m[..., 1, 0] * v[..., 0]) / safe
    return np.where(ok[..., None], np.stack([x, y], axis=-1), np.nan)


def toa_residuals(node_xy: FloatArray, ranges: FloatArray, xy: FloatArray) -> FloatArray:
    """Range residuals `r_i - |x - x_i|` (..., N)."""
    d = xy[..., None, :] - node_xy
    return ranges - np.hypot(d[..., 0], d[..., 1])


def toa_mmse(
    node_xy: FloatArray, ranges: FloatArray, weights: FloatArray, iterations: int = 8,
) -> FloatArray:
    """Weighted nonlinear least-squares range fix (..., 2): Gauss-Newton from the linear fix."""
    xy = toa_linear_fix(node_xy, ranges, weights)
    for _ in range(iterations):
        d = xy[..., None, :] - node_xy
        r = np.maximum(np.hypot(d[..., 0], d[..., 1]), 1e-9)
        jac = d / r[..., None]
        jw = jac * weights[..., None]
        info = np.einsum("...ni,...nj->...ij", jw, jac)
        grad = np.einsum("...ni,...n->...i", jw, ranges - r)
        step = _solve_2x2(info, grad)
        xy = np.where(np.isfinite(step), xy + step, xy)
    return xy


def gar(node_xy: FloatArray, ranges: FloatArray, threshold_m2: float, min_references: int = 3,
        ) -> BaselineResult:
    """Greedy attack-resistant MMSE (Liu, Ning, Du 2005).

    The MMSE fix of the current reference set is consistent when the mean
    square range residual is at most `threshold_m2` (seed 003: `5.76 c^2
    sigma_t^2`). Otherwise every subset with one reference fewer is tried and
    the one of least mean square residual kept, until consistent or only
    `min_references` remain (then `resolved` is False).
    """
    t, n = ranges.shape
    per_trial = node_xy.ndim == 3
    mask = np.ones((t, n), dtype=bool)
    xy = toa_mmse(node_xy, ranges, mask.astype(float))
    mse = _mean_square(node_xy, ranges, xy, mask)
    todo = ~(mse <= threshold_m2)
    for _ in range(n, min_references, -1):   # at most one removal per node
        idx = np.nonzero(todo)[0]
        if idx.size == 0:
            break
        cand = mask[idx][:, None, :] & ~np.eye(n, dtype=bool)          # (Ta, N, N)
        nodes = node_xy[idx][:, None] if per_trial else node_xy
        cxy = toa_mmse(nodes, ranges[idx][:, None, :], cand.astype(float))
        cmse = _mean_square(nodes, ranges[idx][:, None, :], cxy, cand)
        cmse = np.where(mask[idx], np.nan_to_num(cmse, nan=np.inf), np.inf)
        best = np.argmin(cmse, axis=-1)
        take = np.arange(idx.size)
        mask[idx] = cand[take, best]
        xy[idx], mse[idx] = cxy[take, best], cmse[take, best]
        todo[idx] = ~(mse[idx] <= threshold_m2)
    return BaselineResult(mask, xy, mse <= threshold_m2)


def _mean_square(node_xy: FloatArray, ranges: FloatArray, xy: FloatArray, mask: BoolArray,
                 ) -> FloatArray:
    """Mean square range residual over the references in `mask`."""
    res = toa_residuals(node_xy, ranges, xy)
    count = np.maximum(np.sum(mask, axis=-1), 1)
    return np.sum(np.where(mask, res**2, 0.0), axis=-1) / count


def _ring_hits(node_xy: FloatArray, ranges: FloatArray, centres: FloatArray, half: float,
               ring_half_width: float) -> BoolArray:
    """Whether each reference's ring meets each square cell: ranges (V, N), centres (V, C, 2) -> (V, C, N).

    Nodes are (N, 2) or, per trial, (V, N, 2).
    """
    nodes = node_xy[:, None] if node_xy.ndim == 3 else node_xy
    off = np.abs(centres[..., None, :] - nodes)                        # (V, C, N, 2)
    near = np.hypot(*np.moveaxis(np.maximum(off - half, 0.0), -1, 0))
    far = np.hypot(*np.moveaxis(off + half, -1, 0))
    r = ranges[:, None, :]
    return (near <= r + ring_half_width) & (far >= r - ring_half_width)


def _grid_ring_votes(node_xy: FloatArray, ranges: FloatArray, base: FloatArray, step: FloatArray, half: float,
                     ring_half_width: float) -> NDArray[np.intp]:
    """Votes of the cells `base + (step_i, step_j)` (i-major): `_ring_hits` summed over references, (V, S*S).

    The cells form a grid, so the per-axis offsets are worked out per row and
    column (S values, not S*S) and only the distances per cell: the same
    floats as `_ring_hits` on the grid's centres, at a fraction of the cost.
    """
    nodes = node_xy if node_xy.ndim == 3 else node_xy[None]          # (V or 1, N, 2)
    ox = np.abs((base[:, 0, None] + step)[:, :, None] - nodes[:, None, :, 0])   # (V, S, N)
    oy = np.abs((base[:, 1, None] + step)[:, :, None] - nodes[:, None, :, 1])
    near = np.hypot(np.maximum(ox - half, 0.0)[:, :, None], np.maximum(oy - half, 0.0)[:, None])
    far = np.hypot((ox + half)[:, :, None], (oy + half)[:, None])   # (V, S, S, N)
    r = ranges[:, None, None, :]
    hits = (near <= r + ring_half_width) & (far >= r - ring_half_width)
    return np.count_nonzero(hits, axis=-1).reshape(base.shape[0], -1)


def ear(
    node_xy: FloatArray, ranges: FloatArray, ring_width_m: float, *,
    field_half_width_m: float = 1000.0, field_centre_xy: tuple[float, float] | FloatArray = (0.0, 0.0),
    split: int = 10, levels: int = 3, max_cells: int = 16,
) -> BaselineResult:
    """Voting-based location estimation with iterative refinement (Liu, Ning, Liu, Wang, Du 2008).

    Each reference votes for the square cells its ring (measured range +-
    W/2) meets. The field (seed 003: the +-1000 m square about the origin;
    elsewhere, a square that surely holds the target) is cut into
    `split` x `split` cells; the cells with the highest vote (up to
    `max_cells` on ties) are cut again, `levels` times (200 m, 20 m, 2 m
    cells by default). The estimate is the mean of the winning finest cells;
    a delay is normal when its ring meets the first of them. The field
    centre may differ per trial, shape (T, 2).
    """
    t = ranges.shape[0]
    per_trial = node_xy.ndim == 3
    grid = (np.arange(split) + 0.5) / split - 0.5                     # sub-cell centre offsets
    sub = np.stack(np.meshgrid(grid, grid, indexing="ij"), -1).reshape(-1, 2)
    centres = np.broadcast_to(np.asarray(field_centre_xy, dtype=np.float64).reshape(-1, 1, 2), (t, 1, 2))
    keep = np.ones((t, 1), dtype=bool)
    size = 2.0 * field_half_width_m
    for _ in range(levels):
        rows, slots = np.nonzero(keep)                                # only live cells are split
        base = centres[rows, slots]                                    # (V, 2)
        cells = base[:, None, :] + size * sub                          # (V, S, 2)
        step = size * grid
        size /= split
        nodes = node_xy[rows] if per_trial else node_xy
        votes = _grid_ring_votes(nodes, ranges[rows], base, step, size / 2, ring_width_m / 2)
        best = np.full(t, -1)
        np.maximum.at(best, rows, np.max(votes, axis=-1))
        centres, keep = _top_cells(cells, votes == best[rows][:, None], rows, t, max_cells)
    position = np.sum(centres * keep[..., None], axis=1) / np.sum(keep, axis=1, keepdims=True)
    hits = _ring_hits(node_xy, ranges, centres[:, :1], size / 2, ring_width_m / 2)[:, 0]
    return BaselineResult(hits, position, np.ones(t, dtype=bool))


def _top_cells(cells: FloatArray, top: BoolArray, rows: NDArray[np.intp], trials: int,
               max_cells: int) -> tuple[FloatArray, BoolArray]:
    """The first `max_cells` winning cells of each trial, in grid order: centres (T, K, 2), live (T, K)."""
    flat = np.nonzero(top.reshape(-1))[0]
    owner = np.repeat(rows, top.shape[1])[flat]                       # rows are sorted by trial
    rank = np.arange(flat.size) - np.searchsorted(owner, owner, side="left")
    take = rank < max_cells
    centres = np.zeros((trials, max_cells, 2))
    keep = np.zeros((trials, max_cells), dtype=bool)
    centres[owner[take], rank[take]] = cells.reshape(-1, 2)[flat[take]]
    keep[owner[take], rank[take]] = True
    return centres, keep


def lms(node_xy: FloatArray, ranges: FloatArray, gamma: float = 2.5, subset_size: int = 3,
        ) -> BaselineResult:
    """Least median of squares with reweighting (Li, Trappe, Zhang, Nath 2005; Rousseeuw).

    Every subset of `subset_size` references (all of them: N is small, so no
    random drawing) gives an LS fix; the one with the least median squared
    residual over all references wins. Robust scale `s0 = 1.4826 (1 + 5/(N -
    2)) sqrt(med)`; references with `|r_i| <= gamma s0` are normal and give
    the final LS fix. `np.median` averages the two middle values for even N.
    """
    n = ranges.shape[1]
    subsets = np.zeros((0, n), dtype=bool)
    for combo in combinations(range(n), subset_size):
        row = np.zeros((1, n), dtype=bool)
        row[0, list(combo)] = True
        subsets = np.concatenate([subsets, row])
    weights = np.broadcast_to(subsets.astype(float), (ranges.shape[0],) + subsets.shape)
    nodes = node_xy[:, None] if node_xy.ndim == 3 else node_xy
    xy = toa_mmse(nodes, ranges[:, None, :], weights)                   # (T, S, 2)
    res2 = toa_residuals(nodes, ranges[:, None, :], xy) ** 2
    med = np.nan_to_num(np.median(res2, axis=-1), nan=np.inf)
    best = np.argmin(med, axis=-1)
    take = np.arange(ranges.shape[0])
    s0 = 1.4826 * (1.0 + 5.0 / (n - 2)) * np.sqrt(med[take, best])
    normal = np.sqrt(res2[take, best]) <= gamma * s0[:, None]
    final = toa_mmse(node_xy, ranges, normal.astype(float))
    return BaselineResult(normal, final, np.isfinite(s0))


def lhc(node_xy: FloatArray, ranges: FloatArray, huber_k_m: float, *, tolerance_m: float = 1e-6,
        max_iterations: int = 20000) -> BaselineResult:
    """Least Huber cost by iterative majorization (Korkmaz and van der Veen 2009).

    Minimizes `sum_i H_k(r_i - |x - x_i|)`: the Huber function is majorized by
    a quadratic of weight `min(1, k/|e_i|)` and the distance term by the
    SMACOF (Guttman) bound, giving the update
    `x <- sum_i w_i (x_i + r_i (x - x_i)/|x - x_i|) / sum_i w_i`, iterated
    until a step is below `tolerance_m` (the majorization converges slowly,
    so a fixed small count would stop short). Starts from the least-squares
    fix of all ranges; a delay whose final residual lies within the Huber
    break point `k` (seed 003: 1 ms, i.e. 1.5 m) is normal.
    """
    xy = toa_mmse(node_xy, ranges, np.ones_like(ranges))
    xy = np.where(np.isfinite(xy), xy, np.mean(node_xy, axis=-2))
    live = np.arange(ranges.shape[0])
    per_trial = node_xy.ndim == 3
    for _ in range(max_iterations):
        nodes = node_xy[live] if per_trial else node_xy
        new = _majorization_step(nodes, ranges[live], xy[live], huber_k_m)
        moved = np.hypot(*(new - xy[live]).T) > tolerance_m
        xy[live] = new
        live = live[moved]
        if live.size == 0:
            break
    normal = np.abs(toa_residuals(node_xy, ranges, xy)) <= huber_k_m
    return BaselineResult(normal, xy, np.ones(ranges.shape[0], dtype=bool))


def _majorization_step(node_xy: FloatArray, ranges: FloatArray, xy: FloatArray, k: float,
                       ) -> FloatArray:
    """One Huber-SMACOF update of the position (T, 2)."""
    d = xy[:, None, :] - node_xy
    r = np.maximum(np.hypot(d[..., 0], d[..., 1]), 1e-9)
    err = np.abs(ranges - r)
    w = np.where(err <= k, 1.0, k / np.maximum(err, 1e-300))
    target = node_xy + ranges[..., None] * d / r[..., None]
    return np.sum(w[..., None] * target, axis=1) / np.sum(w, axis=1, keepdims=True)
