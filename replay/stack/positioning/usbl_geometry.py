"""Preliminary position fixes of an integrated LBL/USBL system, vectorized over trials.

Seed `003` (KMCDF, Wang et al., JEIT 2018) section 3.1; docs/design.md section 13, step 1.
Every function takes a leading batch axis `T` (trials or epochs) on the
measurements; node positions are shared, shape (N, 2) in metres, or per
trial, shape (T, N, 2) (an epoch's buoys move), axes x and y of the local
frame the phase differences are measured in. A fix that does not
exist (circles that do not meet, near-parallel bearings, collinear nodes, NaN
input) is NaN, never an exception.

Parameter numbering used by every subset in this package: delay of node i is
parameter i, its x phase difference N + i, its y phase difference 2N + i.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

KIND_USBL = 0        # one node: delay and both phases
KIND_BEARING = 1     # two nodes: bearings intersected
KIND_CIRCLES = 2     # two nodes: range circles intersected
KIND_TRILATERATION = 3  # three nodes: ranges by linear least squares
KIND_NAMES: tuple[str, ...] = ("usbl", "bearing_pair", "circle_pair", "range_triple")


def usbl_fixes(
    node_xy: FloatArray, ranges_m: FloatArray, phase_x: FloatArray, phase_y: FloatArray,
    kappa_d0: float,
) -> FloatArray:
    """Single-node USBL fixes `x_i + c t_i (psi_i, phi_i) / (kappa d0)`, shape (T, N, 2).

    Seed 003 eq. (1)-(3) inverted: the raw direction cosines are used, not a
    normalized bearing, so an abnormal phase (at most pi / (kappa d0) ~ 0.056 as
    a cosine) lands near its own node (docs/design.md section 13, step 1).
    """
    cosines = np.stack([phase_x, phase_y], axis=-1) / kappa_d0
    return node_xy + ranges_m[..., None] * cosines


def bearing_intersections(
    node_xy: FloatArray, bearing_rad: FloatArray, pairs: NDArray[np.intp], min_sin: float,
) -> FloatArray:
    """Intersections of the bearing lines of each node pair, shape (T, P, 2); NaN if near-parallel.

    Solves `x_i + a u_i = x_j + b u_j` (seed 003 section 3.1 (2), bearing-only fix
    of two arrays). Pairs whose bearings differ by less than `asin(min_sin)`
    (modulo pi) give no fix: the intersection is then dominated by noise.
    """
    i, j = pairs[:, 0], pairs[:, 1]
    ui = np.stack([np.cos(bearing_rad[..., i]), np.sin(bearing_rad[..., i])], axis=-1)
    uj = np.stack([np.cos(bearing_rad[..., j]), np.sin(bearing_rad[..., j])], axis=-1)
    delta = node_xy[..., j, :] - node_xy[..., i, :]
    cross = ui[..., 0] * uj[..., 1] - ui[..., 1] * uj[..., 0]
    ok = np.abs(cross) >= min_sin
    safe = np.where(ok, cross, 1.0)
    a = (delta[..., 0] * uj[..., 1] - delta[..., 1] * uj[..., 0]) / safe
    fix = node_xy[..., i, :] + a[..., None] * ui
    return np.where(ok[..., None], fix, np.nan)


def circle_intersections(
    node_xy: FloatArray, ranges_m: FloatArray, pairs: NDArray[np.intp],
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Both intersections of the range circles of each node pair, and whether they meet.

    Returns (first, second, meet), points of shape (T, P, 2). Tangent circles
    give the tangent point twice; circles that do not meet (or have a NaN
    radius) give NaN and `meet` False.
    """
    i, j = pairs[:, 0], pairs[:, 1]
    ri, rj = ranges_m[..., i], ranges_m[..., j]
    delta = node_xy[..., j, :] - node_xy[..., i, :]
    dist = np.hypot(delta[..., 0], delta[..., 1])
    apart = dist > 0.0                      # coincident nodes: no geometry
    safe = np.where(apart, dist, 1.0)
    along = (ri**2 - rj**2 + dist**2) / (2.0 * safe)
    h2 = ri**2 - along**2
    # rounding can push exactly tangent circles a hair apart; keep them as tangent
    tol = 1e-12 * np.maximum(np.maximum(ri**2, rj**2), dist**2)
    meet = (h2 >= -tol) & (ri >= 0.0) & (rj >= 0.0) & apart
    h = np.sqrt(np.where(meet, np.maximum(h2, 0.0), 0.0))
    unit = delta / safe[..., None]
    normal = np.stack([-unit[..., 1], unit[..., 0]], axis=-1)
    foot = node_xy[..., i, :] + along[..., None] * unit
    first = foot + h[..., None] * normal
    second = foot - h[..., None] * normal
    nan = np.where(meet, 0.0, np.nan)[..., None]
    return first + nan, second + nan, meet


def circle_fixes(
    node_xy: FloatArray, ranges_m: FloatArray, pairs: NDArray[np.intp], reference: FloatArray,
) -> FloatArray:
    """Two-node TOA fixes: the circle intersection nearer `reference` (T, P, 2), NaN if none.

    Seed 003 section 3.1 (3); the ambiguity is resolved with the mean of the
    pair's own USBL fixes (docs/design.md section 13, step 1). A NaN reference keeps
    the first solution.
    """
    first, second, _ = circle_intersections(node_xy, ranges_m, pairs)
    d1 = np.sum((first - reference) ** 2, axis=-1)
    d2 = np.sum((second - reference) ** 2, axis=-1)
    take_second = d2 < d1
    return np.where(take_second[..., None], second, first)


def trilateration_fixes(
    node_xy: FloatArray, ranges_m: FloatArray, triples: NDArray[np.intp], min_det: float = 1e-9,
) -> FloatArray:
    """Three-node TOA fixes by the linearized range equations, shape (T, K, 2); NaN if collinear.

    Seed 003 section 3.1 (4): subtracting the first node's circle equation from
    the other two gives `2 (x_j - x_1)^T x = r_1^2 - r_j^2 + |x_j|^2 - |x_1|^2`,
    two linear equations solved exactly. Collinear nodes make the system
    singular (relative determinant below `min_det`): no fix.
    """
    p1, p2, p3 = (node_xy[..., triples[:, k], :] for k in range(3))
    r1, r2, r3 = (ranges_m[..., triples[:, k]] for k in range(3))
    a = 2.0 * np.stack([p2 - p1, p3 - p1], axis=-2)          # (K, 2, 2) or (T, K, 2, 2)
    det = a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
    scale = np.sum(a**2, axis=(-2, -1))
    ok = np.abs(det) > min_det * scale
    safe = np.where(ok, det, 1.0)
    sq = np.sum(node_xy**2, axis=-1)
    b1 = r1**2 - r2**2 + sq[..., triples[:, 1]] - sq[..., triples[:, 0]]
    b2 = r1**2 - r3**2 + sq[..., triples[:, 2]] - sq[..., triples[:, 0]]
    x = (a[..., 1, 1] * b1 - a[..., 0, 1] * b2) / safe
    y = (a[..., 0, 0] * b2 - a[..., 1, 0] * b1) / safe
    fix = np.stack([x, y], axis=-1)
    return np.where(ok[..., None], fix, np.nan)


@dataclass(frozen=True)
class FixLayout:
    """Which parameters and nodes each preliminary fix uses; the same for every trial."""

    kinds: NDArray[np.intp]          # (M,) KIND_* code of each fix
    nodes: NDArray[np.intp]          # (M, 3) nodes used, -1 padded
    incidence: BoolArray             # (M, 3N) fix m uses parameter p
    pairs: NDArray[np.intp]          # (C(N,2), 2)
    triples: NDArray[np.intp]        # (C(N,3), 3)
    node_sets: tuple[tuple[int, ...], ...]       # per fix, the nodes it uses
    parameter_sets: tuple[tuple[int, ...], ...]  # per fix, the parameters it uses


@lru_cache(maxsize=16)
def fix_layout(n_nodes: int) -> FixLayout:
    """The subsets of seed 003 section 3.1, in order: N USBL, C(N,2) bearing, C(N,2) circle, C(N,3) triple.

    Cached per N: the result is shared, so its arrays are made read-only.
    """
    n = n_nodes
    pairs = np.array(list(combinations(range(n), 2)), dtype=np.intp).reshape(-1, 2)
    triples = np.array(list(combinations(range(n), 3)), dtype=np.intp).reshape(-1, 3)
    rows: list[tuple[int, tuple[int, ...], tuple[int, ...]]] = []
    rows += [(KIND_USBL, (i,), (i, n + i, 2 * n + i)) for i in range(n)]
    rows += [(KIND_BEARING, (i, j), (n + i, 2 * n + i, n + j, 2 * n + j)) for i, j in pairs]
    rows += [(KIND_CIRCLES, (i, j), (i, j)) for i, j in pairs]
    rows += [(KIND_TRILATERATION, tuple(t), tuple(t)) for t in triples]
    kinds = np.array([r[0] for r in rows], dtype=np.intp)
    nodes = np.full((len(rows), 3), -1, dtype=np.intp)
    incidence = np.zeros((len(rows), 3 * n), dtype=bool)
    for m, (_, used_nodes, params) in enumerate(rows):
        nodes[m, : len(used_nodes)] = used_nodes
        incidence[m, list(params)] = True
    for array in (kinds, nodes, incidence, pairs, triples):
        array.flags.writeable = False
    node_sets = tuple(tuple(int(k) for k in r[1]) for r in rows)
    parameter_sets = tuple(tuple(sorted(int(p) for p in r[2])) for r in rows)
    return FixLayout(kinds, nodes, incidence, pairs, triples, node_sets, parameter_sets)


def preliminary_fixes(
    node_xy: FloatArray, delays_s: FloatArray, phase_x: FloatArray, phase_y: FloatArray,
    *, sound_speed: float, kappa_d0: float, min_bearing_sin: float, layout: FixLayout,
) -> FloatArray:
    """All M = N + 2 C(N,2) + C(N,3) preliminary fixes in `layout` order, shape (T, M, 2), NaN where none."""
    ranges = sound_speed * delays_s
    usbl = usbl_fixes(node_xy, ranges, phase_x, phase_y, kappa_d0)
    bearing = np.arctan2(phase_y, phase_x)
    bearings = bearing_intersections(node_xy, bearing, layout.pairs, min_bearing_sin)
    reference = 0.5 * (usbl[..., layout.pairs[:, 0], :] + usbl[..., layout.pairs[:, 1], :])
    circles = circle_fixes(node_xy, ranges, layout.pairs, reference)
    triples = trilateration_fixes(node_xy, ranges, layout.triples)
    return np.concatenate([usbl, bearings, circles, triples], axis=-2)
