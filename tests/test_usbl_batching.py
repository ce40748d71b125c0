"""USBL epochs positioned in batches give what each epoch gives alone (KMCDF and the four baselines)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import replay.engine.usbl.positioning as up
from recorders.manifest import load_manifest
from recorders.record import record
from replay.engine.usbl.epochs import UsblEpoch
from replay.run.pipeline import replay_archive
from replay.stack.positioning.kmcdf import KmcdfFix, KmcdfParams, kmcdf_epoch, kmcdf_epochs
from replay.stack.positioning.kmcdf_montecarlo import delay_baseline

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
PARAMS = KmcdfParams(sound_speed_mps=1450.0)


def assert_same_fix(batched: KmcdfFix, alone: KmcdfFix) -> None:
    """Positions to 1e-9 m, every parameter state, cluster and preliminary fix the same."""
    np.testing.assert_allclose(batched.position_xy, alone.position_xy, rtol=0, atol=1e-9)
    np.testing.assert_allclose(batched.covariance, alone.covariance, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(batched.delay_normal, alone.delay_normal)
    np.testing.assert_array_equal(batched.phase_normal, alone.phase_normal)
    np.testing.assert_array_equal(batched.clusters, alone.clusters)
    assert (batched.rounds, batched.missing_fixes) == (alone.rounds, alone.missing_fixes)
    assert [f.kind for f in batched.fixes] == [f.kind for f in alone.fixes]
    np.testing.assert_allclose([f.xy for f in batched.fixes], [f.xy for f in alone.fixes], rtol=0, atol=1e-9)


def random_epochs(seed: int, trials: int, n: int) -> tuple[np.ndarray, ...]:
    """Buoys that move between epochs, a target, delays and phases with some wild values."""
    rng = np.random.default_rng(seed)
    nodes = rng.uniform(-800.0, 800.0, (trials, n, 2))
    target = rng.uniform(-500.0, 500.0, (trials, 2))
    d = target[:, None, :] - nodes
    r = np.hypot(d[..., 0], d[..., 1])
    delays = r / PARAMS.sound_speed_mps + rng.normal(0.0, PARAMS.sigma_delay_s, (trials, n))
    cos = d / r[..., None]
    px = PARAMS.kappa_d0 * cos[..., 0] + rng.normal(0.0, PARAMS.sigma_phase_rad, (trials, n))
    py = PARAMS.kappa_d0 * cos[..., 1] + rng.normal(0.0, PARAMS.sigma_phase_rad, (trials, n))
    wild = rng.random((trials, n)) < 0.2
    delays = np.where(wild, rng.uniform(0.0, 1.9, (trials, n)), delays)
    px = np.where(rng.random((trials, n)) < 0.1, rng.uniform(-np.pi, np.pi, (trials, n)), px)
    return nodes, delays, px, py


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 6), st.integers(3, 6))
def test_kmcdf_on_per_epoch_nodes_matches_each_epoch_alone(seed: int, trials: int, n: int) -> None:
    nodes, delays, px, py = random_epochs(seed, trials, n)
    batched = kmcdf_epochs(nodes, delays, px, py, PARAMS)
    assert len(batched) == trials
    for i in range(trials):
        assert_same_fix(batched[i], kmcdf_epoch(nodes[i], delays[i], px[i], py[i], PARAMS))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 6), st.integers(3, 6), st.sampled_from(up.BASELINES))
def test_baselines_on_per_epoch_nodes_match_each_epoch_alone(seed: int, trials: int, n: int, name: str) -> None:
    nodes, delays, _, _ = random_epochs(seed, trials, n)
    kw = dict(field_half_width_m=PARAMS.max_range_m, lhc_tolerance_m=0.01, lhc_max_iterations=100)
    batched = delay_baseline(name, nodes, delays, PARAMS, field_centre_xy=nodes.mean(axis=-2), **kw)
    for i in range(trials):
        centre = tuple(float(v) for v in nodes[i].mean(axis=0))
        alone = delay_baseline(name, nodes[i], delays[i][None, :], PARAMS, field_centre_xy=centre, **kw)
        np.testing.assert_allclose(batched.position[i], alone.position[0], rtol=0, atol=1e-9)
        np.testing.assert_array_equal(batched.normal[i], alone.normal[0])
        assert batched.resolved[i] == alone.resolved[0]


def test_baselines_on_shared_nodes_still_work() -> None:
    nodes, delays, _, _ = random_epochs(7, 5, 4)
    for name in up.BASELINES:
        shared = delay_baseline(name, nodes[0], delays, PARAMS, field_centre_xy=(0.0, 0.0))
        per_trial = delay_baseline(name, np.broadcast_to(nodes[0], nodes.shape).copy(), delays, PARAMS,
                                   field_centre_xy=np.zeros((5, 2)))
        np.testing.assert_allclose(per_trial.position, shared.position, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(per_trial.normal, shared.normal)


@pytest.fixture(scope="module")
def sample_epochs(tmp_path_factory) -> tuple[list[UsblEpoch], list[dict]]:
    """Every epoch of the sample trial as the engine positions it, with the positions it reported."""
    out = tmp_path_factory.mktemp("lake") / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), out)
    seen: list[UsblEpoch] = []
    reported: list[dict] = []
    batched = up.positions_for_epochs

    def spy(epochs: list[UsblEpoch]) -> list[dict]:
        seen.extend(epochs)
        reported.extend(batched(epochs))
        return reported[-len(epochs):]

    mp = pytest.MonkeyPatch()
    mp.setattr(up, "positions_for_epochs", spy)
    try:
        replay_archive(out, write_output=False)
    finally:
        mp.undo()
    return seen, reported


def test_sample_trial_epochs_batched_equal_one_at_a_time(sample_epochs) -> None:
    epochs, reported = sample_epochs
    assert len(epochs) == 340
    assert len({e.params for e in epochs}) >= 1
    for epoch, positions in zip(epochs, reported):
        assert_same_fix(epoch.fix, kmcdf_epoch(epoch.node_en, epoch.delays_s, epoch.phase_x, epoch.phase_y,
                                               epoch.params))
        alone = up.positions_for_epoch(epoch)
        assert list(positions) == list(alone) == ["kmcdf2", *up.BASELINES]
        for method, xy in alone.items():
            np.testing.assert_allclose(positions[method], xy, rtol=0, atol=1e-9)


def test_whole_sample_trial_in_one_batch_equals_one_at_a_time(sample_epochs) -> None:
    epochs, _ = sample_epochs
    together = up.positions_for_epochs(epochs)
    for epoch, positions in zip(epochs, together):
        assert positions == up.positions_for_epoch(epoch) or all(
            np.allclose(positions[m], v, rtol=0, atol=1e-9, equal_nan=True)
            for m, v in up.positions_for_epoch(epoch).items())
