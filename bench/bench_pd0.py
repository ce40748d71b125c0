"""PD0 decoding throughput (ensembles/s): formats.pd0 against dolfyn, same file, same run.

Builds N WorkHorse-style ensembles (fixed + variable leader, a water profile
of C cells, bottom track; default N=20000, C=20), then times, as medians of
repeats: our decoder (bottom track only), our decoder with the water
profile, the recorder's block scan (`pd0_blocks.scan`: runs of like
ensembles as numpy columns), the whole DVL converter (protobuf messages
included) and its record-based reference, and dolfyn's RDI reader (`dolfyn.io.rdi.read_rdi`) in its own
environment bench/.venv-dolfyn (dolfyn needs numpy < 2; built by
bench/make_dolfyn_venv.sh, which this script runs when the venv is missing).
dolfyn runs in a subprocess and reports its own timing, so interpreter
start-up is not counted against it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from common import median_time, print_table

from formats.pd0 import blocks as pd0_blocks
from formats.pd0 import ensembles as pd0
from recorders.base import LogContext
from recorders.dvl import convert_pd0
from tests.reference_converters import convert_pd0_reference

T0 = 1_476_259_200_000_000_000
DOLFYN_PY = HERE / ".venv-dolfyn" / "bin" / "python"

DOLFYN_TIMER = r"""
import contextlib, io, json, statistics, sys, time, warnings
warnings.simplefilter("ignore")
from dolfyn.io.rdi import read_rdi
path, repeats = sys.argv[1], int(sys.argv[2])
times, n = [], 0
for _ in range(repeats):
    t = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        ds = read_rdi(path)
    times.append(time.perf_counter() - t)
    n = int(ds.sizes["time"])
print(json.dumps({"seconds": statistics.median(times), "ensembles": n}))
"""


def build_file(n: int, cells: int, seed: int = 1) -> bytes:
    """N ensembles with a profile of `cells` cells; WorkHorse firmware 16.30 for dolfyn."""
    rng = np.random.default_rng(seed)
    fixed = pd0.encode_fixed(n_cells=cells, firmware=(16, 30))
    vel = rng.normal(0.0, 1.0, (n, 4))
    rngs = rng.uniform(5.0, 50.0, (n, 4))
    prof = rng.normal(0.0, 0.3, (n, cells, 4))
    parts = []
    for k in range(n):
        var = pd0.encode_variable(T0 + k * 200_000_000, k + 1, heading_deg=float(k % 360))
        types = [fixed, var, pd0.encode_profile(prof[k]), pd0.encode_bottom(vel[k], rngs[k])]
        parts.append(pd0.assemble(types))
    return b"".join(parts)


def ours(data: bytes, profiles: bool) -> int:
    """Ensembles decoded by formats.pd0."""
    return sum(isinstance(r, pd0.Ensemble) for r in pd0.decode(data, profiles=profiles))


def ours_blocks(data: bytes) -> int:
    """Ensembles in the blocks of formats.pd0_blocks.scan."""
    return sum(len(b.offsets) for b in pd0_blocks.scan(data) if isinstance(b, pd0_blocks.Block))


def ours_recorder(data: bytes, convert=convert_pd0) -> int:
    """DvlVelocity messages built by recorders.dvl.convert_pd0 (or its reference)."""
    return sum(1 for _ in convert(data, LogContext("follower")))


def dolfyn(path: Path, repeats: int) -> tuple[float, int] | None:
    """(median seconds, ensembles) for dolfyn's reader, or None when it cannot run here."""
    if not DOLFYN_PY.exists():
        subprocess.run(["bash", str(HERE / "make_dolfyn_venv.sh")], check=False)
    if not DOLFYN_PY.exists():
        return None
    res = subprocess.run([str(DOLFYN_PY), "-c", DOLFYN_TIMER, str(path), str(repeats)],
                         capture_output=True, text=True, check=False)
    if res.returncode != 0:
        print(res.stderr[-2000:], file=sys.stderr)
        return None
    out = json.loads(res.stdout.strip().splitlines()[-1])
    return out["seconds"], out["ensembles"]


def main(argv: list[str] | None = None) -> int:
    """Run the comparison and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=20000, help="ensembles")
    ap.add_argument("--cells", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    data = build_file(args.n, args.cells)
    rows = []
    for name, fn in (("formats.pd0 (bottom track)", lambda: ours(data, False)),
                     ("formats.pd0 (+ water profile)", lambda: ours(data, True)),
                     ("formats.pd0_blocks.scan", lambda: ours_blocks(data)),
                     ("recorders.dvl convert_pd0", lambda: ours_recorder(data)),
                     ("tests.reference_converters convert_pd0_reference",
                      lambda: ours_recorder(data, convert_pd0_reference))):
        assert fn() == args.n
        rows.append([name, args.n / median_time(fn, args.repeats)])
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.000"
        path.write_bytes(data)
        ref = dolfyn(path, args.repeats)
    if ref is not None:
        seconds, count = ref
        rows.append([f"dolfyn 1.3 read_rdi ({count} ens)", count / seconds])
        base = rows[-1][1]
    else:
        base = float("nan")
        print("dolfyn unavailable: see bench/make_dolfyn_venv.sh", file=sys.stderr)
    table = [[name, rate, rate / base] for name, rate in rows]
    print_table(f"PD0 decoding, {args.n} ensembles x {args.cells} cells, {len(data) / 1e6:.1f} MB",
                ["reader", "ensembles/s", "x dolfyn"], table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
