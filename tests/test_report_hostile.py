"""`report` of a results archive crafted by someone else: every variant gives one line or a report, never a traceback,
and no markup of the archive reaches the HTML unescaped."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from replay.cli import main
from replay.errors import UserError
from replay.run.rebuild import checked_run_metadata
from tests.test_record import GPS_CSV, MANIFEST, RANGE_CSV

MARK = '<script>alert("x")</script><img src=x onerror=alert(1)>'
RAW_MARKUP = ("<script", "<img src=x")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    """A real trial archive and its replay's raw `run` record (strings, as stored)."""
    tmp = tmp_path_factory.mktemp("run")
    (tmp / "logs").mkdir()
    (tmp / "logs/gps.csv").write_bytes(GPS_CSV)
    (tmp / "logs/range.csv").write_bytes(RANGE_CSV)
    (tmp / "trial.toml").write_text(MANIFEST)
    assert main(["record", str(tmp / "trial.toml"), "-o", str(tmp / "t.mcap"), "--quiet"]) == 0
    assert main(["replay", str(tmp / "t.mcap"), "-o", str(tmp / "r.mcap"), "--json"]) == 0
    with ArchiveReader(tmp / "r.mcap") as reader:
        raw = reader.metadata("run")
    assert raw is not None
    return tmp, raw


def _metrics(raw: dict[str, str], **changes: Any) -> dict[str, str]:
    m = json.loads(raw["metrics"])
    m.update(changes)
    return {**raw, "metrics": json.dumps(m)}


def _without(raw: dict[str, str], key: str) -> dict[str, str]:
    return {k: v for k, v in raw.items() if k != key}


VARIANTS: dict[str, Any] = {
    # markup in every string and number field of the metrics
    "epochs markup": lambda r: _metrics(r, epochs=MARK),
    "anomalous markup": lambda r: _metrics(r, anomalous=MARK),
    "usbl_epochs markup": lambda r: _metrics(r, usbl_epochs=MARK),
    "followers markup": lambda r: _metrics(r, followers=[MARK, 3, None]),
    "method name and figures markup": lambda r: _metrics(r, methods={MARK: {"error_p50_m": MARK, "tp": 3},
                                                                     "ckf": {"error_p50_m": 1.5, "auc": MARK}}),
    "notes markup": lambda r: _metrics(r, notes=[MARK, 5, {"a": MARK}]),
    "skipped markup": lambda r: _metrics(r, skipped={MARK: MARK, "ckf": 7}),
    "rejected markup": lambda r: _metrics(r, rejected={MARK: {MARK: 4, "gate": MARK}, "f": "x"}),
    "navigation markup": lambda r: _metrics(r, navigation={MARK: {"methods": {MARK: {"scored_at": MARK,
                                                                                     "fixes": [1]}}}}),
    "window markup": lambda r: _metrics(r, window=[MARK, 5]),
    # wrong types
    "metrics a list": lambda r: {**r, "metrics": "[1, 2]"},
    "metrics not JSON": lambda r: {**r, "metrics": "{" + MARK},
    "window a string": lambda r: _metrics(r, window="soon"),
    "methods a list": lambda r: _metrics(r, methods=[MARK]),
    "navigation a string": lambda r: _metrics(r, navigation=MARK, rejected=[MARK], skipped=3),
    "parameters a list": lambda r: {**r, "parameters": "[]"},
    "parameter markup": lambda r: {**r, "parameters": json.dumps({"stack": {"r_m": MARK}})},
    "wall time markup": lambda r: {**r, "wall_time_s": MARK, "trial_start_ns": MARK},
    # missing keys
    "no run_id": lambda r: _without(r, "run_id"),
    "no input_sha256": lambda r: _without(r, "input_sha256"),
    "no metrics": lambda r: _without(r, "metrics"),
    "no parameters": lambda r: _without(r, "parameters"),
    "no input_file": lambda r: _without(r, "input_file"),
    # markup in the run's own strings
    "run_id markup": lambda r: {**r, "run_id": MARK},
    "sha markup": lambda r: {**r, "input_sha256": MARK},
    "input_file markup": lambda r: {**r, "input_file": MARK},
    "package_version markup": lambda r: {**r, "package_version": MARK},
    "input_path NUL": lambda r: {**r, "input_path": "/tmp/a\x00b"},
    # huge numbers and NaN
    "huge counts": lambda r: _metrics(r, epochs=10**30, anomalous=-1, usbl_epochs=1e308,
                                      window=[0, 1e308], methods={"ckf": {"error_p50_m": 10**40, "tp": 1e308}}),
    "huge integer text": lambda r: {**r, "metrics": '{"epochs": ' + "9" * 5000 + "}"},
    "huge start": lambda r: {**r, "trial_start_ns": "9" * 30},
    "NaN everywhere": lambda r: _metrics(r, epochs=math.nan, window=[math.nan, math.nan],
                                         methods={"ckf": {"error_p50_m": math.nan, "error_p90_m": math.inf}}),
    "deep nesting": lambda r: {**r, "metrics": "[" * 100_000 + "]" * 100_000},
}


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_a_crafted_results_archive_never_tracebacks_or_injects(run, tmp_path, capsys, name):
    tmp, raw = run
    crafted = tmp_path / "crafted.mcap"
    with ArchiveWriter(crafted) as w:
        w.add_metadata("run", VARIANTS[name](raw))
    out = tmp_path / "report.html"
    code = main(["report", str(crafted), "--archive", str(tmp / "t.mcap"), "-o", str(out)])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    if code == 1:
        assert len(lines) == 1 and lines[0].startswith("auvreplay report: error: "), err
        assert not out.exists()
        return
    assert code == 0, err
    page = out.read_text()
    for bad in RAW_MARKUP:
        assert bad not in page, (name, page[page.index(bad) - 200:page.index(bad) + 100])
    if MARK in json.dumps(VARIANTS[name](raw)):
        # where a crafted string shows, it shows escaped
        assert "&lt;script&gt;" in page or "left out" in err, name


def test_the_variants_cover_refusals_and_reports(run, tmp_path):
    _, raw = run
    refused, kept = [], []
    for name, craft in VARIANTS.items():
        try:
            meta = checked_run_metadata(craft(raw), "x.mcap")
        except UserError as exc:
            assert "\n" not in str(exc)
            refused.append(name)
            continue
        kept.append(name)
        m = meta["metrics"]
        for key in ("epochs", "anomalous", "usbl_epochs"):
            assert m.get(key) is None or (type(m[key]) is int and 0 <= m[key] < 2**63)
        assert all(isinstance(f, str) for f in m["followers"])
        for row in m["methods"].values():
            assert all(v is None or isinstance(v, (int, float)) for v in row.values())
    assert len(VARIANTS) >= 14 and len(refused) >= 8 and len(kept) >= 14
    assert {"epochs markup", "anomalous markup", "usbl_epochs markup"} <= set(kept)


def test_values_left_out_are_counted(run):
    _, raw = run
    meta = checked_run_metadata(_metrics(raw, epochs=MARK, followers=["a", 3], notes=[None]), "x")
    assert meta["skipped_values"] == 3
    assert meta["metrics"]["epochs"] is None and meta["metrics"]["followers"] == ["a"]
    clean = checked_run_metadata(raw, "x")
    assert clean["skipped_values"] == 0
    assert clean["metrics"]["window"] == json.loads(raw["metrics"])["window"]
    assert clean["run_id"] == raw["run_id"] and isinstance(clean["trial_start_ns"], int)


def test_a_report_says_what_it_left_out(run, tmp_path, capsys):
    tmp, raw = run
    crafted = tmp_path / "crafted.mcap"
    with ArchiveWriter(crafted) as w:
        w.add_metadata("run", _metrics(raw, epochs=MARK))
    assert main(["report", str(crafted), "--archive", str(tmp / "t.mcap"), "-o", str(tmp_path / "r.html")]) == 0
    err = capsys.readouterr().err
    assert "1 values of the run metadata were not of their kind: left out of the report" in err
