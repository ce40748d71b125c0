"""Prints dolfyn's reading of the real PD0 fixtures (run with bench/.venv-dolfyn/bin/python).

The numbers in tests/test_real_vendor_files.py were copied from this output.
dolfyn 1.3.0 cannot read these files as they are, for two reasons that are
quirks of the files and not of our decoder:

* it needs several ensembles to measure the ensemble spacing, and each file
  holds one: the ensemble (header to checksum) is repeated four times;
* it indexes ['real', 'simulated'] with fixed-leader byte 6, which is 8 in
  C12AN_90.PD0 (WorkHorse firmware 50.40): the byte is set to 0 (and the
  checksum recomputed) in the copy given to dolfyn (a no-op for 1407E0CA.PD0).
"""

import struct
import sys
import tempfile
from pathlib import Path

import dolfyn
import numpy as np

HERE = Path(__file__).parent
CELLS = (0, 1, 24, 43, 44, 49)


def dolfyn_copy(raw: bytes) -> bytes:
    """Header-to-checksum ensemble with the sim flag cleared, four times."""
    nbytes = struct.unpack_from("<H", raw, 2)[0]
    ens = bytearray(raw[: nbytes + 2])
    fixed = struct.unpack_from("<H", ens, 6)[0]
    ens[fixed + 6] = 0
    struct.pack_into("<H", ens, nbytes, sum(ens[:nbytes]) & 0xFFFF)
    return bytes(ens) * 4


def main() -> None:
    np.set_printoptions(precision=6, floatmode="maxprec", linewidth=150)
    print("dolfyn", dolfyn.__version__, file=sys.stderr)
    for name in ("C12AN_90.PD0", "1407E0CA.PD0"):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / name
            path.write_bytes(dolfyn_copy((HERE / name).read_bytes()))
            ds = dolfyn.read(str(path))
        print("==", name)
        print("time", ds.time.values[0])
        for var in ("number", "heading", "pitch", "roll", "temp", "c_sound", "depth", "pressure"):
            if var in ds:
                print(var, repr(float(ds[var].values[0])))
        for att in ("coord_sys", "beam_angle", "freq", "n_cells", "cell_size", "bin1_dist_m",
                    "blank_dist", "pings_per_ensemble", "serialnum", "prog_ver", "orientation",
                    "beam_pattern", "magnetic_var_deg"):
            print(att, repr(ds.attrs[att]))
        print("range", ds.range.values[[0, -1]])
        for c in CELLS:
            print("vel cell", c, ds.vel.values[:, c, 0].tolist())
        print("nan cells", np.argwhere(np.isnan(ds.vel.values[:, :, 0])).tolist())


if __name__ == "__main__":
    main()
