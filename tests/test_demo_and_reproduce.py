"""The whole job as a user runs it: demo, reproduce anfis, view on results archives."""

from __future__ import annotations

import json
from collections import Counter

import pytest
from rerun.chunk import RrdReader

from replay.cli import main

FAST = "methods=dead_reckoning,ckf,ackf,chi_square,anfis"


def entity_rows(rrd) -> Counter:
    """Rows per entity path in a saved recording."""
    rows: Counter = Counter()
    for chunk in RrdReader(rrd).stream().to_chunks():
        rows[chunk.entity_path] += chunk.num_rows
    return rows


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    assert main(["demo", "--out", str(out), "--no-viewer"]) == 0
    return out


def test_demo_writes_archive_results_metrics_and_recording(demo_dir, capsys):
    for name in ("lake-trial.mcap", "lake-trial-results.mcap", "lake-trial-results.metrics.csv",
                 "lake-trial-results.metrics.json", "lake-trial.rrd"):
        assert (demo_dir / name).stat().st_size > 0, name
    metrics = json.loads((demo_dir / "lake-trial-results.metrics.json").read_text())
    assert metrics["epochs"] == 454 and set(metrics["methods"]) >= {"anfis", "kmcdf2", "dead_reckoning"}
    rows = entity_rows(demo_dir / "lake-trial.rrd")
    rid = metrics["run_id"]
    at = lambda path: rows[f"/{rid}/{path}"]  # noqa: E731
    # every view holds the real run: tracks, ranges, features, lanes, CDFs, ANFIS, KMCDF, events
    # positions: one row per GPS fix and one static styling row (colour, size, name)
    assert at("map/follower/gps/position") == 1701 + 1 and at("local/follower/anfis/position") > 1000
    ranges = at("series/range/follower/leader1/measured") + at("series/range/follower/leader2/measured")
    assert 701 <= ranges <= 701 + 2          # the views add one styling row per series
    assert at("series/f1_innovation_m/follower/leader1") + at("series/f1_innovation_m/follower/leader2") == ranges
    # state-timeline lanes named by leader and method (/lanes/...); each has one static StateConfiguration row
    assert rows["/lanes/leader1/0_truth"] + rows["/lanes/leader2/0_truth"] == 701 + 2
    # the demo runs the new detectors, so the new features are drawn, and every scored epoch is explained
    assert at("features/follower/leader1/z/drift_z") > 100 and at("scores/cusum_drift/follower/leader1/score") > 100
    assert at("why/follower/leader1") + at("why/follower/leader2") == metrics["epochs"] + 2   # + "before t_a"
    assert at("cdf/follower/anfis/curve") > 10
    # one view per ANFIS model (method, leader): the MFs at 11 of the 100 epochs (the kept one among them), and the
    # kept model on `time`; every scored epoch after t_a is explained by each model
    for method in ("anfis", "anfis_aqpso", "anfis_compensation", "anfis_hybrid"):
        assert at(f"anfis/{method}/leader1/training/mf/in1") in (12, 13)
        explained = at(f"anfis/{method}/leader1/explain/firing") + at(f"anfis/{method}/leader2/explain/firing")
        assert explained == metrics["epochs"]
    assert at("kmcdf/follower/kmcdf2/fixes") == metrics["usbl_epochs"]
    assert at("events") > 0


def test_reproduce_anfis_json_has_both_modes_and_the_paper(capsys):
    assert main(["reproduce", "anfis", "--json", "--set", FAST]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["epochs"] == 454 and out["anomalous"] == 57
    assert set(out["modes"]) == {"per_leader", "shared"}
    assert out["paper"]["methods"]["anfis"] == {"tp": 47, "tn": 401, "fp": 4, "fn": 10}
    chi = out["methods"]["chi_square"]
    assert chi["tp"] + chi["fn"] == 57 and chi["fp"] + chi["tn"] == 454 - 57


def test_view_on_two_results_archives_builds_one_comparison(demo_dir, tmp_path, capsys):
    archive = demo_dir / "lake-trial.mcap"
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    assert main(["replay", str(archive), "--set", FAST, "-o", str(a)]) == 0
    assert main(["replay", str(archive), "--set", FAST, "--set", "r_m=5", "-o", str(b)]) == 0
    rrd = tmp_path / "ab.rrd"
    assert main(["view", str(a), str(b), "--save", str(rrd)]) == 0
    captured = capsys.readouterr().out
    assert "saved" in captured
    runs = {p.split("/")[1] for p in entity_rows(rrd) if p.count("/") > 1}
    assert len(runs & {json.loads(p.with_suffix(".metrics.json").read_text())["run_id"] for p in (a, b)}) == 2


def test_view_refuses_a_results_archive_without_its_input(tmp_path, demo_dir, capsys):
    results = tmp_path / "r.mcap"
    (tmp_path / "copy.mcap").write_bytes((demo_dir / "lake-trial.mcap").read_bytes())
    assert main(["replay", str(tmp_path / "copy.mcap"), "--set", FAST, "-o", str(results)]) == 0
    (tmp_path / "copy.mcap").unlink()
    capsys.readouterr()
    assert main(["view", str(results)]) == 1
    assert "cannot find the input archive" in capsys.readouterr().err
