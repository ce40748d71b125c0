"""Peak memory of `auvreplay record` against the size of a log (issue 14: under 400 MB at 200 MB).

Four logs, each recorded in a fresh process at the sizes given (MB): two a
receiver could never write (GGA sentences whose checksums are all wrong,
random bytes) and two clean ones whose every record is archived (the
sample trial's NMEA GPS log and its PHINS INS log, repeated). Printed: log
size, peak RSS (VmHWM of the recording process), wall time, archive size and
the /diagnostics count; the peak should be flat in the size (the log is read
in blocks, `formats.log_blocks`, and the records parsed are counted in a
bounded window, `recorders.record.RecordCount`).

Run: .venv/bin/python bench/bench_record_memory.py [MB ...]   (default 20 200)
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from formats.mcap_reader import ArchiveReader
from tests.hostile import run_child
from tests.test_record_blocks import bad_checksums, random_bytes
from tests.test_record_blocks_text import clean_nmea, clean_phins, log_trial

KINDS = (("bad checksums", "gps", "nmea", bad_checksums), ("random bytes", "gps", "nmea", random_bytes),
         ("clean NMEA", "gps", "nmea", clean_nmea), ("clean PHINS", "ins", "phins", clean_phins))


def main(argv: list[str] | None = None) -> int:
    """Record each kind of garbage at each size; print one row each."""
    sizes = [int(a) for a in (sys.argv[1:] if argv is None else argv)] or [20, 200]
    print(f"{'log':<14} {'MB':>5} {'peak RSS MB':>12} {'wall s':>7} {'archive MB':>11} {'diagnostics':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, sensor, fmt, kind in KINDS:
            for mb in sizes:
                folder = Path(tmp) / f"{name.replace(' ', '_')}{mb}"
                manifest = log_trial(folder, sensor, fmt, kind(mb << 20))
                out = folder / "out.mcap"
                start = time.perf_counter()
                rc, err, peak = run_child("record", str(manifest), "-o", str(out), "--quiet")
                wall = time.perf_counter() - start
                if rc:
                    print(err)
                    return 1
                with ArchiveReader(out) as reader:
                    diagnostics = reader.summary().topics.get("/diagnostics", {}).get("count", 0)
                print(f"{name:<14} {mb:>5} {peak / 1024:>12.0f} {wall:>7.1f} {out.stat().st_size / 2**20:>11.1f} "
                      f"{diagnostics:>12}", flush=True)
                out.unlink()
                (folder / "sensor.log").unlink()
    return 0


if __name__ == "__main__":
    sys.exit(main())
