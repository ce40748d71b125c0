"""The PHINS block columns (formats/phins_columns.py, `recorders.ins.convert_phins`' clean-block path) give what
the record-based reference gives, on clean logs and on damaged ones, whole or cut in blocks anywhere; and a
Batch's columns encode to its messages' own bytes."""

from __future__ import annotations

from datetime import date
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import phins, phins_columns
from formats.log_blocks import LogBlocks, cut_blocks
from formats.nmea.framing import build
from formats.proto_encode import encode_columns, split
from formats.units import NS
from recorders import ins
from recorders.base import Batch, LogContext, Output, one_by_one
from tests import reference_converters as reference

ROOT = Path(__file__).resolve().parent.parent
DAY = date(2016, 10, 12)
T0 = 1476230400 * NS + 23 * 3600 * NS + 3598 * NS  # 23:59:58: bursts roll over midnight
NAN = float("nan")

_VALUE = st.one_of(st.floats(-500.0, 500.0, allow_nan=False).map(lambda x: round(x, 3)), st.just(NAN))
_WORD = st.integers(0, 2 ** 32 - 1)
# one sentence of a burst from its time (ns) and drawn values; the clean layouts the columns take, and odd ones
_SENTENCES = {
    "hdt": lambda t, v, w: phins.encode_hehdt(v[0]),
    "ths": lambda t, v, w: build("INTHS", [f"{v[0]:.2f}" if v[0] == v[0] else "", "V" if w % 2 else "A"]),
    "atitud": lambda t, v, w: phins.encode_atitud(v[0], v[1]),
    "positi": lambda t, v, w: phins.encode_positi(max(-90.0, min(90.0, v[0] / 6)), v[1] % 360.0, v[2]),
    "positi_west": lambda t, v, w: build("PIXSE", ["POSITI", "45.5", f"{-abs(v[1]) % 360.0 - 360.0:.8f}", "1.0"]),
    "speed": lambda t, v, w: phins.encode_speed(*v[:3]),
    "heave": lambda t, v, w: phins.encode_heave(*v[:3]),
    "time": lambda t, v, w: phins.encode_time(t),
    "stdhrp": lambda t, v, w: phins.encode_stdhrp(*v[:3]),
    "stdpos": lambda t, v, w: phins.encode_stdpos(*v[:3]),
    "stdspd": lambda t, v, w: phins.encode_stdspd(*v[:3]),
    "algsts": lambda t, v, w: phins.encode_status("ALGSTS", w, w >> 3),
    "status": lambda t, v, w: phins.encode_status("STATUS", w >> 5, w),
    "htsts": lambda t, v, w: phins.encode_status("HT_STS", w),
    "phtro": lambda t, v, w: phins.encode_phtro(v[0], v[1]),
    "utmwgs": lambda t, v, w: build("PIXSE", ["UTMWGS", "T", "52", "500000.0", f"{v[0]:.2f}", "-1.5"]),
    "other": lambda t, v, w: build("PIXSE", ["DEPIN_", "12.5", "020000.00"]),
    "gga": lambda t, v, w: "$GPGGA,020000.00,4542.1,N,12635.8,E,1,8,1.0,,M,,M,,*4B\r\n",
}
# damage the per-line path decides (rejects, skips, host times): the block then takes it
_DAMAGE = [
    lambda line: line[:-4] + "00\r\n",  # bad checksum
    lambda line: "garbage\x00\r\n",
    lambda line: "1476259205.000 " + line,  # host prefix
    lambda line: build("PIXSE", ["TIME__", "x"]), lambda line: build("PIXSE", ["POSITI", "1", "2"]),
    lambda line: build("PIXSE", ["POSITI", "95.0", "2.0", "3.0"]), lambda line: build("PIXSE", ["ALGSTS", "", "1"]),
    lambda line: build("PIXSE", ["SPEED_", "nan", "1", "2"]), lambda line: build("PIXSE", ["SPEED_", "1e400", "1", "2"]),
    lambda line: build("PHTRO", ["1.0", "X", "2.0", "T"]), lambda line: build("HEHDT", ["1_0.5", "T"]),
    lambda line: line.replace("\r\n", "\n"), lambda line: "\r\n", lambda line: line + line,
]


@st.composite
def logs(draw, damaged: bool) -> bytes:
    kinds = draw(st.lists(st.sampled_from(sorted(_SENTENCES)), min_size=1, max_size=6, unique=True))
    if draw(st.integers(0, 4)):  # mostly bursts with a time and a navigation sentence: the columns' case
        kinds = ["time", *(k for k in kinds if k != "time")]
        if not {"hdt", "ths", "atitud", "positi", "positi_west", "speed", "phtro"} & set(kinds):
            kinds.append(draw(st.sampled_from(["hdt", "atitud", "positi", "phtro"])))
    lines, t = [], T0
    for _ in range(draw(st.integers(0, 12))):
        t += draw(st.sampled_from([0, NS // 2, NS]))
        burst = draw(st.permutations(kinds)) if draw(st.booleans()) else kinds
        for kind in burst:
            values = [draw(_VALUE) for _ in range(3)]
            lines.append(_SENTENCES[kind](t, values, draw(_WORD)))
    if damaged and lines:
        at = draw(st.integers(0, len(lines) - 1))
        lines[at] = draw(st.sampled_from(_DAMAGE))(lines[at])
    return "".join(lines).encode("latin-1")


def _comparable(items: list) -> list:
    """Outputs and rejects as comparable values (messages as bytes: NaN != NaN)."""
    return [(o.topic, o.log_time_ns, o.publish_time_ns, o.where, o.message.SerializeToString())
            if isinstance(o, Output) else o for o in items]


def _check(data: bytes, day: date | None, offset_s: int, block_size: int) -> None:
    """Whole, in blocks (longer than any line: a longer one is cut by design) and batched, against the reference."""
    ctx = LogContext("boat", trial_date=day, clock_offset_ns=offset_s * NS)
    expected = _comparable(list(reference.convert_phins_reference(data, ctx)))
    assert _comparable(list(ins.convert_phins(data, ctx))) == expected
    blocks = LogBlocks(cut_blocks([data], block_size))
    assert _comparable(list(ins.convert_phins(blocks, ctx))) == expected
    batched = list(ins.convert_phins(data, LogContext("boat", trial_date=day, clock_offset_ns=offset_s * NS,
                                                      batches=True)))
    assert _comparable(list(one_by_one(batched))) == expected
    for batch in batched:
        if type(batch) is Batch and not batch.one_by_one:
            part = batch.parts[0]
            payloads = split(*encode_columns(part.message_class, len(part.log_times_ns), part.columns))
            assert payloads == [o.message.SerializeToString() for o in batch.outputs()]


@settings(max_examples=150, deadline=None)
@given(logs(damaged=False), st.sampled_from([DAY, DAY, DAY, None]), st.integers(-2, 2), st.integers(200, 2000))
def test_clean_logs_give_what_the_reference_gives(data, day, offset_s, block_size):
    _check(data, day, offset_s, block_size)


@settings(max_examples=150, deadline=None)
@given(logs(damaged=True), st.sampled_from([DAY, DAY, DAY, None]), st.integers(-2, 2), st.integers(200, 2000))
def test_damaged_logs_give_what_the_reference_gives(data, day, offset_s, block_size):
    _check(data, day, offset_s, block_size)


def test_the_sample_ins_logs_take_the_columns(monkeypatch):
    """The sample trial's PHINS logs are clean: decoded as columns, never line by line, and the same messages."""
    for vehicle in ("leader1", "leader2"):
        data = (ROOT / "samples" / "lake_trial" / vehicle / "ins.log").read_bytes()
        cols = phins_columns.decode_columns(data)
        assert cols is not None and len(cols.key) == data.count(b"\n")
        ctx = LogContext(vehicle, trial_date=DAY, batches=True)
        expected = _comparable(list(reference.convert_phins_reference(data, ctx)))
        with monkeypatch.context() as m:
            m.setattr(phins, "scan_block", lambda *a: pytest.fail("the per-line path"))
            items = list(ins.convert_phins(data, ctx))
        assert all(type(item) is Batch for item in items) and len(items) == 2  # 1701 bursts: 1024 + 677
        assert _comparable(list(one_by_one(items))) == expected


def test_a_line_the_columns_cannot_take_sends_the_block_line_by_line():
    line = phins.encode_speed(1.0, 2.0, 3.0)
    assert phins_columns.decode_columns(line.encode()) is not None
    for odd in (build("PIXSE", ["SPEED_", "1", "2"]), build("PIXSE", ["SPEED_", "1", "2", "3", "4"]),
                build("PIXSE", ["SPEED_", "inf", "2", "3"]), build("HEHDT", ["1.0"]), "$HEHDT*00\r\n",
                build("PIXSE", ["ATITUDE", "1", "2"]), build("hehdt", ["1.0", "T"])):
        assert phins_columns.decode_columns((line + odd).encode()) is None, odd
    cols = phins_columns.decode_columns((line + build("PIXSE", ["DEPIN_", "1"]) + build("GPZDA", ["1"])).encode())
    assert cols is not None and cols.key.tolist() == [phins_columns.KEYS.index("Speed")]
    assert np.array_equal(cols.values["Speed"]["east_mps"], [1.0])
