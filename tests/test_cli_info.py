"""`auvreplay info` and the command-line frame: help, version, exit codes, JSON."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from formats import schemas as S
from formats.mcap_writer import ArchiveWriter
from replay.cli import COMMANDS, main

T0 = 1_476_259_200_000_000_000


@pytest.fixture
def archive(tmp_path):
    path = tmp_path / "trial.mcap"
    with ArchiveWriter(path) as w:
        for i in range(20):
            w.write("/leader1/gps", S.location_fix(T0 + i * 10**9, "leader1", 45.7, 126.6), T0 + i * 10**9)
        w.add_attachment("leader1/gps.log", b"abc")
        w.add_metadata("trial", {"name": "lake", "vehicles": [{"name": "leader1", "role": "leader"}]})
        w.add_metadata("recording", {"files": [{"path": "leader1/gps.log", "vehicle": "leader1", "sensor": "gps",
                                                "format": "nmea", "parsed": 20, "skipped": 1, "bad_checksum": 1}]})
    return path


def test_info_json_has_the_documented_keys(archive, capsys):
    assert main(["info", str(archive), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["topics"] == {"/leader1/gps": {"count": 20, "schema": "foxglove.LocationFix"}}
    assert info["attachments"] == [{"name": "leader1/gps.log", "size": 3, "media_type": "application/octet-stream"}]
    assert info["start"] == "2016-10-12T08:00:00Z" and info["end"] == "2016-10-12T08:00:19Z"
    assert info["vehicles"] == [{"name": "leader1", "role": "leader"}]
    assert info["diagnostics"]["leader1/gps.log"]["bad_checksum"] == 1
    assert info["diagnostics"]["leader1/gps.log"]["parsed"] == 20


def test_info_text(archive, capsys):
    assert main(["info", str(archive)]) == 0
    out = capsys.readouterr().out
    assert "/leader1/gps" in out and "lake" in out and "leader1/gps.log" in out


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 not an archive"])
def test_bad_files_give_one_line_and_exit_1(tmp_path, capsys, content):
    path = tmp_path / "bad.mcap"
    path.write_bytes(content)
    assert main(["info", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.mcap" in err[0] and "Traceback" not in err[0]


def test_missing_file_exits_1(tmp_path, capsys):
    assert main(["info", str(tmp_path / "nope.mcap")]) == 1
    assert "nope.mcap" in capsys.readouterr().err


def test_a_directory_is_named_as_one(tmp_path, capsys):
    assert main(["info", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "a directory, not an MCAP archive" in err[0]


def test_truncated_file_is_recovered_with_a_warning(archive, tmp_path, capsys):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(archive.read_bytes()[:-200])
    assert main(["info", str(cut), "--json"]) == 0
    captured = capsys.readouterr()
    info = json.loads(captured.out)
    assert info["recovered"] and info["problems"]


def test_usage_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["info"])
    assert exc.value.code == 2
    with pytest.raises(SystemExit) as exc:
        main(["no-such-command"])
    assert exc.value.code == 2
    assert main([]) == 2


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    assert "usage: auvreplay" in capsys.readouterr().out


def test_console_script_version(venv_bin):
    out = subprocess.run([str(venv_bin / "auvreplay"), "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("auvreplay ")
    bad = subprocess.run([sys.executable, "-m", "replay.cli", "info", "/nonexistent.mcap"], capture_output=True, text=True)
    assert bad.returncode == 1 and "Traceback" not in bad.stderr
