"""PD0 bottom track a run of ensembles at a time: what `pd0.decode` yields, as numpy columns.

A deployment writes thousands of ensembles with one layout (same size, same
offset table, same data types, the same fixed leader byte for byte). `scan`
finds each such run with one comparison over all its headers and one
checksum difference per ensemble (prefix sums of the whole file, computed
once), then reads the variable leader and bottom track of the whole run with
structured dtypes: a `Block`. Anything else -- noise, bad checksums, cut-off
ensembles, an ensemble whose layout differs from its predecessor's -- goes
through `pd0.decode`'s own per-ensemble logic, so rejects and the ensembles
around damage are exactly `decode`'s (tests/test_pd0_blocks.py checks it on
any bytes).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..records import Reject, Where
from ..units import NS
from . import ensembles as pd0

_DAYS_IN_MONTH = np.array([0, 31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31], np.int64)


@dataclass(frozen=True, slots=True)
class Block:
    """Consecutive checksum-verified ensembles sharing one layout and fixed leader, as columns.

    Row k is the ensemble at byte `offsets[k]`; `numbers` and `time_ns` are
    None per row (or the whole column None) where `pd0.decode` would give None
    (no variable leader, invalid RTC). `velocity_mps` (PD0 values, NaN bad) and
    `range_m` (vertical, NaN no bottom) are (n, 4), or None without bottom track.
    """

    offsets: list[int]
    fixed: pd0.FixedLeader | None
    numbers: list[int] | None
    time_ns: list[int | None] | None
    sound_speed_mps: list[float] | None
    temperature_c: list[float] | None
    velocity_mps: np.ndarray | None
    range_m: np.ndarray | None


def _layout(buf: bytes, i: int, nbytes: int, ndt: int) -> list[tuple[int, int, int]] | None:
    """(offset, length, type id) per data type of the ensemble at `i`, as `_parse_ensemble` reads them."""
    offsets = struct.unpack_from(f"<{ndt}H", buf, i + 6)
    ends = sorted(set(offsets) | {nbytes})
    out = []
    for off in offsets:
        if off < 6 + 2 * ndt or off + 2 > nbytes:
            return None  # malformed: `_parse_ensemble` rejects it
        out.append((off, ends[ends.index(off) + 1] - off, buf[i + off] | buf[i + off + 1] << 8))
    return out


def _run_length(buf: bytes, sums: np.ndarray, i: int, nbytes: int, ndt: int,
                layout: list[tuple[int, int, int]]) -> int:
    """How many ensembles from `i` on repeat the first one's header, type ids and fixed leader, checksums good."""
    stride = nbytes + 2
    rows = (len(buf) - i) // stride
    table = np.frombuffer(buf, np.uint8, rows * stride, i).reshape(rows, stride)
    same = (table[:, : 6 + 2 * ndt] == table[0, : 6 + 2 * ndt]).all(axis=1)
    for off, length, tid in layout:
        cols = slice(off, off + length) if tid == pd0.FIXED_ID else slice(off, off + 2)
        same &= (table[:, cols] == table[0, cols]).all(axis=1)
    starts = i + stride * np.arange(rows)
    given = table[:, nbytes].astype(np.uint16) | (table[:, nbytes + 1].astype(np.uint16) << 8)
    same &= (sums[starts + nbytes] - sums[starts]) == given  # uint16: modulo 65536 as the checksum
    bad = np.flatnonzero(~same)
    return int(bad[0]) if bad.size else rows


def _columns(buf: bytes, i: int, stride: int, rows: int, fields: dict[str, tuple[int, str]]) -> np.ndarray:
    dtype = np.dtype({"names": list(fields), "formats": [f for _, f in fields.values()],
                      "offsets": [o for o, _ in fields.values()], "itemsize": stride})
    return np.frombuffer(buf, dtype, rows, i)


def rtc_seconds(year: np.ndarray, month: np.ndarray, day: np.ndarray, hour: np.ndarray, minute: np.ndarray,
                second: np.ndarray, hundredths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(whole seconds since the epoch, valid) per RTC reading: `pd0.rtc_to_ns` over arrays."""
    y, mo, d = (np.asarray(a, np.int64) for a in (year, month, day))
    leap = (y % 4 == 0) & ((y % 100 != 0) | (y % 400 == 0))
    ok_month = (mo >= 1) & (mo <= 12)
    dim = _DAYS_IN_MONTH[np.where(ok_month, mo, 0)] + (leap & (mo == 2))
    valid = ok_month & (d >= 1) & (d <= dim) & (hour <= 23) & (minute <= 59) & (second <= 59) & (hundredths <= 99)
    days = ((y - 1970) * 12 + np.where(ok_month, mo, 1) - 1).astype("datetime64[M]").astype("datetime64[D]")
    secs = (days.astype(np.int64) + d - 1) * 86400 + hour * 3600 + minute * 60 + second.astype(np.int64)
    return secs, valid


def _variable(buf: bytes, i: int, stride: int, rows: int, off: int, length: int) -> tuple:
    """numbers, time_ns, sound speed, temperature columns of a run (`pd0.parse_variable`)."""
    if length < 28:
        return None, None, None, None
    names = ("yy", "mo", "dd", "hh", "mi", "ss", "cs")
    fields = {"lo": (off + 2, "<u2"), "hi": (off + 11, "u1"), "c": (off + 14, "<u2"), "t": (off + 26, "<i2")}
    fields.update({n: (off + 4 + k, "u1") for k, n in enumerate(names)})
    if length >= 65:
        fields.update({"y2k_" + n: (off + 58 + k, "u1") for k, n in enumerate(names)})
        fields["century"] = (off + 57, "u1")
    v = _columns(buf, i, stride, rows, fields).astype(np.dtype([(n, np.int64) for n in fields]))
    yy = v["yy"]
    secs, ok = rtc_seconds(np.where(yy < 80, 2000 + yy, 1900 + yy), *(v[n] for n in names[1:]))
    cs = v["cs"]
    if length >= 65:
        century = v["century"]
        y2k_secs, y2k_ok = rtc_seconds(century * 100 + v["y2k_yy"], *(v["y2k_" + n] for n in names[1:]))
        y2k_ok &= (century >= 19) & (century <= 21)
        secs, ok, cs = np.where(y2k_ok, y2k_secs, secs), y2k_ok | ok, np.where(y2k_ok, v["y2k_cs"], cs)
    # in Python ints: a Y2K century of 21 reaches years past int64 nanoseconds (2262)
    times = [s * NS + c * 10_000_000 if good else None for s, c, good in zip(secs.tolist(), cs.tolist(), ok.tolist())]
    numbers = (v["lo"] + 65536 * v["hi"]).tolist()
    return numbers, times, v["c"].astype(float).tolist(), (v["t"] / 100).tolist()


def _bottom(buf: bytes, i: int, stride: int, rows: int, off: int, length: int) -> tuple:
    """(velocity, range) columns of a run (`pd0.parse_bottom`)."""
    if length < 44:
        return None, None
    fields = {"r": (off + 16, "(4,)<u2"), "v": (off + 24, "(4,)<i2")}
    if length >= 81:
        fields["msb"] = (off + 77, "(4,)u1")
    b = _columns(buf, i, stride, rows, fields)
    cm = b["r"].astype(np.int64)
    if length >= 81:
        cm += b["msb"].astype(np.int64) * 65536
    raw = b["v"]
    vel = np.where(raw == pd0.BAD_VELOCITY, np.nan, raw / 1000)
    rng = np.where(cm != 0, cm / 100, np.nan)
    return vel, rng


def _block(buf: bytes, sums: np.ndarray, i: int, nbytes: int, ndt: int) -> Block | None:
    """The run of like ensembles starting with the verified one at `i`; None when its offsets are malformed."""
    layout = _layout(buf, i, nbytes, ndt)
    if layout is None:
        return None
    stride = nbytes + 2
    rows = _run_length(buf, sums, i, nbytes, ndt, layout)
    fixed = numbers = times = sound = temp = vel = rng = None
    for off, length, tid in layout:  # in table order: a repeated type overrides, as in `_parse_ensemble`
        if tid == pd0.FIXED_ID:
            fixed = pd0._fixed_cached(buf[i + off : i + off + length])
        elif tid == pd0.VARIABLE_ID:
            numbers, times, sound, temp = _variable(buf, i, stride, rows, off, length)
        elif tid == pd0.BOTTOM_ID:
            vel, rng = _bottom(buf, i, stride, rows, off, length)
    offsets = list(range(i, i + rows * stride, stride))
    return Block(offsets, fixed, numbers, times, sound, temp, vel, rng)


def scan(data: bytes) -> Iterator[Block | pd0.Ensemble | Reject]:
    """`pd0.decode(data)` (bottom track only) as runs of like ensembles; others one by one."""
    buf = bytes(data)
    sums = np.zeros(len(buf) + 1, np.uint16)
    np.cumsum(np.frombuffer(buf, np.uint8), dtype=np.uint16, out=sums[1:])  # wraps: sums modulo 65536

    def intact(i: int, nbytes: int) -> bool:
        return (int(sums[i + nbytes]) - int(sums[i])) & 0xFFFF == struct.unpack_from("<H", buf, i + nbytes)[0]

    pos = 0
    while True:
        rejects, frame = pd0.next_frame(buf, pos, intact)
        yield from rejects
        if frame is None:
            return
        i, nbytes, ndt = frame
        block = _block(buf, sums, i, nbytes, ndt)
        if block is not None:
            yield block
            pos = block.offsets[-1] + nbytes + 2
            continue
        try:
            yield pd0._parse_ensemble(buf, i, nbytes, ndt, False)
        except (struct.error, ValueError, IndexError) as exc:
            yield Reject(Where(i), f"malformed ensemble: {exc}")
        pos = i + nbytes + 2
