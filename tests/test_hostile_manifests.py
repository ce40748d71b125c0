"""Issue 14, manifests and `record`: logs contained in the manifest's folder, outputs never over inputs,
part files never left behind, every value checked; one line and exit 1, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from formats.mcap_reader import ArchiveReader
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record
from replay.cli import main

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "samples" / "lake_trial"
GPS = (SAMPLE / "leader1" / "gps.log").read_bytes()[:20_000]


def trial(tmp_path: Path, path: str = "gps.log", extra: str = "") -> Path:
    """A one-vehicle trial folder: gps.log and trial.toml (its log `path` and extra log keys as given)."""
    folder = tmp_path / "trial"
    folder.mkdir(exist_ok=True)
    (folder / "gps.log").write_bytes(GPS)
    (folder / "trial.toml").write_text(
        '[trial]\nname = "t"\ndate = "2016-10-12"\n\n[[vehicles]]\nname = "a"\nrole = "leader"\n\n'
        f'[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\npath = "{path}"\n{extra}\n')
    return folder / "trial.toml"


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    rc = main(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return rc, out, err


def error_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and ": error: " in lines[0], err
    return lines[0]


# -- containment --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["dotdot", "absolute", "symlink"])
def test_logs_outside_the_manifest_folder_are_refused(tmp_path, capsys, kind):
    secret = tmp_path / "secret.log"
    secret.write_bytes(GPS)
    rel = os.path.relpath(secret, tmp_path / "trial")
    manifest = trial(tmp_path, {"dotdot": rel, "absolute": str(secret), "symlink": "link.log"}[kind])
    if kind == "symlink":
        (manifest.parent / "link.log").symlink_to(secret)
    out = tmp_path / "out.mcap"
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(out), "--quiet")
    assert rc == 1 and "outside the manifest's folder" in error_line(err) and str(secret) in err
    assert not out.exists()
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(out), "--quiet", "--allow-outside")
    assert rc == 0 and out.exists()


def test_a_symlink_inside_the_folder_is_fine(tmp_path, capsys):
    manifest = trial(tmp_path, "sub/gps.log")
    (manifest.parent / "sub").mkdir()
    (manifest.parent / "sub" / "gps.log").symlink_to(manifest.parent / "gps.log")
    rc, _, _ = run_cli(capsys, "record", str(manifest), "-o", str(tmp_path / "o.mcap"), "--quiet")
    assert rc == 0


@pytest.mark.parametrize("pattern", ["../*.log", "/*.log", "sub/../../*.log"])
def test_a_glob_that_climbs_out_of_the_folder_is_refused_before_it_is_walked(tmp_path, capsys, pattern):
    (tmp_path / "secret.log").write_bytes(GPS)
    pattern = pattern if not pattern.startswith("/") else str(tmp_path) + pattern
    manifest = trial(tmp_path, pattern)
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(tmp_path / "o.mcap"), "--quiet")
    assert rc == 1 and "reaches outside the manifest's folder" in error_line(err)
    if not pattern.startswith("sub"):   # a ".." glob is the user's to allow (the secret is then matched)
        rc, _, _ = run_cli(capsys, "record", str(manifest), "-o", str(tmp_path / "o.mcap"), "--quiet",
                           "--allow-outside")
        assert rc == 0


def test_a_glob_matching_too_many_files_is_refused(tmp_path, monkeypatch):
    manifest = trial(tmp_path, "parts/*.log")
    (manifest.parent / "parts").mkdir()
    for k in range(6):
        (manifest.parent / "parts" / f"{k}.log").write_bytes(GPS[:100])
    monkeypatch.setattr("recorders.manifest.MAX_GLOB_MATCHES", 5)
    with pytest.raises(ManifestError, match="matches more than 5 files"):
        load_manifest(manifest)
    monkeypatch.setattr("recorders.manifest.MAX_GLOB_MATCHES", 6)
    assert len(load_manifest(manifest).vehicles[0].logs[0].parts) == 6


def test_a_manifest_is_read_bounded(tmp_path, monkeypatch):
    """A huge manifest is refused after MAX_MANIFEST_BYTES, not read whole; a device, FIFO or folder before any read."""
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * 1001)
    monkeypatch.setattr("recorders.manifest.MAX_MANIFEST_BYTES", 1000)
    with pytest.raises(ManifestError, match="not a trial manifest"):
        load_manifest(big)
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    for special in ("/dev/zero", fifo, tmp_path):
        with pytest.raises(ManifestError, match="not a regular file"):
            load_manifest(special)


# -- outputs ------------------------------------------------------------------------------------------------
def test_output_never_overwrites_an_input_or_a_foreign_file(tmp_path, capsys):
    manifest = trial(tmp_path)
    log = manifest.parent / "gps.log"
    for target in (log, manifest):
        before = target.read_bytes()
        rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(target), "--quiet", "--force")
        assert rc == 1 and "is an input of this trial" in error_line(err) and target.read_bytes() == before
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(notes), "--quiet", "--force")
    assert rc == 1 and "not an MCAP archive" in error_line(err) and notes.read_text() == "mine"


def test_an_existing_archive_needs_force(tmp_path, capsys):
    manifest = trial(tmp_path)
    out = tmp_path / "out.mcap"
    assert run_cli(capsys, "record", str(manifest), "-o", str(out), "--quiet")[0] == 0
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(out), "--quiet")
    assert rc == 1 and "--force to replace it" in error_line(err)
    assert run_cli(capsys, "record", str(manifest), "-o", str(out), "--quiet", "--force")[0] == 0
    with ArchiveReader(out) as r:
        assert r.summary().message_count > 0


def test_a_directory_as_output_leaves_nothing(tmp_path, capsys):
    manifest = trial(tmp_path)
    out = tmp_path / "dir"
    out.mkdir()
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(out), "--quiet")
    assert rc == 1 and "is a directory" in error_line(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir", "trial"] and not list(out.iterdir())


def test_a_failure_while_writing_removes_the_part_file(tmp_path):
    manifest = load_manifest(trial(tmp_path))
    (manifest.root / "gps.log").unlink()  # gone between the manifest check and the read
    with pytest.raises(OSError):
        record(manifest, tmp_path / "out.mcap")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trial"]


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_part_files_of_dead_processes_are_removed(tmp_path, capsys):
    manifest = trial(tmp_path)
    dead = tmp_path / f".out.mcap.part-{_dead_pid()}"
    alive = tmp_path / f".out.mcap.part-{os.getppid()}"
    other = tmp_path / f".other.mcap.part-{_dead_pid()}"
    for p in (dead, alive, other):
        p.write_bytes(b"partial")
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(tmp_path / "out.mcap"), "--quiet")
    assert rc == 0 and f"removed {dead}" in err
    assert not dead.exists() and alive.exists() and other.exists()


# -- values -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("extra, words", [
    ("clock_offset_s = nan", "clock_offset_s = nan"),
    ("clock_offset_s = inf", "clock_offset_s = inf"),
    ("clock_offset_s = -inf", "clock_offset_s = -inf"),
    ("clock_offset_s = 1e30", "clock_offset_s = 1e+30"),
    ('clock_offset_s = "soon"', "clock_offset_s = 'soon' is not a number"),
    ('prefix = "weird"', "prefix = 'weird' is not one of auto, none, iso8601, unix"),
    ("uere_m = -1.0", "uere_m = -1.0"),
    ("sound_speed_mps = 1e400", "sound_speed_mps = inf"),
    ("anything = 1e300", "anything = 1e+300"),
])
def test_manifest_values_are_checked_with_one_line(tmp_path, capsys, extra, words):
    manifest = trial(tmp_path, extra=extra)
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(tmp_path / "o.mcap"), "--quiet")
    assert rc == 1 and words in error_line(err) and "log 1 (gps.log)" in err


def test_trial_and_vehicle_values_are_checked(tmp_path):
    manifest = trial(tmp_path)
    text = manifest.read_text()
    for old, new, words in (('name = "t"', 'name = "t"\nsound_speed_mps = nan', "sound_speed_mps = nan"),
                            ('role = "leader"', 'role = "leader"\nmodem_address = 1099511627776',
                             "modem_address = 1099511627776 is out of range")):
        manifest.write_text(text.replace(old, new))
        with pytest.raises(ManifestError, match=words):
            load_manifest(manifest)


# -- strings ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("old, new, key, code", [
    ('path = "gps.log"', 'path = "gps\\u0000.log"', "vehicles[1].logs[1].path", "U+0000"),
    ('path = "gps.log"', 'path = "gps.log\\n"', "vehicles[1].logs[1].path", "U+000A"),
    ('name = "t"', 'name = "t\\u001b[2J"', "trial.name", "U+001B"),
    ('name = "a"', 'name = "a\\u0000"', "vehicles[1].name", "U+0000"),
    ('sensor = "gps"', 'sensor = "gps\\r"', "vehicles[1].logs[1].sensor", "U+000D"),
    ('format = "nmea"', 'format = "nmea"\nsplit = ["x", "y\\u0085"]', "vehicles[1].logs[1].split[2]", "U+0085"),
    ('format = "nmea"', 'format = "nmea"\ncolumns = { time = "t\\u007f" }', "vehicles[1].logs[1].columns.time",
     "U+007F"),
])
def test_a_control_character_in_any_manifest_string_is_one_line(tmp_path, capsys, old, new, key, code):
    manifest = trial(tmp_path)
    manifest.write_text(manifest.read_text().replace(old, new, 1))
    rc, _, err = run_cli(capsys, "record", str(manifest), "-o", str(tmp_path / "o.mcap"), "--quiet")
    line = error_line(err)
    assert rc == 1 and f"{key} holds a control character ({code})" in line and str(manifest) in line
    assert not (tmp_path / "o.mcap").exists()
    with pytest.raises(ManifestError, match="control character"):
        load_manifest(manifest)


def test_a_control_character_in_a_key_is_refused_and_a_tab_is_not(tmp_path):
    manifest = trial(tmp_path)
    text = manifest.read_text()
    manifest.write_text(text.replace('format = "nmea"', 'format = "nmea"\n"odd\\u0000key" = 1', 1))
    with pytest.raises(ManifestError, match="a key 'vehicles\\[1\\].logs\\[1\\].odd\\\\x00key' holds a control"):
        load_manifest(manifest)
    manifest.write_text(text.replace('name = "t"', 'name = "t\\tu"', 1))
    assert load_manifest(manifest).name == "t\tu"  # a tab (a tab-separated log's delimiter) is text
