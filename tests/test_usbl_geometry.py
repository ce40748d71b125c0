"""Preliminary LBL/USBL fixes: exact on noise-free data, degenerate geometry gives NaN, never raises."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.stack.positioning import usbl_geometry as ug

KD0 = 2 * math.pi * 75e3 * 0.18 / 1500.0
NODES6 = 800.0 * np.stack([np.cos(2 * np.pi * np.arange(6) / 6), np.sin(2 * np.pi * np.arange(6) / 6)], -1)
coord = st.floats(-1500.0, 1500.0, allow_nan=False)


def observe(node_xy: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise-free ranges and phase differences (T, N) for targets (T, 2); seed 003 eq. (1)-(3)."""
    d = target[:, None, :] - node_xy
    r = np.hypot(d[..., 0], d[..., 1])
    return r, KD0 * d[..., 0] / r, KD0 * d[..., 1] / r


def far_from_nodes(target: np.ndarray, node_xy: np.ndarray, margin: float = 5.0) -> bool:
    """Whether a target is clear of every node (bearings are undefined at a node)."""
    return bool(np.min(np.hypot(*(node_xy - target).T)) > margin)


@settings(max_examples=60, deadline=None)
@given(coord, coord)
def test_usbl_fix_is_exact_without_noise(x: float, y: float) -> None:
    target = np.array([[x, y]])
    if not far_from_nodes(target[0], NODES6):
        return
    r, px, py = observe(NODES6, target)
    fixes = ug.usbl_fixes(NODES6, r, px, py, KD0)
    np.testing.assert_allclose(fixes[0], np.repeat(target, 6, 0), atol=1e-8)


def test_abnormal_phase_lands_near_its_own_node() -> None:
    fixes = ug.usbl_fixes(NODES6, np.full((1, 6), 1000.0), np.full((1, 6), math.pi),
                          np.full((1, 6), -math.pi), KD0)
    offsets = np.hypot(*(fixes[0] - NODES6).T)
    np.testing.assert_allclose(offsets, 1000.0 * math.sqrt(2) * math.pi / KD0)
    assert np.all(offsets < 80.0)


@settings(max_examples=60, deadline=None)
@given(coord, coord)
def test_bearing_and_circle_pairs_are_exact(x: float, y: float) -> None:
    target = np.array([[x, y]])
    if not far_from_nodes(target[0], NODES6):
        return
    layout = ug.fix_layout(6)
    r, px, py = observe(NODES6, target)
    bearings = ug.bearing_intersections(NODES6, np.arctan2(py, px), layout.pairs, 0.05)
    ok = np.isfinite(bearings[0, :, 0])
    np.testing.assert_allclose(bearings[0, ok], np.repeat(target, ok.sum(), 0), atol=1e-6)
    first, second, meet = ug.circle_intersections(NODES6, r, layout.pairs)
    hit = np.minimum(np.hypot(*(first[0] - target).T), np.hypot(*(second[0] - target).T))
    assert np.all(hit[meet[0]] < 1e-4 * (1 + np.max(r)))
    chosen = ug.circle_fixes(NODES6, r, layout.pairs, np.repeat(target[:, None], 15, 1))
    np.testing.assert_allclose(chosen[0, meet[0]], np.repeat(target, meet.sum(), 0), atol=1e-3)


@settings(max_examples=60, deadline=None)
@given(coord, coord)
def test_every_preliminary_fix_is_the_target_without_noise(x: float, y: float) -> None:
    target = np.array([[x, y]])
    if not far_from_nodes(target[0], NODES6):
        return
    layout = ug.fix_layout(6)
    r, px, py = observe(NODES6, target)
    fixes = ug.preliminary_fixes(NODES6, r / 1500.0, px, py, sound_speed=1500.0, kappa_d0=KD0,
                                 min_bearing_sin=0.05, layout=layout)
    assert fixes.shape == (1, 56, 2)
    ok = np.all(np.isfinite(fixes[0]), -1)
    assert ok[:6].all() and ok[41:].all()     # USBL and triples always exist here
    np.testing.assert_allclose(fixes[0, ok], np.repeat(target, ok.sum(), 0), atol=2e-3)


def test_fix_layout_counts_and_subsets() -> None:
    for n in (3, 4, 6):
        layout = ug.fix_layout(n)
        m = n + 2 * math.comb(n, 2) + math.comb(n, 3)
        assert layout.incidence.shape == (m, 3 * n)
        assert np.bincount(layout.kinds).tolist() == [n, math.comb(n, 2), math.comb(n, 2), math.comb(n, 3)]
    layout = ug.fix_layout(4)
    assert np.nonzero(layout.incidence[1])[0].tolist() == [1, 5, 9]        # USBL node 1
    assert np.nonzero(layout.incidence[4])[0].tolist() == [4, 5, 8, 9]     # bearings 0-1
    assert np.nonzero(layout.incidence[10])[0].tolist() == [0, 1]          # circles 0-1
    assert np.nonzero(layout.incidence[16])[0].tolist() == [0, 1, 2]       # triple 0-1-2


def test_parallel_and_antiparallel_bearings_give_no_fix() -> None:
    nodes = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 50.0]])
    pairs = np.array([[0, 1], [0, 2], [1, 2]])
    # 0 and 2 both look along +x (parallel); 0 and 1 look at each other (antiparallel, collinear)
    bearing = np.array([[0.0, math.pi, 0.0]])
    out = ug.bearing_intersections(nodes, bearing, pairs, 0.05)
    assert np.isnan(out[0, 0]).all() and np.isnan(out[0, 1]).all()
    # 1 looks back along -x, 2 along +x: still parallel lines
    assert np.isnan(out[0, 2]).all()


def test_tangent_circles_meet_once_and_disjoint_do_not() -> None:
    nodes = np.array([[0.0, 0.0], [10.0, 0.0]])
    pairs = np.array([[0, 1]])
    first, second, meet = ug.circle_intersections(nodes, np.array([[4.0, 6.0], [3.0, 3.0], [20.0, 5.0]]), pairs)
    assert meet[:, 0].tolist() == [True, False, False]
    np.testing.assert_allclose(first[0, 0], [4.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(second[0, 0], [4.0, 0.0], atol=1e-9)
    assert np.isnan(first[1:]).all() and np.isnan(second[1:]).all()
    # externally tangent with rounding noise in the radii is still tangent
    nodes2 = np.array([[0.1, 0.2], [0.4, 0.9]])
    dist = math.hypot(0.3, 0.7)
    _, _, meet2 = ug.circle_intersections(nodes2, np.array([[dist / 3, 2 * dist / 3]]), pairs)
    assert meet2[0, 0]


def test_coincident_nodes_and_nan_ranges_do_not_raise() -> None:
    nodes = np.array([[5.0, 5.0], [5.0, 5.0], [9.0, 1.0]])
    pairs = np.array([[0, 1], [0, 2]])
    with np.errstate(all="raise"):
        first, _, meet = ug.circle_intersections(nodes, np.array([[3.0, np.nan, 1.0]]), pairs)
    assert not meet.any() and np.isnan(first).all()


def test_collinear_triples_give_no_fix() -> None:
    nodes = np.array([[0.0, 0.0], [100.0, 0.0], [250.0, 0.0], [0.0, 300.0]])
    triples = np.array([[0, 1, 2], [0, 1, 3]])
    target = np.array([[40.0, 70.0]])
    r = np.hypot(*(target[:, None, :] - nodes).transpose(2, 0, 1))
    with np.errstate(all="raise"):
        out = ug.trilateration_fixes(nodes, r, triples)
    assert np.isnan(out[0, 0]).all()
    np.testing.assert_allclose(out[0, 1], target[0], atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(coord, coord), min_size=3, max_size=3, unique=True), coord, coord)
def test_trilateration_exact_for_any_non_collinear_nodes(pts: list[tuple[float, float]], x: float,
                                                        y: float) -> None:
    nodes = np.array(pts)
    (ax, ay), (bx, by) = nodes[1] - nodes[0], nodes[2] - nodes[0]
    area = abs(ax * by - ay * bx)
    if area < 1e3:
        return
    target = np.array([[x, y]])
    r = np.hypot(*(target[:, None, :] - nodes).transpose(2, 0, 1))
    out = ug.trilateration_fixes(nodes, r, np.array([[0, 1, 2]]))
    np.testing.assert_allclose(out[0, 0], target[0], atol=1e-6 * (1 + np.max(np.abs(nodes))) ** 2 / np.sqrt(area))
