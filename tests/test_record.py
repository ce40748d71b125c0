"""Recording a manifest into an archive: topics, diagnostics, summary, unpack, manifest errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from recorders.attachments import safe_target, unpack
from recorders.manifest import ManifestError, load_manifest, parse_manifest
from replay.cli import main

MANIFEST = """
[trial]
name = "csv-trial"
date = "2016-10-12"

[[vehicles]]
name = "leader1"
role = "leader"
modem_address = 1

[[vehicles]]
name = "follower"
role = "follower"
modem_address = 3

[[vehicles.logs]]
sensor = "gps"
format = "csv"
path = "logs/gps.csv"
clock_offset_s = 0.5
columns = { time = "t", latitude = "lat", longitude = "lon" }

[[vehicles.logs]]
sensor = "modem"
format = "csv"
path = "logs/range.csv"
time_format = "tod"
columns = { time = "t", range_m = "range", source = "from" }
"""

GPS_CSV = b"t,lat,lon\r\n1476259200.0,45.7,126.6\r\n1476259201.0,45.70001,126.6\r\nbad,1,2\r\n1476259202.0,45.7\r\n"
RANGE_CSV = b"t,range,from\n23:59:58,600.5,leader1\n00:00:03,,leader1\n"


def write_csv_trial(folder: Path) -> Path:
    """The small CSV trial (a GPS and a range log, their manifest) written into `folder`."""
    (folder / "logs").mkdir()
    (folder / "logs/gps.csv").write_bytes(GPS_CSV)
    (folder / "logs/range.csv").write_bytes(RANGE_CSV)
    (folder / "trial.toml").write_text(MANIFEST)
    return folder


@pytest.fixture
def trial(tmp_path) -> Path:
    return write_csv_trial(tmp_path)


def test_record_writes_topics_diagnostics_and_summary(trial, capsys):
    out = trial / "t.mcap"
    assert main(["record", str(trial / "trial.toml"), "-o", str(out)]) == 0
    table = capsys.readouterr().out
    assert "logs/gps.csv" in table and "skipped" in table
    with ArchiveReader(out) as r:
        msgs = list(r.messages())
        trial_meta = r.metadata_json("trial")
        files = {f["path"]: f for f in r.metadata_json("recording")["files"]}
    gps = [m for m in msgs if m.topic == "/follower/gps"]
    # clock offset 0.5 s applied to log time and to the message's own timestamp
    assert [m.log_time_ns for m in gps] == [1476259200_500000000, 1476259201_500000000]
    assert gps[1].message.latitude == 45.70001 and gps[0].message.timestamp.nanos == 500_000_000
    ranges = [m for m in msgs if m.topic == "/follower/modem/range"]
    # time of day with the manifest date; the row after midnight has no range: refused at record time
    assert [m.log_time_ns for m in ranges] == [1476316798_000000000]
    assert ranges[0].message.travel_time_s == pytest.approx(600.5 / 1500.0)
    assert ranges[0].message.source == "leader1" and ranges[0].message.destination == "follower"
    diags = [m.message for m in msgs if m.topic == "/diagnostics"]
    assert len(diags) == 3 and sorted((d.file, d.line) for d in diags) == [
        ("logs/gps.csv", 4), ("logs/gps.csv", 5), ("logs/range.csv", 3)]
    assert any("range_m is NaN" in d.message for d in diags)
    assert files["logs/gps.csv"]["parsed"] == 2 and files["logs/gps.csv"]["skipped"] == 2
    assert files["logs/range.csv"]["parsed"] == 1 and files["logs/range.csv"]["skipped"] == 1
    assert files["logs/range.csv"]["bad_ranges"] == 1
    assert [v["name"] for v in trial_meta["vehicles"]] == ["leader1", "follower"]
    assert trial_meta["modem_addresses"] == {"1": "leader1", "3": "follower"}
    assert "csv-trial" in trial_meta["manifest"]


def test_unpack_gives_the_logs_back_byte_for_byte(trial, tmp_path):
    out = trial / "t.mcap"
    assert main(["record", str(trial / "trial.toml"), "-o", str(out), "--quiet"]) == 0
    target = tmp_path / "unpacked"
    assert main(["unpack", str(out), str(target)]) == 0
    assert (target / "logs/gps.csv").read_bytes() == GPS_CSV
    assert (target / "logs/range.csv").read_bytes() == RANGE_CSV


def test_info_reports_the_recording(trial, capsys):
    out = trial / "t.mcap"
    main(["record", str(trial / "trial.toml"), "-o", str(out), "--quiet"])
    capsys.readouterr()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["diagnostics"]["logs/gps.csv"]["skipped"] == 2
    assert info["topics"]["/diagnostics"]["count"] == 3  # the range row without a range too
    assert {a["name"] for a in info["attachments"]} == {"logs/gps.csv", "logs/range.csv"}


@pytest.mark.parametrize(
    "name, safe",
    [("logs/gps.csv", True), ("a/b/c.log", True), ("../evil", False), ("/etc/passwd", False),
     ("a/../../x", False), ("C:/x", False), ("a\\..\\x", False), ("", False), ("./a", True), ("a//b", True)],
)
def test_safe_target(tmp_path, name, safe):
    assert (safe_target(tmp_path, name) is not None) == safe


def test_unpack_refuses_names_outside_the_target(tmp_path, capsys):
    path = tmp_path / "evil.mcap"
    with ArchiveWriter(path) as w:
        w.add_attachment("../escape.txt", b"x")
        w.add_attachment("/tmp/abs.txt", b"y")
        w.add_attachment("ok/file.log", b"z")
        w.add_attachment("link/inside.txt", b"w")
    target = tmp_path / "out"
    target.mkdir()
    (target / "link").symlink_to(tmp_path)  # a symlinked directory pointing outside
    result = unpack(path, target)
    assert [p.relative_to(target).as_posix() for p in result.written] == ["ok/file.log"]
    assert set(result.refused) == {"../escape.txt", "/tmp/abs.txt", "link/inside.txt"}
    assert not (tmp_path / "escape.txt").exists() and not (tmp_path / "inside.txt").exists()
    assert main(["unpack", str(path), str(tmp_path / "out2")]) == 1
    assert "refused" in capsys.readouterr().err


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda m: m.replace('format = "csv"', 'format = "nosuch"', 1), "format 'nosuch' is not a gps format"),
        (lambda m: m.replace("logs/gps.csv", "logs/missing.csv"), "logs/missing.csv not found"),
        (lambda m: m.replace('role = "leader"', 'role = "captain"'), "role 'captain'"),
        (lambda m: m + "\n[[vehicles]\n", "not valid TOML"),
        (lambda m: m.replace('sensor = "gps"', 'sensor = "sonar"'), "unknown sensor 'sonar'"),
        (lambda m: m.replace("columns = { time", 'target = "ghost"\ncolumns = { time', 1), "'ghost' is not a vehicle"),
        (lambda m: m.replace('name = "follower"', 'name = "leader1"'), "used twice"),
    ],
)
def test_bad_manifests_give_one_clear_message(trial, capsys, edit, words):
    (trial / "trial.toml").write_text(edit(MANIFEST))
    assert main(["record", str(trial / "trial.toml"), "-o", str(trial / "t.mcap")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]
    assert not (trial / "t.mcap").exists()


def test_bad_csv_mapping_is_a_clear_error(trial, capsys):
    (trial / "trial.toml").write_text(MANIFEST.replace("latitude = \"lat\"", "lattitude = \"lat\""))
    assert main(["record", str(trial / "trial.toml"), "-o", str(trial / "t.mcap")]) == 1
    assert "lattitude" in capsys.readouterr().err
    assert not (trial / "t.mcap").exists()


def test_manifest_defaults():
    m = parse_manifest('[[vehicles]]\nname = "a"\nrole = "buoy"\n', Path("/x/trial.toml"))
    assert m.name == "trial" and m.date is None and m.vehicles[0].logs == ()
    with pytest.raises(ManifestError, match="no \\[\\[vehicles\\]\\]"):
        parse_manifest("[trial]\nname='x'\n", Path("/x/t.toml"))
    with pytest.raises(ManifestError, match="cannot read"):
        load_manifest("/nonexistent/trial.toml")
