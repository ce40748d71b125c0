"""One output rule for every command that writes: refuse an existing file with one line, replace only with --force,
claim the output atomically, and clean up the part files of writers that are gone."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from formats.output_files import OutputBusy, OutputClaim, OutputExists, part_name, write_new_file
from recorders.attachments import unpack
from recorders.capture.session import CaptureOptions, CaptureSession, part_path
from recorders.manifest import parse_manifest
from replay.cli import main
from tests.test_record import GPS_CSV, MANIFEST, RANGE_CSV


@pytest.fixture
def trial(tmp_path) -> Path:
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs/gps.csv").write_bytes(GPS_CSV)
    (tmp_path / "logs/range.csv").write_bytes(RANGE_CSV)
    (tmp_path / "trial.toml").write_text(MANIFEST)
    return tmp_path


@pytest.fixture
def archive(trial) -> Path:
    out = trial / "t.mcap"
    assert main(["record", str(trial / "trial.toml"), "-o", str(out), "--quiet"]) == 0
    return out


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def _one_error_line(err: str, *words: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], lines[0]


def test_record_while_another_process_writes_the_same_output_is_refused(trial, capsys):
    out = trial / "t.mcap"
    held = OutputClaim(out)  # what a first `record` holds while it writes
    try:
        assert main(["record", str(trial / "trial.toml"), "-o", str(out), "--quiet", "--force"]) == 1
        _one_error_line(capsys.readouterr().err, str(out), "being written by another process")
        assert not out.exists()
    finally:
        held.abandon()
    assert not held.lock_path.exists()  # the claim leaves nothing behind
    assert main(["record", str(trial / "trial.toml"), "-o", str(out), "--quiet"]) == 0
    assert sorted(p.name for p in trial.iterdir()) == ["logs", "t.mcap", "trial.toml"]


def test_two_record_processes_at_once_never_both_succeed(trial):
    out = trial / "t.mcap"
    cmd = [sys.executable, "-m", "replay.cli", "record", str(trial / "trial.toml"), "-o", str(out), "--quiet"]
    runs = [subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(r.wait(), r.stderr.read() if r.stderr else "") for r in runs]
    for r in runs:
        if r.stderr:
            r.stderr.close()
    codes = sorted(code for code, _ in results)
    assert codes == [0, 1], results  # the loser is refused, whenever it comes
    loser = next(err for code, err in results if code == 1)
    assert "Traceback" not in loser and ("exists" in loser or "being written by another process" in loser)
    with ArchiveReader(out) as reader:
        assert not reader.problems


def test_a_writer_never_replaces_a_file_that_appears_while_it_writes(tmp_path):
    out = tmp_path / "a.mcap"
    writer = ArchiveWriter(out, replace=False)
    writer.add_metadata("trial", {"name": "mine"})
    out.write_text("someone else's")
    with pytest.raises(OutputExists, match="exists: not replaced"):
        writer.close()
    assert out.read_text() == "someone else's"
    assert [p.name for p in tmp_path.iterdir()] == ["a.mcap"]  # no part file, no lock left


def test_a_dead_writers_lock_file_does_not_block(tmp_path):
    out = tmp_path / "a.mcap"
    (tmp_path / ".a.mcap.lock").write_text(f"{_dead_pid()}\n")  # kill -9 leaves the file, not the lock
    with ArchiveWriter(out, replace=False) as w:
        w.add_metadata("trial", {"name": "t"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcap"]


def test_replay_cleans_up_a_dead_replays_part_file_and_refuses_an_existing_result(archive, capsys):
    out = archive.with_name("r.mcap")
    stale = part_name(out, _dead_pid())
    stale.write_bytes(b"half a results archive")
    mine = part_name(out, 1)  # pid 1 is alive: not ours to remove
    mine.write_bytes(b"a live process's part")
    assert main(["replay", str(archive), "-o", str(out), "--json"]) == 0
    assert not stale.exists() and mine.exists()
    before = out.read_bytes()
    capsys.readouterr()
    assert main(["replay", str(archive), "-o", str(out), "--json"]) == 1
    _one_error_line(capsys.readouterr().err, str(out), "--force")
    assert out.read_bytes() == before


def test_recover_refuses_an_existing_output_and_replaces_it_with_force(archive, capsys):
    out = archive.with_name("fixed.mcap")
    out.write_text("notes")
    stale = part_name(out, _dead_pid())
    stale.write_bytes(b"x")
    assert main(["recover", str(archive), "-o", str(out)]) == 1
    _one_error_line(capsys.readouterr().err, str(out), "--force")
    assert out.read_text() == "notes"
    assert main(["recover", str(archive), "-o", str(out), "--force"]) == 0
    assert not stale.exists()
    with ArchiveReader(out) as reader:
        assert {a.name for a in reader.attachments()} == {"logs/gps.csv", "logs/range.csv"}


def test_unpack_checks_every_name_before_writing_anything(archive, tmp_path, capsys):
    target = tmp_path / "u"
    (target / "logs").mkdir(parents=True)
    (target / "logs/range.csv").write_text("mine")
    assert main(["unpack", str(archive), str(target)]) == 1
    _one_error_line(capsys.readouterr().err, str(target / "logs/range.csv"), "nothing unpacked")
    assert sorted(p.name for p in (target / "logs").iterdir()) == ["range.csv"]  # gps.csv not written either
    assert (target / "logs/range.csv").read_text() == "mine"
    assert main(["unpack", str(archive), str(target), "--force"]) == 0
    assert (target / "logs/range.csv").read_bytes() == RANGE_CSV
    assert (target / "logs/gps.csv").read_bytes() == GPS_CSV


def test_unpack_refuses_a_file_where_a_directory_must_go(archive, tmp_path):
    target = tmp_path / "u"
    target.mkdir()
    (target / "logs").write_text("a file, not a folder")
    with pytest.raises(NotADirectoryError, match="nothing unpacked"):
        unpack(archive, target, replace=True)
    assert sorted(p.name for p in target.iterdir()) == ["logs"]
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError, match="not a directory"):
        unpack(archive, tmp_path / "f")


def test_unpack_refuses_a_directory_in_the_way_even_with_force(archive, tmp_path):
    target = tmp_path / "u"
    (target / "logs/gps.csv").mkdir(parents=True)
    with pytest.raises(IsADirectoryError, match="nothing unpacked"):
        unpack(archive, target, replace=True)
    assert not (target / "logs/range.csv").exists()


def test_feed_manifest_out_follows_the_rule(trial, capsys):
    manifest = trial / "trial.toml"
    out = trial / "live.toml"
    out.write_text("kept")
    args = ["feed", str(manifest), "--to", "udp://127.0.0.1:9", "--seconds", "0", "--hold-s", "0"]
    assert main([*args, "--manifest-out", str(out)]) == 1
    _one_error_line(capsys.readouterr().err, str(out), "--force")
    assert out.read_text() == "kept"
    assert main([*args, "--manifest-out", str(manifest), "--force"]) == 1
    _one_error_line(capsys.readouterr().err, "manifest being played")
    assert manifest.read_text() == MANIFEST
    assert main([*args, "--manifest-out", str(out), "--force"]) == 0
    assert 'source = "udp://127.0.0.1:9"' in out.read_text()
    assert sorted(p.name for p in trial.iterdir()) == ["live.toml", "logs", "trial.toml"]


def _live_manifest(tmp_path: Path):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    text = f"""[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "a"\nrole = "leader"\n
[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\nsource = "udp://127.0.0.1:{port}"\n"""
    (tmp_path / "live.toml").write_text(text)
    return parse_manifest(text, tmp_path / "live.toml")


def test_capture_refuses_an_existing_output_before_it_starts(tmp_path, capsys):
    _live_manifest(tmp_path)
    out = tmp_path / "c.mcap"
    out.write_text("an earlier capture")
    assert main(["capture", str(tmp_path / "live.toml"), "-o", str(out), "--duration", "0.1"]) == 1
    _one_error_line(capsys.readouterr().err, str(out), "--force")
    assert out.read_text() == "an earlier capture" and not part_path(out).exists()
    assert main(["capture", str(tmp_path / "live.toml"), "-o", str(out), "--duration", "0.1", "--force"]) == 0
    with ArchiveReader(out) as reader:
        assert reader.metadata_json("trial")["name"] == "t"


def test_capture_keeps_its_part_file_when_the_output_appears_meanwhile(tmp_path):
    manifest = _live_manifest(tmp_path)
    out = tmp_path / "c.mcap"
    session = CaptureSession(manifest, out, CaptureOptions(flush_s=0.05, duration_s=0.1))
    out.write_text("written by hand during the capture")
    with pytest.raises(OutputExists):
        session.run()
    assert out.read_text() == "written by hand during the capture"
    with ArchiveReader(part_path(out)) as reader:  # the capture is not lost: recover reads it
        assert reader.metadata_json("trial")["name"] == "t"


def test_a_second_capture_into_the_same_output_is_refused(tmp_path):
    manifest = _live_manifest(tmp_path)
    out = tmp_path / "c.mcap"
    held = OutputClaim(out)
    try:
        with pytest.raises(OutputBusy, match="being written by another process"):
            CaptureSession(manifest, out, CaptureOptions(duration_s=0.1))
    finally:
        held.abandon()
    assert not part_path(out).exists()


def test_write_new_file_is_whole_and_never_replaces_without_asking(tmp_path):
    out = tmp_path / "m.toml"
    write_new_file(out, b"one")
    with pytest.raises(OutputExists):
        write_new_file(out, b"two")
    assert out.read_bytes() == b"one"
    write_new_file(out, b"two", replace=True)
    assert out.read_bytes() == b"two"
    with pytest.raises(IsADirectoryError):
        write_new_file(tmp_path, b"x", replace=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.toml"]
