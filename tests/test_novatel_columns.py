"""NovAtel column path (`formats.novatel.columns`, the column batches of `recorders.gps` and `recorders.ins`) judged
by the per-line path (`novatel.scan`, the row batches) on clean and damaged files."""

from __future__ import annotations

import math
from unittest import mock

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import gpstime
from formats.novatel import columns as novatel_columns
from formats.novatel import logs as nv
from formats.novatel import scan as novatel_scan
from formats.records import Reject
from formats.units import NS as S1
from recorders import base, gps, ins, novatel_epochs
from recorders.base import Batch, LogContext
from tests.test_novatel_scan import _comparable, _outputs, assert_batch_is_its_items

T0 = 1476259201_250_000_000  # 2016-10-12T08:00:01.25Z

_CLEAN = [
    lambda t, k: nv.encode_bestposa(t, 45.7 + k * 1e-7, 126.6, 120.0 + k, undulation_m=-8.0, sequence=k),
    lambda t, k: nv.encode_bestposa(t, -45.7, -126.6, 12.0, undulation_m=math.nan),
    lambda t, k: nv.encode_bestposa(t, 1.0, 2.0, 3.0, solution_status="INSUFFICIENT_OBS", position_type="NONE"),
    lambda t, k: nv.encode_bestvela(t, 1.5 + k * 0.01, 45.0 + k),
    lambda t, k: nv.encode_bestvela(t, 1.5, 45.0, solution_status="COLD_START"),
    lambda t, k: nv.encode_inspvaa(t, 45.7, 126.6, -10.0, 0.1, 0.2, -0.0, 1.0, 2.0, 93.0 + k),
    lambda t, k: nv.encode_inspvaxa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, 93.0, undulation_m=-8.0),
    lambda t, k: nv.encode_inspvaxa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, 93.0, undulation_m=math.nan,
                                    position_type="INS_SOLUTION_GOOD"),
]


def _resigned(line: str, at: int, text: str, cut: int) -> str:
    """The line with `cut` payload characters at `at` replaced by `text`, its CRC made good again."""
    star = line.rfind("*")
    payload = line[1:star]
    at %= len(payload)
    payload = payload[:at] + text + payload[at + cut:]
    return f"{line[0]}{payload}*{nv.crc32(payload.encode('latin-1')):08x}\r\n"


_DAMAGE = st.one_of(
    st.tuples(st.just("resign"), st.integers(0, 400), st.sampled_from(
        [",", ";", "*", "", "x", "0", "-", ".", '"', "A", "#", "%", "²", "nan", "inf", "1e400", " ", "_", "+",
         "99999999999999999999999", ",,", "RANGE"]), st.integers(0, 3)),
    st.tuples(st.just("crc"), st.integers(0, 7)),       # one CRC digit changed
    st.tuples(st.just("cut"), st.integers(1, 60)),      # the line truncated
    st.tuples(st.just("lf"), st.just(0)),               # LF alone
    st.tuples(st.just("blank"), st.sampled_from(["\r\n", "\n", " \r\n", "\r\r\n"])),
    st.tuples(st.just("short"), st.just(0)),            # a short header (%INSPVASA)
)


def _damaged(line: str, damage: tuple, t: int) -> str:
    kind = damage[0]
    if kind == "resign":
        return _resigned(line, damage[1], damage[2], damage[3])
    if kind == "crc":
        star = line.rfind("*") + 1 + damage[1]
        if star >= len(line):
            return line
        return line[:star] + ("0" if line[star] != "0" else "1") + line[star + 1:]
    if kind == "cut":
        return line[: max(1, len(line) - 2 - damage[1])] + "\r\n"
    if kind == "lf":
        return line.rstrip("\r\n") + "\n"
    if kind == "blank":
        return line + damage[1]
    return nv.encode_inspvaa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, 93.0, short=True)


@st.composite
def _file(draw, damaged: bool = True) -> bytes:
    t, lines = T0, []
    picks = draw(st.lists(st.tuples(st.integers(0, len(_CLEAN) - 1), st.integers(0, 2)), min_size=1, max_size=40))
    for k, (make, step) in enumerate(picks):
        t += step * S1 // 2
        lines.append(_CLEAN[make](t, k))
    if damaged:
        for at, damage in draw(st.lists(st.tuples(st.integers(0, len(lines) - 1), _DAMAGE), max_size=3)):
            lines[at] = _damaged(lines[at], damage, t)
    return "".join(lines).encode("latin-1")


def _scanned_columns(cols: novatel_columns.NovatelColumns) -> list:
    """The columns as `novatel_scan.scan`'s tuples, file order."""
    rows = {name: iter(range(len(r))) for name, r in cols.rows.items()}
    values = {name: [c.tolist() if isinstance(c, np.ndarray) else c for c in v] for name, v in cols.values.items()}
    out = []
    for i, code in enumerate(cols.code.tolist()):
        name = novatel_columns.NAMES[code]
        row = next(rows[name])
        out.append(_comparable((name, name + "A", int(cols.week[i]), float(cols.seconds[i]),
                                tuple(c[row] for c in values[name]), int(cols.offsets[i]), int(cols.numbers[i]),
                                None)))
    return out


@settings(max_examples=400, deadline=None)
@given(_file())
def test_columns_are_what_scan_gives_or_none(data: bytes) -> None:
    cols = novatel_columns.decode_columns(data)
    if cols is not None:
        scanned = list(novatel_scan.scan(data, "auto"))
        assert not any(isinstance(item, Reject) for item in scanned)
        assert _scanned_columns(cols) == [_comparable(item) for item in scanned]


@settings(max_examples=100, deadline=None)
@given(_file(damaged=False))
def test_a_clean_file_takes_the_column_path(data: bytes) -> None:
    cols = novatel_columns.decode_columns(data)
    assert cols is not None
    assert len(cols.code) == data.count(b"\n")


def _items(convert, data: bytes, ctx: LogContext, columns: bool) -> list:
    if columns:
        return list(convert(data, ctx))
    with mock.patch.object(novatel_columns, "decode_columns", lambda data, binary_checked=False: None):
        return list(convert(data, ctx))


def _same_batches(a: list, b: list) -> None:
    """Column batches equal to the row batches: order, records, times, columns (bit for bit) and items."""
    assert [type(x) for x in a] == [type(x) for x in b]
    for x, y in zip(a, b):
        if type(x) is not Batch:
            assert x == y
            continue
        assert x.one_by_one == y.one_by_one and x.where == y.where
        assert x.order.tolist() == y.order.tolist() and x.keys.tolist() == y.keys.tolist()
        assert [p.topic for p in x.parts] == [p.topic for p in y.parts]
        for p, q in zip(x.parts, y.parts):
            assert p.log_times_ns.tolist() == q.log_times_ns.tolist()
            assert p.publish_times_ns.tolist() == q.publish_times_ns.tolist()
            assert set(p.columns) == set(q.columns)
            for name, u in p.columns.items():
                v = q.columns[name]
                if isinstance(u, np.ndarray) or isinstance(v, np.ndarray):
                    u, v = np.asarray(u), np.asarray(v)
                    assert u.dtype == v.dtype and u.shape == v.shape, name
                    assert u.tobytes() == v.tobytes(), name  # NaN, -0.0: the same bits
                else:
                    assert _comparable(u) == _comparable(v), name
        assert _outputs(x.outputs()) == _outputs(y.outputs())
        if not x.one_by_one:
            assert_batch_is_its_items(x)


@settings(max_examples=300, deadline=None)
@given(_file(), st.integers(-2, 2))
def test_column_batches_are_the_row_batches(data: bytes, offset_s: int) -> None:
    ctx = LogContext("boat", clock_offset_ns=offset_s * S1, batches=True)
    for convert in (gps.convert_novatel, ins.convert_span):
        _same_batches(_items(convert, data, ctx, True), _items(convert, data, ctx, False))


@settings(max_examples=300, deadline=None)
@given(_file(), st.integers(300, 3000), st.integers(2, 6))
def test_small_blocks_and_batches_give_the_row_batches(data: bytes, block: int, rows: int) -> None:
    """Blocks of a few lines and Batches of a few messages: runs carried over block ends, a damaged block met
    after clean ones (the per-line path goes on from its start)."""
    ctx = LogContext("boat", batches=True)
    with mock.patch.object(novatel_epochs, "BLOCK_BYTES", block), mock.patch.object(base, "ROWS_PER_BATCH", rows), \
            mock.patch.object(gps, "ROWS_PER_BATCH", rows), mock.patch.object(ins, "ROWS_PER_BATCH", rows):
        for convert in (gps.convert_novatel, ins.convert_span):
            _same_batches(_items(convert, data, ctx, True), _items(convert, data, ctx, False))


def test_a_long_clean_log_takes_the_column_path_in_batches_of_bounded_size() -> None:
    lines = []
    for k in range(700):
        t = T0 + k * S1
        lines += [nv.encode_bestposa(t, 45.7 + k * 1e-6, 126.6, 120.0 + k, undulation_m=-8.0),
                  nv.encode_bestvela(t, 1.5, 45.0 + k % 360),
                  nv.encode_inspvaxa(t, 45.7, 126.6, -10.0, 0.1, 0.2, 0.0, 1.0, 2.0, k % 360)]
    data = "".join(lines).encode()
    ctx = LogContext("boat", batches=True)
    with mock.patch.object(gps, "_NovatelRows", None), mock.patch.object(ins, "ins_rows", None):
        fast = {c: _items(c, data, ctx, True) for c in (gps.convert_novatel, ins.convert_span)}  # no row path here
    assert [len(b.order) for b in fast[gps.convert_novatel]] == [1026, 1026, 48]  # 3 messages an epoch
    assert [len(b.order) for b in fast[ins.convert_span]] == [700]
    for convert, items in fast.items():
        _same_batches(items, _items(convert, data, ctx, False))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([1, 1917, 1918, 1930, 2086, 5000]),
                          st.one_of(st.floats(-100.0, 605000.0), st.sampled_from([0.0, 604799.9995, 0.0005]))),
                min_size=1, max_size=30))
def test_gps_time_column_is_the_per_time_conversion(times: list[tuple[int, float]]) -> None:
    weeks = np.array([w for w, _ in times], dtype=np.int64)
    seconds = np.array([s for _, s in times], dtype=np.float64)
    column = gpstime.gps_to_unix_ns_column(weeks, seconds)
    assert column is not None
    assert column.tolist() == [gpstime.gps_to_unix_ns(w, s) for w, s in times]
