"""The shareable report, track export (GeoJSON, KML), mission seconds in exports and compare, and the rule that no
command overwrites a file it did not create."""

from __future__ import annotations

import base64
import json
import re
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.geojson import feature_collection
from formats.kml import kml_document
from formats.mcap_reader import ArchiveReader
from formats.tracks import Track
from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from replay.review.anomaly_kinds import load_intervals
from replay.review.report import build_report, detection_tallies
from replay.review.scoreboard import format_value
from replay.run.config import load_config
from replay.run.pipeline import replay_archive
from replay.run.rebuild import run_metadata

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
FAST = ["methods=dead_reckoning,ckf,ackf,chi_square,anfis"]
KML = "{http://www.opengis.net/kml/2.2}"
GX = "{http://www.google.com/kml/ext/2.2}"


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("lake") / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), out)
    return out


@pytest.fixture(scope="module")
def runs(archive, tmp_path_factory):
    """Two FAST runs of the sample trial that differ in the chi-square alpha (A with its review data)."""
    d = tmp_path_factory.mktemp("runs")
    a = replay_archive(archive, load_config(None, FAST), d / "a.mcap", review=True)
    b = replay_archive(archive, load_config(None, FAST + ["chi_square_alpha=0.2"]), d / "b.mcap")
    return a, b


@pytest.fixture(scope="module")
def report(runs, tmp_path_factory):
    """The report of run A with the simulator's kinds, written over someone else's file with --force."""
    out = tmp_path_factory.mktemp("report") / "report.html"
    out.write_text("someone else's file")
    argv = ["report", str(runs[0].output), "-o", str(out), "--anomalies", str(SAMPLE / "anomalies.csv")]
    assert main(argv) == 1 and out.read_text() == "someone else's file"
    assert main(argv + ["--force"]) == 0
    return out.read_text(), run_metadata(runs[0].output), runs[0].review


class _Cells(HTMLParser):
    """Every scoreboard cell (method, key, data-value, text), every src/href, every table cell's text."""

    def __init__(self) -> None:
        super().__init__()
        self.cells: list[tuple[str, str, str, str]] = []
        self.links: list[str] = []
        self.kind_cells: list[tuple[str, str, str]] = []
        self._method = ""
        self._open: dict[str, str] | None = None
        self._text = ""

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        self.links += [a[k] for k in ("src", "href") if k in a]
        if tag == "tr" and "data-method" in a:
            self._method = a["data-method"]
        if tag == "td" and ("data-key" in a or "data-kind" in a):
            self._open, self._text = a, ""

    def handle_data(self, data):
        if self._open is not None:
            self._text += data

    def handle_endtag(self, tag):
        if tag == "td" and self._open is not None:
            a = self._open
            if "data-key" in a:
                self.cells.append((self._method, a["data-key"], a["data-value"], self._text))
            else:
                self.kind_cells.append((a["data-kind"], a["data-method"], self._text))
            self._open = None


def test_report_holds_the_scoreboard_numbers_of_metrics_json(report, runs):
    text, _, _ = report
    stored = json.loads(runs[0].output.with_suffix(".metrics.json").read_text())["methods"]
    parsed = _Cells()
    parsed.feed(text)
    assert {m for m, *_ in parsed.cells} == set(stored)          # every method of the run, positioning too
    assert {"kmcdf2", "gar", "ear", "lms", "lhc", "chi_square", "anfis"} <= set(stored)
    for method, key, value, shown in parsed.cells:
        assert json.loads(value) == stored[method][key], (method, key)
        assert shown == format_value(stored[method][key])
    assert len(parsed.cells) == 9 * len(stored)


def test_report_fetches_nothing(report):
    text, _, _ = report
    parsed = _Cells()
    parsed.feed(text)
    assert parsed.links and not [u for u in parsed.links if re.match(r"\s*(https?:)?//", u, re.IGNORECASE)]
    assert "<script" not in text and "<link" not in text and "@import" not in text and "url(" not in text
    images = [u for u in parsed.links if u.startswith("data:")]
    assert len(images) == 4           # tracks, CDF, error series, timeline
    for uri in images:                    # inside the SVGs: only references to their own elements
        svg = base64.b64decode(uri.split(",", 1)[1]).decode()
        assert re.findall(r'href="([^"]*)"', svg) and all(h.startswith("#") for h in re.findall(r'href="([^"]*)"', svg))


def test_report_lanes_and_kinds_count_what_the_scoreboard_counts(report):
    text, meta, review = report
    methods = meta["metrics"]["methods"]
    tallies = detection_tallies(review, meta["metrics"]["window"][0])
    for method in ("chi_square", "anfis"):
        mine = [t for t in tallies if t.method == method]
        assert {t.leader for t in mine} == {"leader1", "leader2"}
        assert sum(len(t.hits) for t in mine) == methods[method]["tp"]
        assert sum(len(t.false_alarms) for t in mine) == methods[method]["fp"]
        assert sum(len(t.misses) for t in mine) == methods[method]["fn"]
    parsed = _Cells()
    parsed.feed(text)
    flagged = {(k, m): int(s.split(" of ")[0]) for k, m, s in parsed.kind_cells}
    assert {k for k, _ in flagged} == {"stale", "drift", "outlier", "none"}
    for method in ("chi_square", "anfis"):   # every flag lands in exactly one kind's row
        assert sum(v for (k, m), v in flagged.items() if m == method) == methods[method]["tp"] + methods[method]["fp"]
    assert "a missed reply leaves no ranging epoch" in text


def test_the_same_run_gives_the_same_report(report):
    text, meta, review = report         # the CLI's report of the re-run against the original run's review data
    assert build_report(meta, review, load_intervals(SAMPLE / "anomalies.csv")) == text


def test_report_without_kinds_says_the_archive_has_none(report, tmp_path, capsys):
    _, meta, review = report
    text = build_report(meta, review, None)
    assert "not the kind of anomaly" in text and "labelled (kind unknown)" in text
    assert meta["run_id"] in text and meta["input_sha256"] in text and meta["package_version"] in text
    assert main(["report", str(tmp_path / "nope.mcap")]) == 1
    assert "no such file" in capsys.readouterr().err


def _fix_topics(path: Path) -> dict[str, int]:
    with ArchiveReader(path) as r:
        return {t: v["count"] for t, v in r.summary().topics.items() if v["schema"] == "foxglove.LocationFix"}


def test_export_geojson_and_kml_have_every_track_and_point(runs, tmp_path):
    results = runs[0].output
    counts = _fix_topics(results)
    assert main(["export", str(results), "--format", "geojson", "-o", str(tmp_path / "t.geojson")]) == 0
    features = json.loads((tmp_path / "t.geojson").read_text())["features"]
    assert {f["properties"]["topic"]: len(f["geometry"]["coordinates"]) for f in features} == counts
    ackf = next(f for f in features if f["properties"]["source"] == "ackf")
    lon, lat = ackf["geometry"]["coordinates"][0]
    assert 126.5 < lon < 126.7 and 45.6 < lat < 45.8 and ackf["properties"]["vehicle"] == "follower"
    assert len(ackf["properties"]["coordTimes"]) == len(ackf["properties"]["mission_s"]) == counts[
        ackf["properties"]["topic"]]
    assert main(["export", str(results), "--format", "kml", "-o", str(tmp_path / "t.kml")]) == 0
    marks = ET.parse(tmp_path / "t.kml").getroot().iter(f"{KML}Placemark")
    seen = {}
    for p in marks:
        track = p.find(f"{GX}Track")
        coords, whens = track.findall(f"{GX}coord"), track.findall(f"{KML}when")
        assert len(coords) == len(whens)
        seen[p.findtext(f"{KML}name")] = len(coords)
    assert seen == {f"{t.split('/')[3]} {t.split('/')[4]}": n for t, n in counts.items()}


def test_mission_s_column_counts_from_the_trial_start(archive, runs, tmp_path):
    gps = tmp_path / "gps.csv"
    assert main(["export", str(archive), "--topic", "/follower/gps", "-o", str(gps)]) == 0
    df = pd.read_csv(gps)
    assert df.columns[1] == "mission_s" and df["mission_s"].iloc[0] == 0.0
    assert np.allclose(np.diff(df["mission_s"].to_numpy()[:10]), 1.0)
    results = runs[0].output
    rid = runs[0].run_id
    det = tmp_path / "det.parquet"
    assert main(["export", str(results), "--topic", f"/replay/{rid}/follower/detections", "--format", "parquet",
                 "-o", str(det)]) == 0
    d = pd.read_parquet(det)
    start = int(run_metadata(results)["trial_start_ns"])
    expect = (d.index.asi8 - start) / 1e9
    assert np.array_equal(d["mission_s"].to_numpy(), expect) and 0 < d["mission_s"].min() < 5
    assert d["mission_s"].max() == pytest.approx(1700, abs=5)


def test_compare_prints_mission_seconds_truth_and_which_run_was_right(runs, capsys):
    a, b = (r.output for r in runs)
    assert main(["compare", str(a), str(b), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["a"]["label"] == "chi_square_alpha=0.01" and result["b"]["label"] == "chi_square_alpha=0.2"
    rows = result["differing_epochs"]["chi_square"]
    assert rows and all(0 < r["mission_s"] < 1800 for r in rows)
    right = result["right"]["chi_square"]
    assert right["epochs"] == len(rows)
    assert right["a"] == sum(r["a"] == bool(r["label"]) for r in rows)
    assert right["b"] == sum(r["b"] == bool(r["label"]) for r in rows)
    assert main(["compare", str(a), str(b), "--limit", "1000"]) == 0
    out = capsys.readouterr().out
    line = r"^\s+(\d+\.\d) s  follower <- (leader\d)\s+A (\w+)\s+B (\w+)\s+truth (\w+)$"
    listed = re.findall(line, out, re.MULTILINE)
    assert len(listed) == sum(len(v) for v in result["differing_epochs"].values())
    assert {x[4] for x in listed} <= {"normal", "anomalous"}
    assert "t=14" not in out and all(float(x[0]) < 1800 for x in listed)
    assert f"right on {right['a']} of {right['epochs']}" in out
    assert re.search(r"^all detectors: (A|B) was right more often", out, re.MULTILINE)


def _keep(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("someone else's file")
    return path


def _refused(argv: list[str], target: Path, capsys) -> None:
    assert main(argv) == 1, argv
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("exists" in err[0] or "not empty" in err[0]), err
    assert target.read_text() == "someone else's file"


def test_no_command_overwrites_a_file_it_did_not_create(archive, runs, tmp_path, capsys):
    res = str(runs[0].output)
    out = _keep(tmp_path / "x.mcap")
    _refused(["replay", str(archive), "-o", str(out), "--set", FAST[0]], out, capsys)
    metrics = _keep(tmp_path / "y.metrics.json")
    _refused(["replay", str(archive), "-o", str(tmp_path / "y.mcap"), "--set", FAST[0]], metrics, capsys)
    assert not (tmp_path / "y.mcap").exists()
    rrd = _keep(tmp_path / "z.rrd")
    _refused(["replay", str(archive), "-o", str(tmp_path / "z.mcap"), "--rrd", str(rrd)], rrd, capsys)
    for fmt in ("csv", "parquet", "geojson", "kml"):
        target = _keep(tmp_path / f"e.{fmt}")
        _refused(["export", res, "--topic", f"/replay/{runs[0].run_id}/follower/ackf", "--format", fmt,
                  "-o", str(target)], target, capsys)
    html = _keep(tmp_path / "r.html")
    _refused(["report", res, "-o", str(html)], html, capsys)
    trial = _keep(tmp_path / "sim" / "trial.toml")
    _refused(["simulate", "-o", str(trial.parent), "--duration", "60"], trial, capsys)
    demo = _keep(tmp_path / "demo" / "lake-trial.rrd")
    _refused(["demo", "--out", str(demo.parent), "--no-viewer"], demo, capsys)
    assert not (demo.parent / "lake-trial.mcap").exists()
    png = _keep(tmp_path / "k.png")
    _refused(["reproduce", "kmcdf", "--trials", "1", "--png", str(png), "--rrd", str(tmp_path / "k.rrd")], png,
             capsys)
    assert not (tmp_path / "k.rrd").exists()
    table = _keep(tmp_path / "batch" / "metrics.csv")
    _refused(["batch", str(archive), "-o", str(table.parent), "--quiet"], table, capsys)
    assert not (table.parent / "runs").exists()


def test_force_replaces(runs, tmp_path):
    res = str(runs[0].output)
    target = _keep(tmp_path / "e.geojson")
    assert main(["export", res, "--format", "geojson", "-o", str(target), "--force"]) == 0
    assert json.loads(target.read_text())["type"] == "FeatureCollection"
    csv = _keep(tmp_path / "e.csv")
    assert main(["export", res, "--topic", f"/replay/{runs[0].run_id}/follower/ackf", "-o", str(csv), "--force"]) == 0
    assert pd.read_csv(csv)["mission_s"].iloc[0] == pytest.approx(1.0, abs=0.01)


coords = st.lists(st.tuples(st.one_of(st.floats(-90, 90), st.just(float("nan"))),
                            st.one_of(st.floats(-180, 180), st.just(float("inf")))), min_size=0, max_size=30)


@settings(max_examples=60, deadline=None)
@given(coords, st.text(max_size=12))
def test_geojson_and_kml_keep_every_finite_point(points, name):
    lat = np.array([p[0] for p in points], float)
    lon = np.array([p[1] for p in points], float)
    t_ns = 1_476_237_600_000_000_000 + np.arange(len(points), dtype="int64") * 1_000_000_000
    track = Track(name, t_ns, lat, lon, (t_ns - t_ns[0]) / 1e9 if len(t_ns) else np.empty(0), {"source": "ckf"})
    ok = np.isfinite(lat) & np.isfinite(lon)
    features = json.loads(feature_collection([track]))["features"]
    if not ok.any():
        assert features == []
    else:
        geom = features[0]["geometry"]
        got = np.array(geom["coordinates"] if geom["type"] == "LineString" else [geom["coordinates"]])
        assert got.shape == (ok.sum(), 2)
        assert np.allclose(got[:, 0], lon[ok], atol=1e-7) and np.allclose(got[:, 1], lat[ok], atol=1e-7)
        assert features[0]["properties"]["name"] == name
    root = ET.fromstring(kml_document(name, [("follower", [(track, "ff0000ff")])]))   # parses, whatever the name
    if name.isprintable():
        assert root.findtext(f"{KML}Document/{KML}name") == name
    assert len(list(root.iter(f"{GX}coord"))) == ok.sum() == len(list(root.iter(f"{KML}when")))


def test_report_has_every_track_and_each_vehicles_own_navigation(report):
    text, meta, review = report
    table = re.search(r'<table id="tracks-table">(.*?)</table>', text, re.S)
    assert table is not None
    shown = set(re.findall(r"<tr><td>([^<]+)</td><td>([^<]+)</td>", table.group(1)))
    assert shown == {(str(v), str(s)) for v, s in review.tracks[["vehicle", "source"]].drop_duplicates()
                     .itertuples(index=False)}
    assert ("follower", "dead_reckoning (DVL)") in shown and ("leader1", "ins") in shown
    nav = re.search(r'<table id="navigation-table">(.*?)</table>', text, re.S)
    assert nav is not None
    rows = re.findall(r'<tr><td class="num">(\d+)</td><td>([^<]+)</td><td>([^<]+)</td><td class="num">([^<]+)</td>',
                      nav.group(1))
    stored = meta["metrics"]["navigation"]
    assert {(v, m) for _, v, m, _ in rows} == {(v, m) for v, n in stored.items() for m in n["methods"]}
    for _, vehicle, method, p50 in rows:
        assert p50 == format_value(stored[vehicle]["methods"][method]["error_p50_m"])


def test_report_of_the_bundled_sample_finds_its_anomaly_kinds_itself(runs, tmp_path, capsys):
    out = tmp_path / "found.html"
    assert main(["report", str(runs[0].output), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"anomaly kinds from {SAMPLE / 'anomalies.csv'}" in printed
    kinds = {i.kind for i in load_intervals(SAMPLE / "anomalies.csv")}
    section = out.read_text().split('id="kinds"', 1)[1]
    assert all(kind in section for kind in kinds)
