"""Recording with worker processes gives the serial archive byte for byte, and fails as the serial path does."""

from __future__ import annotations

import multiprocessing
import os
import shutil
import signal
import time
from pathlib import Path

import pytest

import recorders.record as rec
from formats.mcap_reader import ArchiveReader
from formats.records import FormatError
from recorders import csvlog
from recorders.base import blockwise
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record, resolve_workers
from replay.cli import main

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"

pytestmark = pytest.mark.skipif(not rec.can_fork(), reason="worker processes are forked")

CSV_MANIFEST = """
[trial]
name = "csv-trial"
date = "2016-10-12"

[[vehicles]]
name = "follower"
role = "follower"
modem_address = 3

[[vehicles.logs]]
sensor = "gps"
format = "csv"
path = "gps.csv"
columns = { time = "t", latitude = "lat", longitude = "lon" }

[[vehicles.logs]]
sensor = "modem"
format = "csv"
path = "range.csv"
time_format = "TIME_FORMAT"
columns = { time = "t", range_m = "range", source = "from" }
"""


LATE_GPS_LOG = """
[[vehicles.logs]]
sensor = "gps"
format = "csv"
path = "late.csv"
columns = { time = "t", latitude = "lat", longitude = "lon" }
"""


def _csv_trial(root: Path, time_format: str = "tod") -> Path:
    (root / "gps.csv").write_bytes(b"t,lat,lon\n1476259200.0,45.7,126.6\nbad,1,2\n1476259201.0,45.70001,126.6\n")
    (root / "range.csv").write_bytes(b"t,range,from\n23:59:58,600.5,leader1\n00:00:03,,leader1\n")
    (root / "trial.toml").write_text(CSV_MANIFEST.replace("TIME_FORMAT", time_format))
    return root / "trial.toml"


def _errors_serial_and_parallel(manifest, directory: Path) -> list[str]:
    """The ManifestError text of recording with 1 and with 2 workers (each must fail, leaving nothing)."""
    messages = []
    for workers in (1, 2):
        with pytest.raises(ManifestError) as err:
            record(manifest, directory / "t.mcap", workers=workers)
        messages.append(str(err.value))
        _no_leftovers(directory)
    return messages


def _no_leftovers(directory: Path) -> None:
    assert not multiprocessing.active_children()
    assert not [p.name for p in directory.iterdir() if p.suffix == ".mcap" or ".part-" in p.name]


def _damage(path: Path, every: int, garbage: bytes) -> None:
    """Overwrite a few bytes every `every` bytes, and cut the file short in its last record."""
    data = bytearray(path.read_bytes())
    for at in range(every // 2, len(data) - len(garbage), every):
        data[at:at + len(garbage)] = garbage
    path.write_bytes(bytes(data[: len(data) - 37]))


def _diagnostics(path: Path) -> list[tuple[int, str, int, str]]:
    with ArchiveReader(path) as r:
        return [(m.log_time_ns, m.message.file, m.message.line, m.message.message)
                for m in r.messages() if m.topic == "/diagnostics"]


def test_sample_trial_archive_is_byte_identical_for_any_worker_count(tmp_path):
    manifest = load_manifest(SAMPLE / "trial.toml")
    serial = record(manifest, tmp_path / "serial.mcap", workers=1)
    two = record(manifest, tmp_path / "two.mcap", workers=2)
    three = record(manifest, tmp_path / "three.mcap", workers=3)  # more workers than cores, uneven shares
    assert (serial.workers, two.workers, three.workers) == (1, 2, 3)
    data = (tmp_path / "serial.mcap").read_bytes()
    assert len(data) > 1_000_000
    assert (tmp_path / "two.mcap").read_bytes() == data
    assert (tmp_path / "three.mcap").read_bytes() == data
    assert two.files == serial.files and len(serial.files) == 20
    assert sum(f.messages for f in two.files) == sum(f.messages for f in serial.files) > 20_000


def test_damaged_logs_give_the_same_diagnostics_and_summary(tmp_path):
    trial = tmp_path / "trial"
    shutil.copytree(SAMPLE, trial)
    _damage(trial / "leader1" / "gps.log", 5_000, b"$GP*ZZ")
    _damage(trial / "follower" / "dvl.pd0", 7_000, b"\x7f\x7f\x00\x01")
    _damage(trial / "follower" / "modem.log", 3_000, b"\n#!garbage\n")
    _damage(trial / "buoy1" / "usbl.log", 4_000, b"USBLLONG,x")
    manifest = load_manifest(trial / "trial.toml")
    serial = record(manifest, tmp_path / "serial.mcap", workers=1)
    parallel = record(manifest, tmp_path / "parallel.mcap", workers=2)
    assert parallel.workers == 2
    assert parallel.files == serial.files
    damaged = {f.path: f.skipped for f in serial.files if f.skipped}
    assert set(damaged) >= {"leader1/gps.log", "follower/dvl.pd0", "follower/modem.log", "buoy1/usbl.log"}
    assert sum(f.bad_checksum for f in serial.files) > 0
    diags = _diagnostics(tmp_path / "serial.mcap")
    assert len(diags) == serial.skipped and {d[1] for d in diags} == set(damaged)
    assert _diagnostics(tmp_path / "parallel.mcap") == diags
    assert (tmp_path / "parallel.mcap").read_bytes() == (tmp_path / "serial.mcap").read_bytes()


def test_a_log_that_cannot_be_decoded_gives_the_serial_message(tmp_path):
    manifest = load_manifest(_csv_trial(tmp_path, time_format="fortnights"))
    messages = _errors_serial_and_parallel(manifest, tmp_path)
    assert messages[0] == messages[1]
    assert "range.csv" in messages[0] and "fortnights" in messages[0]


def test_an_earlier_logs_error_comes_first_though_the_main_process_failed_on_a_later_one(tmp_path, monkeypatch):
    toml = _csv_trial(tmp_path)
    (tmp_path / "late.csv").write_bytes((tmp_path / "gps.csv").read_bytes())
    toml.write_text(toml.read_text() + LATE_GPS_LOG)
    main_pid = os.getpid()

    def gps_or_late(gps, data, ctx):
        if ctx.path == "late.csv":
            raise FormatError("late broke")
        if os.getpid() == main_pid:
            time.sleep(0.3)  # the worker takes range.csv meanwhile; the main process then takes late.csv
        return gps(data, ctx)

    def modem(data, ctx):
        time.sleep(0.6 if os.getpid() != main_pid else 0)  # still at it when the main process fails on late.csv
        raise FormatError("range broke")

    _patch_converters(monkeypatch, gps_or_late, modem)
    manifest = load_manifest(toml)
    messages = _errors_serial_and_parallel(manifest, tmp_path)
    assert messages[0] == messages[1] and "range.csv" in messages[0] and "range broke" in messages[0]


def test_the_cli_gives_one_line_for_it_with_workers(tmp_path, capsys):
    _csv_trial(tmp_path, time_format="fortnights")
    assert main(["record", str(tmp_path / "trial.toml"), "-o", str(tmp_path / "t.mcap"), "--workers", "2"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fortnights" in err[0]
    _no_leftovers(tmp_path)


def _crashing_table(monkeypatch, how) -> None:
    """The converter of the modem csv log dies in the worker that runs it; the main process lets a worker take it."""
    main_pid = os.getpid()

    def slow_gps(gps, data, ctx):
        # the main process takes the first log itself; while it is on it, the worker claims the second
        if os.getpid() == main_pid:
            time.sleep(0.5)
        return gps(data, ctx)

    def modem(data, ctx):
        if os.getpid() == main_pid:
            raise AssertionError("the crashing log was decoded in the main process")
        return how()

    _patch_converters(monkeypatch, slow_gps, modem)


def _patch_converters(monkeypatch, gps, modem) -> None:
    """Record through `gps(real_gps_converter, data, ctx)` for csv GPS logs and `modem(data, ctx)` for csv modem logs."""
    real, real_blocks = rec.converters, rec.block_converters

    def table():
        t = real()
        real_gps = t[("gps", "csv")]
        t[("gps", "csv")] = lambda data, ctx: gps(real_gps, data, ctx)
        t[("modem", "csv")] = modem
        return t

    def block_table():  # csv logs are read in blocks: the same functions over them
        t = real_blocks()
        t[("gps", "csv")] = blockwise(lambda data, ctx: gps(csvlog.converter_for("gps"), data, ctx))
        t[("modem", "csv")] = blockwise(modem)
        return t

    monkeypatch.setattr(rec, "converters", table)
    monkeypatch.setattr(rec, "block_converters", block_table)


@pytest.mark.parametrize("how, words", [
    (lambda: os.kill(os.getpid(), signal.SIGKILL), "was killed by SIGKILL"),
    (lambda: os._exit(3), "exited with status 3"),
])
def test_a_worker_that_dies_is_a_clear_error_naming_its_log(tmp_path, monkeypatch, how, words):
    manifest = load_manifest(_csv_trial(tmp_path))
    _crashing_table(monkeypatch, how)
    with pytest.raises(ManifestError) as err:
        record(manifest, tmp_path / "t.mcap", workers=2)
    assert str(err.value) == f"range.csv: the worker process decoding it {words}"
    _no_leftovers(tmp_path)


def test_an_exception_in_a_worker_is_raised_as_itself(tmp_path, monkeypatch):
    manifest = load_manifest(_csv_trial(tmp_path))

    def boom():
        raise ZeroDivisionError("no range")

    _crashing_table(monkeypatch, boom)
    with pytest.raises(ZeroDivisionError, match="no range") as err:
        record(manifest, tmp_path / "t.mcap", workers=2)
    assert any("in a worker process" in note for note in err.value.__notes__)
    _no_leftovers(tmp_path)


def test_an_interrupt_stops_the_workers_and_leaves_no_file(tmp_path):
    manifest = load_manifest(SAMPLE / "trial.toml")
    seen = []

    def progress(name: str, done: int, total: int) -> None:
        seen.append(name)
        if len(seen) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        record(manifest, tmp_path / "t.mcap", progress=progress, workers=2)
    _no_leftovers(tmp_path)


def test_progress_reports_every_file_in_order(tmp_path):
    manifest = load_manifest(SAMPLE / "trial.toml")
    seen = []
    record(manifest, tmp_path / "t.mcap", progress=lambda n, d, t: seen.append((n, d == t)), workers=2)
    assert [n for n, done in seen if done] == [log.path for log in manifest.logs()]


def test_automatic_mode_stays_in_process_for_a_tiny_trial(tmp_path, monkeypatch):
    monkeypatch.setattr(rec, "available_cores", lambda: 8)
    monkeypatch.setattr(rec, "only_thread", lambda: True)  # earlier tests may leave threads behind
    tiny = load_manifest(_csv_trial(tmp_path))
    assert resolve_workers(tiny) == 1
    assert record(tiny, tmp_path / "t.mcap").workers == 1
    sample = load_manifest(SAMPLE / "trial.toml")
    assert resolve_workers(sample) == 8  # 4 MB over 20 logs: one worker per core
    assert resolve_workers(sample, workers=50) == 20  # never more workers than logs
    monkeypatch.setattr(rec, "available_cores", lambda: 1)
    assert resolve_workers(sample) == 1
    with pytest.raises(ValueError):
        resolve_workers(sample, workers=0)


def test_cli_workers_flag(tmp_path, capsys):
    toml = _csv_trial(tmp_path)
    assert main(["record", str(toml), "-o", str(tmp_path / "a.mcap"), "--quiet", "--workers", "2"]) == 0
    assert main(["record", str(toml), "-o", str(tmp_path / "b.mcap"), "--quiet", "--workers", "1"]) == 0
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()
    with pytest.raises(SystemExit):
        main(["record", str(toml), "-o", str(tmp_path / "c.mcap"), "--workers", "0"])
    assert "at least 1" in capsys.readouterr().err


def test_automatic_mode_stays_in_process_beside_other_threads(monkeypatch):
    monkeypatch.setattr(rec, "available_cores", lambda: 8)
    sample = load_manifest(SAMPLE / "trial.toml")
    monkeypatch.setattr(rec, "only_thread", lambda: False)
    assert resolve_workers(sample) == 1
    assert resolve_workers(sample, workers=2) == 2  # asked for: the caller knows its threads


def test_inside_a_daemonic_worker_recording_stays_in_process(tmp_path):
    manifest = load_manifest(SAMPLE / "trial.toml")
    with multiprocessing.get_context("fork").Pool(1) as pool:  # pool workers are daemonic
        used = pool.apply(_record_in_child, (manifest, tmp_path / "t.mcap"))
    assert used == 1 and (tmp_path / "t.mcap").stat().st_size > 1_000_000


def _record_in_child(manifest, out: Path) -> int:
    return record(manifest, out, workers=2).workers


def _big(task: int) -> bytes:
    return bytes([task]) * (4 << 20)


def test_a_worker_hands_over_big_results_without_waiting_for_the_main_process():
    with rec.WorkerPool(_big, 3, 1) as pool:
        deadline = time.monotonic() + 20
        # nobody reads the results yet: through a pipe alone, the worker would block on the first 4 MiB
        while multiprocessing.active_children() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not multiprocessing.active_children()
        assert [pool.result(t)[:1] for t in range(3)] == [b"\0", b"\1", b"\2"]


def _slow_square(task: int) -> int:
    time.sleep(0.002 * (task % 3))
    return task * task


def test_tasks_are_shared_in_order_between_the_caller_and_the_workers():
    claimed = []
    with rec.WorkerPool(_slow_square, 30, 2, caller_first=True) as pool:
        own = {}
        results = []
        for task in range(30):
            while task not in own and not pool.ready(task):
                mine = pool.claim()
                if mine is None:
                    break
                claimed.append(mine)
                own[mine] = _slow_square(mine)
            results.append(own.pop(task) if task in own else pool.result(task))
        assert pool.claim() is None
    assert results == [t * t for t in range(30)]
    assert claimed[0] == 0 and claimed == sorted(claimed)  # caller_first, then in increasing order
    assert not multiprocessing.active_children()
