"""KMCDF: anti-outlier LBL/USBL positioning by k-means clustering and decision fusion.

Seed `003` (Wang, Li, Zhang, JEIT 2018, eq. (1)-(10)); docs/design.md section 13.
Pipeline: preliminary fixes from parameter subsets (`usbl_geometry`), a support
matrix and its Perron weights, k-means (k = 2) on the weights with the rho
re-clustering, OR-rule decision fusion of the parameter states, and the final
maximum-likelihood fix over the parameters judged normal.

Batch functions take a leading axis T (Monte Carlo trials or epochs) so a
whole simulation point runs as array operations; `kmcdf_epoch` wraps them for
one USBL epoch of the replay engine. Parameter p of a node set of size N is
the delay of node p (p < N), the x phase of node p - N, or the y phase of node
p - 2N.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from replay.stack.positioning.usbl_geometry import KIND_NAMES, FixLayout, fix_layout, preliminary_fixes

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class KmcdfParams:
    """System and algorithm constants; defaults are the simulation of seed 003 section 4."""

    sound_speed_mps: float = 1500.0
    frequency_hz: float = 75e3
    element_spacing_m: float = 0.18
    rho_m: float = 30.0                  # spread of fixes from normal parameters only
    sigma_delay_s: float = 0.5e-3
    sigma_phase_rad: float = 0.1         # not given by the seed (docs/design.md section 13)
    max_range_m: float = 2830.0
    min_bearing_sin: float = 0.05        # bearing pairs closer than ~2.9 deg give no fix
    ml_iterations: int = 10

    @property
    def kappa_d0(self) -> float:
        """Phase difference per unit direction cosine, `kappa d0 = 2 pi f d0 / c` (rad)."""
        return 2.0 * np.pi * self.frequency_hz * self.element_spacing_m / self.sound_speed_mps


def pairwise_distances(points: FloatArray, valid: BoolArray) -> FloatArray:
    """Distance matrix `A` of seed 003 section 3.2, (T, M, M); 0 wherever a fix is missing."""
    diff = points[..., :, None, :] - points[..., None, :, :]
    dist = np.sqrt(np.sum(diff**2, axis=-1))
    both = valid[..., :, None] & valid[..., None, :]
    return np.where(both, dist, 0.0)


def masked_max(dist: FloatArray, mask: BoolArray) -> FloatArray:
    """Largest distance among the fixes in `mask`, per trial (0 for fewer than two)."""
    both = mask[..., :, None] & mask[..., None, :]
    return np.max(np.where(both, dist, 0.0), axis=(-2, -1))


def perron_weights(dist: FloatArray, mask: BoolArray) -> FloatArray:
    """Support weights of the fixes in `mask`, (T, M), zero outside; seed 003 section 3.2.

    `B = U - A / Amax` over the masked set; `w` is the eigenvector of B's
    largest eigenvalue (Perron-Frobenius: non-negative for a non-negative
    matrix) normalized to sum 1. Masked-out rows and columns are zero, so the
    Perron vector of the whole matrix lives on the mask (diag(B) = 1 there).
    """
    both = mask[..., :, None] & mask[..., None, :]
    amax = np.max(np.where(both, dist, 0.0), axis=(-2, -1))
    scale = np.where(amax > 0.0, amax, 1.0)[..., None, None]
    support = np.where(both, 1.0 - dist / scale, 0.0)
    values, vectors = np.linalg.eigh(support)
    v = np.abs(vectors[..., :, -1]) * mask
    # a repeated largest eigenvalue (two fixes: B = I) has no one Perron vector, and LAPACK's pick depends on
    # the padding of a batch: every fix of the mask then has the same support
    tied = values[..., -1] - values[..., -2] <= 1e-9 * np.maximum(np.abs(values[..., -1]), 1.0) \
        if support.shape[-1] > 1 else np.zeros(values.shape[:-1], dtype=bool)
    v = np.where(tied[..., None], mask.astype(float), v)
    total = np.sum(v, axis=-1, keepdims=True)
    return v / np.where(total > 0.0, total, 1.0)


def kmeans2_1d(weights: FloatArray, mask: BoolArray) -> BoolArray:
    """k-means with k = 2 on 1-D weights: True for the higher cluster, (T, M).

    In one dimension the k-means optimum is a split of the sorted values, so
    the global minimum of the within-cluster sum of squares is found exactly by
    scanning every split (no initialization, no local minima). Ties in the
    objective go to the first split, so equal weights stay deterministic.
    """
    m = weights.shape[-1]
    key = np.where(mask, weights, np.inf)
    order = np.argsort(key, axis=-1, kind="stable")
    ws = np.take_along_axis(np.where(mask, weights, 0.0), order, axis=-1)
    n = np.sum(mask, axis=-1, keepdims=True).astype(float)
    s1, q1 = np.cumsum(ws, axis=-1), np.cumsum(ws**2, axis=-1)
    left = np.arange(1, m + 1, dtype=float)
    right = n - left
    s2, q2 = s1[..., -1:] - s1, q1[..., -1:] - q1
    sse = (q1 - s1**2 / left) + (q2 - s2**2 / np.where(right > 0, right, 1.0))
    sse = np.where((right >= 1) & (left <= n - 1), sse, np.inf)
    split = np.argmin(sse, axis=-1)[..., None] + 1     # size of the low cluster
    rank = np.argsort(order, axis=-1)
    return mask & (rank >= split)


@dataclass(frozen=True)
class Clustering:
    """Outcome of the clustering stage for T trials."""

    cluster1: BoolArray     # (T, M) fix in C1 at the end
    weights: FloatArray     # (T, M) first-round Perron weights (support of each fix)
    amax_m: FloatArray      # (T,) spread of all fixes
    rounds: NDArray[np.intp]  # (T,) k-means rounds run (0: all normal at once)


def cluster_fixes(points: FloatArray, valid: BoolArray, rho_m: float) -> Clustering:
    """k-means on the Perron weights, re-clustering C1 as a new data set until its spread is <= rho.

    Seed 003 section 3.2. Each round recomputes A, Amax, B and the weights on
    the current C1 alone (docs/design.md section 13, step 3); re-clustering the old
    weights instead collapses the success rate. C1 strictly shrinks each
    round, so the loop ends within M rounds.
    """
    t = points.shape[0]
    dist = pairwise_distances(np.nan_to_num(points), valid)
    amax = masked_max(dist, valid)
    weights = perron_weights(dist, valid)
    cluster1 = valid.copy()
    rounds = np.zeros(t, dtype=np.intp)
    todo = amax > rho_m
    first = True
    while np.any(todo):
        idx = np.nonzero(todo)[0]
        mask = cluster1[idx]
        if first:
            high = kmeans2_1d(weights[idx], mask)
            first = False
        else:
            high = _recluster_compact(dist[idx], mask)
        cluster1[idx] = high
        rounds[idx] += 1
        todo[idx] = masked_max(dist[idx], high) > rho_m
    return Clustering(cluster1, weights, amax, rounds)


def _recluster_compact(dist: FloatArray, mask: BoolArray) -> BoolArray:
    """One re-clustering round on the fixes in `mask`, gathered first so the eigenproblem is small."""
    size = int(np.max(np.sum(mask, axis=-1)))
    order = np.argsort(~mask, axis=-1, kind="stable")[:, :size]
    sub = np.take_along_axis(dist, order[:, :, None], axis=1)
    sub = np.take_along_axis(sub, order[:, None, :], axis=2)
    submask = np.take_along_axis(mask, order, axis=-1)
    high_c = kmeans2_1d(perron_weights(sub, submask), submask)
    high = np.zeros_like(mask)
    np.put_along_axis(high, order, high_c, axis=-1)
    return high


def or_fusion(cluster1: BoolArray, incidence: BoolArray) -> BoolArray:
    """Global parameter states by the OR rule, eq. (10): normal iff some fix using it is in C1, (T, 3N)."""
    return (cluster1.astype(np.float64) @ incidence.astype(np.float64)) > 0.5


def _measurement_model(
    xy: FloatArray, node_xy: FloatArray, kappa_d0: float,
) -> tuple[FloatArray, FloatArray]:
    """Predicted [ranges, psi, phi] (T, 3N) and their Jacobian (T, 3N, 2); eq. (1)-(3)."""
    d = xy[:, None, :] - node_xy              # nodes (N, 2) or per trial (T, N, 2)
    r = np.maximum(np.hypot(d[..., 0], d[..., 1]), 1e-6)
    u = d / r[..., None]
    pred = np.concatenate([r, kappa_d0 * u[..., 0], kappa_d0 * u[..., 1]], axis=-1)
    outer = u[..., :, None] * u[..., None, :]                      # (T, N, 2, 2)
    dcos = (np.eye(2) - outer) / r[..., None, None] * kappa_d0     # d(kappa d0 u)/dx
    jac = np.concatenate([u, dcos[..., 0, :], dcos[..., 1, :]], axis=-2)
    return pred, jac


def ml_fix(
    node_xy: FloatArray, delays_s: FloatArray, phase_x: FloatArray, phase_y: FloatArray,
    normal: BoolArray, start_xy: FloatArray, params: KmcdfParams,
) -> tuple[FloatArray, FloatArray]:
    """Maximum-likelihood position over the normal parameters: position (T, 2), covariance (T, 2, 2).

    Eq. (5)-(9) with the states decided: the uniform outlier terms drop out and
    the Gaussian terms of the normal parameters leave weighted least squares,
    solved by Gauss-Newton from `start_xy`. NaN when the normal parameters do
    not determine a position. Each trial stops at its own convergence, so a
    trial's result does not depend on the others in its batch.
    """
    c = params.sound_speed_mps
    meas = np.concatenate([c * delays_s, phase_x, phase_y], axis=-1)
    n = node_xy.shape[-2]
    sig = np.repeat([c * params.sigma_delay_s, params.sigma_phase_rad, params.sigma_phase_rad], n)
    w = np.where(normal & np.isfinite(meas), 1.0 / sig**2, 0.0)
    meas = np.nan_to_num(meas)
    xy = np.nan_to_num(start_xy.astype(np.float64))
    cov = np.full((xy.shape[0], 2, 2), np.nan)
    live = np.arange(xy.shape[0])
    per_trial_nodes = node_xy.ndim == 3
    for _ in range(params.ml_iterations):
        nodes = node_xy[live] if per_trial_nodes else node_xy
        pred, jac = _measurement_model(xy[live], nodes, params.kappa_d0)
        jw = jac * w[live][..., None]
        cov[live] = _inverse_2x2(np.einsum("tki,tkj->tij", jw, jac))
        step = np.nan_to_num(np.einsum("tij,tki,tk->tj", cov[live], jw, meas[live] - pred))
        xy[live] = xy[live] + step
        # converged trials stop here, so cov is at their final point
        live = live[np.max(np.abs(step), axis=-1, initial=0.0) >= 1e-7]
        if live.size == 0:
            break
    bad = ~np.isfinite(cov[:, 0, 0])
    xy[bad] = np.nan
    return xy, cov


def _inverse_2x2(m: FloatArray) -> FloatArray:
    """Batched inverse of symmetric 2x2 matrices; NaN where (near) singular."""
    det = m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] * m[:, 1, 0]
    scale = np.maximum(m[:, 0, 0] * m[:, 1, 1], 1e-300)
    ok = det > 1e-10 * scale
    safe = np.where(ok, det, 1.0)
    inv = np.stack([np.stack([m[:, 1, 1], -m[:, 0, 1]], -1),
                    np.stack([-m[:, 1, 0], m[:, 0, 0]], -1)], -2) / safe[:, None, None]
    return np.where(ok[:, None, None], inv, np.nan)


@dataclass(frozen=True)
class KmcdfBatch:
    """KMCDF outcome for T trials of the same node layout."""

    fixes: FloatArray        # (T, M, 2) preliminary fixes, NaN where none
    valid: BoolArray         # (T, M)
    clustering: Clustering
    normal: BoolArray        # (T, 3N) parameter states: delays, x phases, y phases
    position: FloatArray     # (T, 2)
    covariance: FloatArray   # (T, 2, 2)
    layout: FixLayout


def kmcdf_batch(
    node_xy: FloatArray, delays_s: FloatArray, phase_x: FloatArray, phase_y: FloatArray,
    params: KmcdfParams = KmcdfParams(),
) -> KmcdfBatch:
    """KMCDF over T trials: measurements (T, N) each, nodes (N, 2) or (T, N, 2); seed 003 sections 3.1-3.3."""
    node_xy = np.asarray(node_xy, dtype=np.float64)
    layout = fix_layout(node_xy.shape[-2])
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        fixes = preliminary_fixes(
            node_xy, delays_s, phase_x, phase_y, sound_speed=params.sound_speed_mps,
            kappa_d0=params.kappa_d0, min_bearing_sin=params.min_bearing_sin, layout=layout)
    valid = np.all(np.isfinite(fixes), axis=-1)
    clustering = cluster_fixes(fixes, valid, params.rho_m)
    normal = or_fusion(clustering.cluster1, layout.incidence)
    c1 = clustering.cluster1
    count = np.sum(c1, axis=-1, keepdims=True)
    start = np.sum(np.where(c1[..., None], np.nan_to_num(fixes), 0.0), axis=-2)
    start = start / np.where(count > 0, count, 1)
    position, covariance = ml_fix(node_xy, delays_s, phase_x, phase_y, normal, start, params)
    return KmcdfBatch(fixes, valid, clustering, normal, position, covariance, layout)


@dataclass(frozen=True)
class PreliminaryFix:
    """One preliminary fix of an epoch, for the viewer: what it used, where it fell, its cluster."""

    kind: str                      # usbl | bearing_pair | circle_pair | range_triple
    nodes: tuple[int, ...]
    parameters: tuple[int, ...]    # indices into delays, x phases, y phases (module docstring)
    xy: tuple[float, float]
    cluster: int                   # 1 = C1 (consistent), 2 = C2
    weight: float                  # first-round Perron weight


@dataclass(frozen=True)
class KmcdfFix:
    """KMCDF result of one USBL epoch: position, covariance and the state of every parameter."""

    position_xy: FloatArray        # (2,), NaN if undetermined
    covariance: FloatArray         # (2, 2) m^2
    delay_normal: BoolArray        # (N,)
    phase_normal: BoolArray        # (N, 2): x and y phase differences
    weights: FloatArray            # (M,) first-round Perron weights, 0 where no fix
    clusters: NDArray[np.intp]     # (M,) 1 = C1, 2 = C2, 0 = no fix
    missing_fixes: int             # subsets that gave no fix (circles apart, parallel bearings...)
    rounds: int                    # k-means rounds
    spread_m: float                # Amax over all fixes
    # (layout, fix positions (M, 2)) that `fixes` is built from: only viewers read it, a replay seldom
    _source: tuple[FixLayout, FloatArray] = field(repr=False, compare=False)

    @cached_property
    def fixes(self) -> tuple[PreliminaryFix, ...]:
        """The preliminary fixes that exist, in layout order (built on first use)."""
        layout, xy_all = self._source
        valid = self.clusters > 0
        kinds, xy = layout.kinds.tolist(), xy_all.tolist()
        cl, wt = self.clusters.tolist(), self.weights.tolist()
        return tuple(
            PreliminaryFix(kind=KIND_NAMES[kinds[m]], nodes=layout.node_sets[m],
                           parameters=layout.parameter_sets[m], xy=(xy[m][0], xy[m][1]),
                           cluster=cl[m], weight=wt[m])
            for m in np.nonzero(valid)[0].tolist())


    def fix_columns(self) -> tuple[list[float], list[float], list[int]]:
        """x, y and cluster of the preliminary fixes that exist, in layout order (those of `fixes`), as lists."""
        _, xy_all = self._source
        valid = self.clusters > 0
        return xy_all[valid, 0].tolist(), xy_all[valid, 1].tolist(), self.clusters[valid].tolist()


def kmcdf_epoch(
    node_xy: FloatArray, delays_s: FloatArray, phase_x: FloatArray, phase_y: FloatArray,
    params: KmcdfParams = KmcdfParams(),
) -> KmcdfFix:
    """KMCDF on one epoch: N >= 3 nodes (N, 2), one-way delays (N,), phase differences (N,) each.

    Missing measurements are NaN: fixes that need them do not exist, and a
    parameter with no fix at all is judged abnormal (nothing supports it).
    """
    node_xy = np.asarray(node_xy, dtype=np.float64)
    row = [np.asarray(a, dtype=np.float64)[None, :] for a in (delays_s, phase_x, phase_y)]
    return epoch_fix(kmcdf_batch(node_xy, row[0], row[1], row[2], params), 0)


def kmcdf_epochs(
    node_xy: FloatArray, delays_s: FloatArray, phase_x: FloatArray, phase_y: FloatArray,
    params: KmcdfParams = KmcdfParams(),
) -> list[KmcdfFix]:
    """KMCDF on T epochs at once: nodes (T, N, 2) per epoch, delays and phases (T, N); one fix per epoch.

    Gives the same fixes as `kmcdf_epoch` on each epoch alone.
    """
    batch = kmcdf_batch(np.asarray(node_xy, dtype=np.float64), np.asarray(delays_s, dtype=np.float64),
                        np.asarray(phase_x, dtype=np.float64), np.asarray(phase_y, dtype=np.float64), params)
    return [epoch_fix(batch, i) for i in range(batch.position.shape[0])]


def epoch_fix(batch: KmcdfBatch, i: int) -> KmcdfFix:
    """Trial `i` of a batch as one epoch's `KmcdfFix`, with its preliminary fixes for the viewer."""
    n = batch.normal.shape[-1] // 3
    valid, c1 = batch.valid[i], batch.clustering.cluster1[i]
    clusters = np.where(valid, np.where(c1, 1, 2), 0).astype(np.intp)
    weights = np.where(valid, batch.clustering.weights[i], 0.0)
    normal = batch.normal[i]
    return KmcdfFix(
        position_xy=batch.position[i], covariance=batch.covariance[i],
        delay_normal=normal[:n], phase_normal=np.stack([normal[n:2 * n], normal[2 * n:]], -1),
        weights=weights, clusters=clusters,
        missing_fixes=int(np.sum(~valid)), rounds=int(batch.clustering.rounds[i]),
        spread_m=float(batch.clustering.amax_m[i]), _source=(batch.layout, batch.fixes[i]))
