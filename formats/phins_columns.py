"""PHINS standard lines of a clean block as numpy columns (the block fast path of `phins.scan`).

`decode_columns` gives, for a block whose every line is a clean sentence
(`formats.nmea.clean`: ``$ADDRS,...*HH``, one '$', checksum right), the
sentences `phins.scan` would give as values, one array per field and kind,
with each sentence's epoch key in file order. Every sentence of a kind must
have that kind's usual number of fields, every value must be one the
per-sentence parsers read without a doubt (`formats.nmea.fields`' column
helpers: Python's own `float` and `int` on the same strings), and every
POSITI in range; any other block gets None, and the caller takes the per-line
path, which decides every kind of damage. Sentences `scan` skips (other
$PIXSE names, other addresses) are dropped here too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .nmea.clean import clean_lines, field_table, select
from .nmea.fields import NAN, number_column, tod_column
from .numbers import integer
from .phins import PIXSE, wrap_longitude

# epoch keys (`phins.scan`'s first value) by code
KEYS = ("Heading", "Atitud", "Positi", "Speed", "Utmwgs", "Heave", "Time", "StdHrp", "StdPos", "StdSpd",
        "ALGSTS", "STATUS", "HT_STS", "Phtro")
_CODE = {key: code for code, key in enumerate(KEYS)}
_PIXSE_CODE = {name.encode("ascii"): _CODE[key] for name, (key, _) in PIXSE.items()}
# fields of a line with its address (and $PIXSE's name) and its checksum, as `field_table` counts them
_WIDTH = {"Heading": 4, "Atitud": 5, "Positi": 6, "Speed": 6, "Utmwgs": 8, "Heave": 6, "Time": 4, "StdHrp": 6,
          "StdPos": 6, "StdSpd": 6, "ALGSTS": 5, "STATUS": 5, "HT_STS": 4, "Phtro": 6}
# the value fields of each kind after the address (and name), in the record's order (`phins.scan`'s values)
_NUMBERS = {"Atitud": ("roll_port_up_deg", "pitch_bow_down_deg"),
            "Positi": ("latitude", "longitude", "altitude_m"), "Speed": ("east_mps", "north_mps", "up_mps"),
            "Heave": ("surge_m", "sway_m", "heave_m"),
            "StdHrp": ("heading_std_deg", "roll_std_deg", "pitch_std_deg"),
            "StdPos": ("lat_std_m", "lon_std_m", "altitude_std_m"),
            "StdSpd": ("east_std_mps", "north_std_mps", "up_std_mps")}


@dataclass(frozen=True, slots=True)
class PhinsColumns:
    """A clean block's PHINS sentences in file order: epoch key code, byte offset, line number; values per key."""

    key: np.ndarray      # index into KEYS
    offsets: np.ndarray  # byte offset of each sentence in the block
    numbers: np.ndarray  # 1-based line number of each sentence in the block
    rows: dict[str, np.ndarray]  # key -> its sentences' positions in file order
    values: dict[str, dict[str, np.ndarray | list]]  # key -> field name -> one value per sentence


def _codes(heads: np.ndarray) -> np.ndarray | None:
    """Epoch key code per line from the 13 bytes after its '$' (-1: a sentence `scan` skips), or None when a line
    needs the per-line path (an address of another length, or malformed, or a known one without fields)."""
    keys, inverse = np.unique(heads, return_inverse=True)
    code_of = np.full(len(keys), -1, dtype=np.int64)
    for j, key in enumerate(keys.tolist()):
        address = key[:5].decode("latin-1")
        if key[5:6] != b"," or not (address.isascii() and address.isalnum() and address.isupper()):
            return None
        if address == "PIXSE":
            code = _PIXSE_CODE.get(key[6:12])
            if code is not None and key[12:13] != b",":
                return None  # "ATITUD*..." or "ATITUDX": the per-line path reads or skips it
            code_of[j] = -1 if code is None else code
        elif address == "PHTRO":
            code_of[j] = _CODE["Phtro"]
        elif address[0] != "P" and address.endswith(("HDT", "THS")):
            code_of[j] = _CODE["Heading"]
    return code_of[inverse.ravel()]


def _numbers(fields: list[list[str]], names: tuple[str, ...]) -> dict | None:
    """Float columns of the number rule (NaN when empty), or None where it might refuse one."""
    cols = {name: number_column(float, fields[k], NAN) for k, name in enumerate(names)}
    if any(v is None for v in cols.values()):
        return None
    return {k: np.array(v, dtype=np.float64) for k, v in cols.items()}


def _words(fields: list[list[str]], two: bool) -> dict | None:
    """Status words as `phins._words` reads them (hex, at most 18 digits); None where it might refuse one."""
    first, second = fields[0], fields[1] if two else []
    distinct = set(first) | set(second)
    if "" in first:  # no first word: `phins._words` refuses the sentence
        return None
    try:  # the very rule, once per distinct string: a log repeats a handful of words
        table = {s: integer(s, "status word", 16) if s else 0 for s in distinct}
    except ValueError:
        return None
    return {"lsb": [table[s] for s in first], "msb": [table[s] for s in second] if two else [0] * len(first)}


def _values(key: str, f: list[list[str]]) -> dict | None:
    """One kind's value columns from its field columns (address first), or None for the per-line path."""
    if key == "Heading":
        heading = number_column(float, f[1], NAN)
        if heading is None:
            return None
        ths = [a.endswith("THS") for a in f[0]]
        return {"heading_deg": np.array(heading, dtype=np.float64),
                "mode": [m if t else "" for m, t in zip(f[2], ths)]}
    if key == "Time":
        tod = tod_column(f[2])
        return None if tod is None else {"time_s": tod}
    if key in ("ALGSTS", "STATUS", "HT_STS"):
        return _words(f[2:], key != "HT_STS")
    if key == "Phtro":
        if not set(f[2]) <= {"M", "P", ""} or not set(f[4]) <= {"B", "T", ""}:
            return None
        cols = _numbers([f[1], f[3]], ("pitch", "roll"))
        if cols is None:
            return None
        pitch, roll = cols["pitch"], cols["roll"]
        return {"pitch_bow_up_deg": np.where(np.array(f[2]) == "P", -pitch, pitch),
                "roll_port_up_deg": np.where(np.array(f[4]) == "B", -roll, roll)}
    if key == "Utmwgs":
        zone = number_column(int, f[3], -1)
        cols = _numbers(f[4:7], ("east_m", "north_m", "altitude_m"))
        return None if zone is None or cols is None else {"lat_zone": f[2], "lon_zone": zone, **cols}
    cols = _numbers(f[2:], _NUMBERS[key])
    if cols is None or key != "Positi":
        return cols
    lat, lon = cols["latitude"], cols["longitude"]
    if ((np.abs(lat) > 90.0) | ~((lon >= -360.0) & (lon <= 360.0))).any():  # NaN fails too, as in `_positi`
        return None
    outside = np.flatnonzero(~((lon >= -180.0) & (lon < 180.0)))
    if len(outside):  # PHINS writes 0..360: `wrap_longitude` itself, on the few that need it
        lon = lon.copy()
        lon[outside] = [wrap_longitude(x) for x in lon[outside].tolist()]
        cols["longitude"] = lon
    return cols


def decode_columns(data: bytes) -> PhinsColumns | None:
    """A clean block's PHINS sentences as columns, or None when the per-line path must decode it."""
    clean = clean_lines(data)
    if clean is None:
        return None
    heads = clean.heads(13)
    # the name after "PIXSE," tells its kind; any other line's address alone does (its values are no key)
    raw = heads.view(np.uint8).reshape(len(heads), 13)
    raw[(raw[:, :6] != np.frombuffer(b"PIXSE,", np.uint8)).any(axis=1), 6:] = 0
    code = _codes(heads)
    if code is None:
        return None
    kept = np.flatnonzero(code >= 0)
    key = code[kept]
    rows, values = {}, {}
    for c in np.unique(key).tolist():
        name = KEYS[c]
        pos = np.flatnonzero(key == c)
        table = field_table(select(clean.lines, kept[pos]), _WIDTH[name])
        cols = None if table is None else _values(name, table)
        if cols is None:
            return None
        rows[name], values[name] = pos, cols
    return PhinsColumns(key, clean.offsets[kept], clean.numbers[kept], rows, values)
