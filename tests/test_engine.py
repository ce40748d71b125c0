"""The replay engine on the sample trial, through the archive: metrics, determinism, compare, gaps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from replay.run.config import load_config
from replay.run.pipeline import replay_archive
from replay.stack.methods import detecting_names, runnable_names

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
FAST = ["methods=dead_reckoning,ckf,ackf,chi_square,anfis"]


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("lake") / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), out)
    return out


@pytest.fixture(scope="module")
def full_run(archive, tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "results.mcap"
    return replay_archive(archive, load_config(default_methods=runnable_names()), out, review=True)   # every method


def test_replay_scores_every_method_on_the_test_window(full_run):
    m = full_run.metrics
    assert m["window"] == [600.0, pytest.approx(1700.0, abs=1.0)]
    assert m["epochs"] == 454 and m["anomalous"] == 57   # the simulator's own count for seed 0
    for name in ("chi_square", "dual_threshold", "anfis", "anfis_aqpso", "anfis_compensation"):
        row = m["methods"][name]
        assert row["tp"] + row["tn"] + row["fp"] + row["fn"] == 454
        assert 0.5 < row["auc"] <= 1.0
    for name in ("dead_reckoning", "ckf", "ackf"):
        assert m["methods"][name]["tp"] is None and m["methods"][name]["error_p50_m"] > 0
    # cooperative ranging beats dead reckoning, KMCDF positions the follower to a few metres
    assert m["methods"]["ackf"]["error_p50_m"] < m["methods"]["dead_reckoning"]["error_p50_m"]
    assert m["methods"]["kmcdf2"]["error_p50_m"] < 5.0 and m["usbl_epochs"] > 300


def test_replay_matches_the_stack_on_the_simulator_arrays(full_run):
    """Labels through the archive equal the simulator's GPS-based labels, epoch for epoch."""
    sim = pd.read_csv(SAMPLE / "ranges.csv")
    sim = sim[sim["t_s"] > 600.0]
    assert int(sim["label"].sum()) == full_run.metrics["anomalous"]
    ranges = full_run.review.ranges
    ranges = ranges[ranges["t_s"] > 600.0]
    assert len(ranges) == len(sim)
    np.testing.assert_allclose(ranges["true_m"].to_numpy(), sim["z_gps_m"].to_numpy(), atol=0.05)
    np.testing.assert_allclose(ranges["measured_m"].to_numpy(), sim["z_m"].to_numpy(), atol=0.2)


def test_results_archive_holds_runs_channels_and_metadata(full_run):
    rid = full_run.run_id
    with ArchiveReader(full_run.output) as r:
        topics = r.summary().topics
        meta = r.metadata_json("run")
    assert topics[f"/replay/{rid}/follower/detections"]["count"] >= 5 * 690   # 5 detectors x ~700 epochs
    assert topics[f"/replay/{rid}/follower/anfis"]["schema"] == "foxglove.LocationFix"
    assert topics[f"/replay/{rid}/anfis/leader1"]["schema"] == "auvreplay.AnfisSnapshot"
    assert topics[f"/replay/{rid}/follower/kmcdf2"]["count"] > 300
    assert meta["run_id"] == rid and len(meta["input_sha256"]) == 64
    assert meta["configuration"]["stack"]["r_m"] == 3.0
    assert Path(str(full_run.output).replace(".mcap", ".metrics.csv")).exists()


def test_same_archive_and_configuration_give_identical_runs(archive, tmp_path):
    a = replay_archive(archive, load_config(None, FAST), tmp_path / "a.mcap")
    b = replay_archive(archive, load_config(None, FAST), tmp_path / "b.mcap")
    assert a.run_id == b.run_id
    strip = lambda m: {k: v for k, v in m.items() if k != "wall_s"}  # noqa: E731
    assert strip(a.metrics) == strip(b.metrics)
    with ArchiveReader(a.output) as ra, ArchiveReader(b.output) as rb:
        assert [(m.topic, m.log_time_ns, m.message.SerializeToString()) for m in ra.messages()] == \
               [(m.topic, m.log_time_ns, m.message.SerializeToString()) for m in rb.messages()]


def test_a_changed_parameter_changes_the_run_and_compare_shows_it(archive, tmp_path, capsys):
    a = replay_archive(archive, load_config(None, FAST), tmp_path / "a.mcap")
    b = replay_archive(archive, load_config(None, FAST + ["chi_square_alpha=0.2"]), tmp_path / "b.mcap")
    assert a.run_id != b.run_id
    assert main(["compare", str(a.output), str(b.output), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["parameters"] == {"stack.chi_square_alpha": [0.01, 0.2]}
    assert result["metrics"]["chi_square"]["fp"]["diff"] > 0
    assert len(result["differing_epochs"]["chi_square"]) > 0
    assert "anfis" not in result["differing_epochs"]


def test_usbl_fixes_update_the_follower_filters(archive, tmp_path):
    """engine.usbl_update=kmcdf2: every filter but dead reckoning takes the KMCDF fixes of the follower."""
    off = replay_archive(archive, load_config(None, FAST), write_output=False)
    on = replay_archive(archive, load_config(None, FAST + ["usbl_update=kmcdf2"]), tmp_path / "on.mcap")
    assert on.run_id != off.run_id
    fed = on.metrics["counts"]["usbl_fixes_to_filters"]
    assert fed > 300 and fed + on.metrics["counts"].get("usbl_fixes_undetermined", 0) == on.metrics["usbl_epochs"]
    assert on.results["follower"].position_fixes == fed
    m_on, m_off = on.metrics["methods"], off.metrics["methods"]
    for name in ("ckf", "ackf", "chi_square", "anfis"):
        # anchored every few seconds by ~2 m fixes, no longer by the ranges alone
        assert m_on[name]["error_p90_m"] < 5.0 < m_off[name]["error_p90_m"]
    assert m_on["dead_reckoning"]["error_p50_m"] == pytest.approx(m_off["dead_reckoning"]["error_p50_m"], rel=0.1)
    assert m_on["kmcdf2"] == m_off["kmcdf2"]          # positioning itself is unchanged


def test_replay_command_json(archive, tmp_path, capsys):
    out = tmp_path / "r.mcap"
    assert main(["replay", str(archive), "--set", FAST[0], "-o", str(out), "--json",
                 "--window", "0", "900"]) == 0
    m = json.loads(capsys.readouterr().out)
    assert set(m) >= {"run_id", "window", "epochs", "anomalous", "methods"}
    assert m["window"][1] <= 900.5 and 0 < m["epochs"] < 200
    assert set(m["methods"]["chi_square"]) >= {"tp", "tn", "fp", "fn", "accuracy", "precision", "recall", "fpr",
                                               "fnr", "auc", "recall_at_fpr_5", "error_p50_m", "error_p90_m",
                                               "error_rms_m"}


def copy_without(archive: Path, out: Path, drop: callable) -> Path:
    """A copy of an archive without the messages `drop(topic, t_s)` selects (metadata kept)."""
    with ArchiveReader(archive) as r, ArchiveWriter(out) as w:
        t0 = r.summary().start_ns
        for m in r.messages():
            if not drop(m.topic, (m.log_time_ns - t0) / 1e9):
                w.write(m.topic, m.message, m.log_time_ns, m.publish_time_ns)
        for name in ("trial", "recording"):
            w.add_metadata(name, r.metadata(name))
    return out


def test_missing_dvl_says_what_cannot_run(archive, tmp_path):
    path = copy_without(archive, tmp_path / "nodvl.mcap", lambda topic, t: topic == "/follower/dvl")
    out = replay_archive(path, load_config(None, FAST), write_output=False)
    assert any("no /follower/dvl" in n and "nothing can run" in n for n in out.notes)
    assert out.metrics["epochs"] == 0 and out.results == {}


def test_no_gps_after_the_window_means_no_labels_but_detectors_run(archive, tmp_path):
    path = copy_without(archive, tmp_path / "nogps.mcap",
                        lambda topic, t: topic.endswith("/gps") and t > 700.0)
    out = replay_archive(path, load_config(None, FAST), write_output=False, review=True)
    assert out.metrics["methods"]["anfis"]["tp"] is not None
    assert 0 < out.metrics["epochs"] < 60     # only 600-700 s have labels
    det = out.review.detections
    late = det[(det["t_s"] > 800) & (det["method"] == "chi_square")]
    assert len(late) > 100 and (late["label"] == -1).all()


def test_gaps_duplicates_and_out_of_order_are_handled(archive, tmp_path):
    """A DVL outage, duplicated ranges and a range out of order: counted, the run goes on."""
    path = tmp_path / "messy.mcap"
    with ArchiveReader(archive) as r, ArchiveWriter(path) as w:
        t0 = r.summary().start_ns
        for m in r.messages():
            t = (m.log_time_ns - t0) / 1e9
            if m.topic == "/follower/dvl" and 1000 < t < 1060:
                continue
            w.write(m.topic, m.message, m.log_time_ns)
            if m.topic == "/follower/modem/range" and 1200 < t < 1230:
                w.write(m.topic, m.message, m.log_time_ns)                 # duplicate
        w.add_metadata("trial", r.metadata("trial"))
    out = replay_archive(path, load_config(None, FAST), write_output=False)
    assert out.metrics["epochs"] > 400
    rejected = out.metrics["rejected"]["follower"]
    assert sum(rejected.values()) >= 1
    assert out.metrics["methods"]["ackf"]["error_p50_m"] < 20


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_export_any_topic(full_run, tmp_path, capsys, fmt):
    topic = f"/replay/{full_run.run_id}/follower/detections"
    out = tmp_path / f"det.{fmt}"
    assert main(["export", str(full_run.output), "--topic", topic, "--format", fmt, "-o", str(out)]) == 0
    df = pd.read_csv(out, index_col=0) if fmt == "csv" else pd.read_parquet(out)
    with ArchiveReader(full_run.output) as r:
        assert len(df) == r.summary().topics[topic]["count"]
    assert {"method", "flagged", "score", "feature_mahalanobis2", "label"} <= set(df.columns)
    assert set(df["method"]) == set(detecting_names())
    assert main(["export", str(full_run.output), "--topic", "/nope", "-o", str(out)]) == 1
    assert "no topic /nope" in capsys.readouterr().err


def test_notebook_api(archive):
    from replay import api

    with api.open_archive(archive) as a:
        assert len(a.to_dataframe("/follower/dvl")) == 1701
    out = api.run(archive, {"methods": "dead_reckoning,ckf,ackf,chi_square", "chi_square_alpha": 0.05})
    frame = api.metrics_frame(out)
    assert list(frame.index) == ["dead_reckoning", "ckf", "ackf", "chi_square", "kmcdf2", "gar", "ear", "lms",
                                 "lhc"]
    assert frame.loc["chi_square", "tp"] + frame.loc["chi_square", "fn"] == 57
    assert set(out.review.detections["method"]) == {"chi_square"}
    assert out.output is None


def test_two_followers_are_each_run_and_pooled(tmp_path):
    """A simulated trial with two followers: both run every method; the metrics pool their epochs."""
    trial = tmp_path / "trial"
    assert main(["simulate", "-o", str(trial), "--duration", "420", "--followers", "2", "--seed", "3"]) == 0
    archive = tmp_path / "two.mcap"
    record(load_manifest(trial / "trial.toml"), archive)
    run = replay_archive(archive, load_config(None, FAST + ["training_window_s=200"]), write_output=False,
                         review=True)
    assert run.metrics["followers"] == ["follower", "follower2"] and set(run.results) == {"follower", "follower2"}
    det = run.review.detections
    scored = det[(det["method"] == "chi_square") & (det["t_s"] > 200.0) & (det["label"] >= 0)]
    counts = scored.groupby("follower").size().to_dict()
    assert set(counts) == {"follower", "follower2"} and min(counts.values()) > 20
    assert sum(counts.values()) == run.metrics["epochs"]
    for name, res in run.results.items():
        assert res.trained and not res.training_errors, name
    m = run.metrics["methods"]
    assert m["ackf"]["error_p50_m"] < m["dead_reckoning"]["error_p50_m"]
    assert run.metrics["epochs"] > 0 and m["chi_square"]["tp"] + m["chi_square"]["tn"] + m["chi_square"]["fp"] + \
        m["chi_square"]["fn"] == run.metrics["epochs"]


def test_rate_paces_the_replay_against_wall_time(archive):
    """--rate 100 over a 40 s window takes at least 0.4 s of wall time (as fast as possible it takes less)."""
    import time

    t = time.monotonic()
    run = replay_archive(archive, load_config(None, ["methods=ckf"], window=(0.0, 40.0), rate=100.0),
                         write_output=False)
    assert time.monotonic() - t >= 0.4 and run.messages > 0


def test_an_archive_cut_off_mid_write_still_knows_its_vehicles(archive, tmp_path):
    """The trial record comes first: a cut-off archive replays with its roles, not a guess."""
    data = archive.read_bytes()
    cut = tmp_path / "cut.mcap"
    # the summary and part of the last chunk cut (the follower's ranges sit in the last chunks, and with the modem
    # logs' events those now begin after 95 % of the file)
    cut.write_bytes(data[: int(len(data) * 0.98)])
    run = replay_archive(cut, load_config(None, FAST), write_output=False)
    assert not any("roles guessed" in n for n in run.notes)
    assert any("truncated or damaged" in n for n in run.notes)
    assert run.metrics["followers"] == ["follower"] and run.metrics["epochs"] > 300


def test_roles_guessed_from_topics_without_trial_metadata():
    from replay.engine.layout import plan_trial

    topics = {"/leader1/ins": 5, "/leader1/modem/range": 3, "/leader2/gps": 5, "/follower/dvl": 9,
              "/follower/modem/range": 7, "/buoy1/usbl": 4, "/buoy1/gps": 2, "/diagnostics": 1}
    layout = plan_trial(None, topics)
    assert layout.roles == {"leader1": "leader", "leader2": "leader", "follower": "follower", "buoy1": "buoy"}
    assert any("roles guessed" in n for n in layout.notes)
    no_dvl = plan_trial(None, {"/a/modem/range": 3, "/b/gps": 4})
    assert no_dvl.roles == {"a": "follower", "b": "leader"}


def test_detections_carry_the_filter_independent_features(full_run, tmp_path):
    """Every Detection holds replay.stack.features' EXTRA_FEATURES, the same for every method of an epoch."""
    from replay.stack.features import EXTRA_FEATURES

    out = tmp_path / "det.csv"
    assert main(["export", str(full_run.output), "--topic", f"/replay/{full_run.run_id}/follower/detections",
                 "-o", str(out)]) == 0
    df = pd.read_csv(out, index_col=0)
    assert set(EXTRA_FEATURES) <= set(df.columns)
    per_epoch = df.groupby(["timestamp", "leader"])[list(EXTRA_FEATURES)].nunique(dropna=False)
    assert (per_epoch <= 1).all().all()
    # the DR error model's residual (lag_residual_m is NaN unless drift_source is "lag" or anfis_hybrid takes it)
    assert np.isfinite(df["drift_residual_m"]).mean() > 0.8 and (df["repeat_count"] >= 0).all()
    assert np.isfinite(df["drift_z"]).mean() > 0.5


@pytest.mark.parametrize("setting, words", [
    ("training_source=x", "unknown training_source 'x'"),
    ("anfis.threshold_rule=x", "unknown ANFIS threshold rule 'x'"),
    ("drift_reference_z=-1", "drift_reference_z must be positive"),
    ("hybrid_inputs=f2,nope", "unknown hybrid input 'nope'"),
])
def test_a_configuration_the_stack_cannot_run_is_a_one_line_error(archive, tmp_path, capsys, setting, words):
    """Refused where the stack checks it (ConfigError), printed as one line, no traceback and no results."""
    out = tmp_path / "r.mcap"
    code = main(["replay", str(archive), "--set", "methods=ackf,anfis,anfis_hybrid,drift_reference",
                 "--set", setting, "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and not out.exists()
    assert err[0].startswith("auvreplay replay: error: configuration: ") and words in err[0]
