"""Issue 14: `view` and `compare` end with the one damage warning line that info, replay, export and unpack print
(`replay.errors.warn_damage`), for archives damaged here; an undamaged archive gives no warning."""

from __future__ import annotations

from pathlib import Path

import pytest

from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from replay.run.batch import replay_task
from tests.hostile import rewrite
from tests.test_hostile_archives import _garbage, one_line

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"


@pytest.fixture(scope="module")
def archives(tmp_path_factory) -> dict[str, Path]:
    """The sample trial, a copy with 1 in 97 messages garbage, and a results archive of it."""
    d = tmp_path_factory.mktemp("warnings")
    trial = d / "trial.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), trial)
    garbage = rewrite(trial, d / "garbage.mcap", message=_garbage(1 / 97), seed=5)
    # a method that detects: compare reads the detections
    assert main(["replay", str(trial), "--set", "methods=chi_square", "--window", "0", "700",
                 "-o", str(d / "results.mcap")]) == 0
    return {"trial": trial, "garbage": garbage, "results": d / "results.mcap"}


def _garbage_detections(t: str, data: bytes, rng) -> bytes:
    return rng.randbytes(len(data) + 3) if t.endswith("/detections") and rng.random() < 0.2 else data


def test_view_warns_of_skipped_messages_before_the_viewer(archives, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(archives["garbage"])]) == 0
    out, err = capsys.readouterr()
    line = one_line(err, "warning")
    assert line.startswith("auvreplay view: warning: ") and str(archives["garbage"]) in line
    assert "do not decode" in line and "no display" in out
    assert main(["view", str(archives["trial"])]) == 0
    assert "warning" not in capsys.readouterr().err


def test_compare_warns_of_a_damaged_results_archive(archives, tmp_path, capsys):
    damaged = rewrite(archives["results"], tmp_path / "damaged.mcap", message=_garbage_detections)
    assert main(["compare", str(archives["results"]), str(damaged)]) == 0
    line = one_line(capsys.readouterr().err, "warning")
    assert line.startswith("auvreplay compare: warning: ") and str(damaged) in line and "do not decode" in line
    assert str(archives["results"]) + ":" not in line  # the whole one is not named
    assert main(["compare", str(archives["results"]), str(archives["results"])]) == 0
    assert "warning" not in capsys.readouterr().err


def test_a_batch_run_keeps_the_archives_warning(archives, tmp_path):
    # the worker's record carries the line; `batch` prints it once per archive (tests/test_batch.py, on Dask)
    damaged = replay_task(str(archives["garbage"]), REPLAY_OVERRIDES, str(tmp_path), "garbage")
    whole = replay_task(str(archives["trial"]), REPLAY_OVERRIDES, str(tmp_path), "trial")
    assert damaged["error"] is None and "do not decode" in damaged["warning"]
    assert whole["error"] is None and whole["warning"] is None


REPLAY_OVERRIDES = ["methods=dead_reckoning", "window_s=[0,700]"]


def test_view_and_report_warn_of_the_damaged_input_archive_they_re_run(archives, tmp_path, capsys, monkeypatch):
    """A results archive's view and report re-run its input: that input's damage is named too, once."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    results = tmp_path / "of-garbage.mcap"
    assert main(["replay", str(archives["garbage"]), "--set", "methods=chi_square", "--window", "0", "700",
                 "-o", str(results)]) == 0
    capsys.readouterr()
    for command in (["view", str(results), "--save", str(tmp_path / "v.rrd")],
                    ["report", str(results), "-o", str(tmp_path / "r.html")]):
        assert main(command) == 0
        line = one_line(capsys.readouterr().err, "warning")
        assert line.startswith(f"auvreplay {command[0]}: warning: {archives['garbage']}: ")
        assert "do not decode" in line and str(results) + ":" not in line
    assert main(["view", str(archives["results"]), "--save", str(tmp_path / "w.rrd")]) == 0
    assert "warning" not in capsys.readouterr().err
