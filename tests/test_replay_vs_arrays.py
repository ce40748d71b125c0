"""A replay through logs and the archive reproduces the stack run straight on the simulator's arrays.

The logs quantize what the arrays hold (DVL velocities to mm/s, headings and
positions to the vendor formats' digits, times to microseconds), so the two
paths agree closely rather than bit for bit: the labels exactly, confusion
counts within a few epochs, error percentiles within 5 %.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from recorders.manifest import load_manifest
from recorders.record import record
from replay.run.config import load_config
from replay.run.pipeline import replay_archive
from samples.scenario import Scenario
from samples.simulator import simulate_trial
from tests.sim_arrays import run_on_arrays

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
# |archive - arrays| allowed per confusion count; the compensating detector feeds its own
# predictions back into the ranges, so small input differences move more of its epochs
COUNT_TOLERANCE = {"chi_square": 3, "dual_threshold": 3, "anfis": 5, "anfis_aqpso": 5, "anfis_compensation": 12}


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    archive = tmp_path_factory.mktemp("arr") / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), archive)
    config = load_config()
    through_archive = replay_archive(archive, config, write_output=False).metrics
    results, on_arrays = run_on_arrays(simulate_trial(Scenario(), 0), config.stack)
    return through_archive, on_arrays, results


def test_labels_are_identical(both):
    through_archive, on_arrays, results = both
    after = results.epochs["time_s"] > results.training_end_s
    labelled = after & (results.epochs["label"] >= 0) & (results.epochs["method"] == "chi_square")
    assert through_archive["epochs"] == int(labelled.sum())
    assert through_archive["anomalous"] == int((results.epochs["label"][labelled] == 1).sum())
    row = on_arrays["chi_square"]
    assert row["tp"] + row["fn"] == through_archive["anomalous"]


@pytest.mark.parametrize("method", sorted(COUNT_TOLERANCE))
def test_detections_agree(both, method):
    through_archive, on_arrays, _ = both
    a, b = through_archive["methods"][method], on_arrays[method]
    for key in ("tp", "tn", "fp", "fn"):
        assert abs(a[key] - b[key]) <= COUNT_TOLERANCE[method], (method, key, a[key], b[key])


@pytest.mark.parametrize("method", ["dead_reckoning", "ckf", "ackf", "chi_square", "dual_threshold", "anfis"])
def test_errors_agree(both, method):
    through_archive, on_arrays, _ = both
    a, b = through_archive["methods"][method], on_arrays[method]
    for key in ("error_p50_m", "error_p90_m"):
        assert a[key] == pytest.approx(b[key], rel=0.05), (method, key)
