"""PD0 fast path: `pd0_blocks.scan` against `pd0.decode`, `convert_pd0` against its record-based reference."""

from __future__ import annotations

import math
import struct

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from formats.pd0 import blocks as pd0_blocks
from formats.pd0 import ensembles as pd0
from formats.records import Reject
from formats.units import NS as S1
from recorders import dvl
from recorders.base import LogContext, Output
from tests import reference_converters as reference

T0 = 1476259201_250_000_000  # 2016-10-12T08:00:01.25Z


def _rows(items: list) -> list:
    """Scanned items as decode's (offset, number, time, bottom velocity, range) per ensemble, rejects as they are."""
    out: list = []
    for item in items:
        if isinstance(item, pd0_blocks.Block):
            n = len(item.offsets)
            vel = item.velocity_mps.tolist() if item.velocity_mps is not None else [None] * n
            rng = item.range_m.tolist() if item.range_m is not None else [None] * n
            for k, off in enumerate(item.offsets):
                number = item.numbers[k] if item.numbers is not None else None
                t = item.time_ns[k] if item.time_ns is not None else None
                extra = (item.sound_speed_mps[k], item.temperature_c[k]) if item.numbers is not None else None
                out.append((off, item.fixed, number, t, extra, _nan_safe(vel[k]), _nan_safe(rng[k])))
        elif isinstance(item, pd0.Ensemble):
            out.append(_ensemble_row(item))
        else:
            out.append(item)
    return out


def _ensemble_row(e: pd0.Ensemble) -> tuple:
    v, bt = e.variable, e.bottom_track
    return (e.where.offset, e.fixed, v.ensemble_number if v else None, e.time_ns,
            (v.sound_speed_mps, v.temperature_c) if v else None,
            _nan_safe(list(bt.velocity_mps)) if bt else None, _nan_safe(list(bt.range_m)) if bt else None)


def _nan_safe(values: list | None) -> list | None:
    return None if values is None else [("nan", math.copysign(1, x)) if x != x else x for x in values]


def _reference_rows(data: bytes) -> list:
    return [r if isinstance(r, Reject) else _ensemble_row(r) for r in pd0.decode(data)]


def _outputs(items) -> list:
    return [(o.topic, o.log_time_ns, o.publish_time_ns, o.where, o.message.SerializeToString())
            if isinstance(o, Output) else o for o in items]


def _ensemble(k: int, kind: int, coords: str, bad: bool) -> list[bytes]:
    """Data types of ensemble k; `kind` picks a layout, `bad` a bad bottom velocity and a missing range."""
    vel = (0.1 * k, -1.5, 0.02, math.nan if bad else 0.01)
    rng = (10.0, 10.5, math.nan if bad else 9.5, 655.37 + k)
    t = T0 + k * S1 // 5
    fixed = pd0.encode_fixed(coordinates=coords, beam_angle_deg=20 if kind == 4 else 30, serial_number=kind)
    var = pd0.encode_variable(t, k + 65530, y2k=kind != 1, temperature_c=-1.5 + k, sound_speed_mps=1480 + k)
    bottom = pd0.encode_bottom(vel, rng, msb=kind != 2)
    if kind == 3:
        return [var, bottom]  # no fixed leader: the last one applies
    if kind == 5:
        return [fixed, var]  # no bottom track
    if kind == 6:
        return [fixed, var, bottom, b"\x00\x20" + bytes(10)]  # a vendor type after the bottom track
    if kind == 7:
        return [fixed, var[:40], bottom]  # variable leader cut before the pressure
    return [fixed, var, bottom]


def _tweak(types: list[bytes], where: int, value: int) -> bytes:
    """The ensemble with one body byte set (checksum recomputed): odd leaders, bad RTCs, broken offsets."""
    body = bytearray(pd0.assemble(types)[:-2])
    body[where % len(body)] = value
    return bytes(body) + struct.pack("<H", pd0.checksum(bytes(body)))


_ENSEMBLE = st.tuples(st.integers(0, 7), st.sampled_from(["ship", "earth", "instrument", "beam"]), st.booleans(),
                      st.one_of(st.none(), st.tuples(st.integers(0, 400), st.integers(0, 255))))
_DAMAGE = st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255), st.booleans()), max_size=4)


def _build(parts: list, damage: list) -> bytes:
    blobs = []
    for k, (kind, coords, bad, tweak) in enumerate(parts):
        types = _ensemble(k, kind, coords, bad)
        blobs.append(_tweak(types, *tweak) if tweak else pd0.assemble(types))
    data = bytearray(b"".join(blobs))
    for pos, value, insert in damage:  # checksums not fixed: noise, bad ensembles, resyncs
        if data:
            if insert:
                data[pos % len(data) : pos % len(data)] = bytes([value, 0x7F, 0x7F][: 1 + value % 3])
            else:
                data[pos % len(data)] = value
    return bytes(data)


@settings(max_examples=200, deadline=None)
@given(st.lists(_ENSEMBLE, max_size=12), _DAMAGE, st.integers(0, 3))
def test_scan_gives_what_decode_gives(parts, damage, cut) -> None:
    data = _build(parts, damage)
    data = data[: len(data) - cut]
    assert _rows(list(pd0_blocks.scan(data))) == _reference_rows(data)


# the Y2K RTC's year byte (body byte 129 of a kind-0 ensemble) set to 200 dates it 2200-10-12, no archivable
# time: the block path set its Timestamp, the reference left it unset (found by a random hypothesis run)
_DATED_2200 = [(0, "ship", False, (71 + 58, 200))]


@settings(max_examples=200, deadline=None)
@given(st.lists(_ENSEMBLE, max_size=12), _DAMAGE, st.integers(-2, 2),
       st.sampled_from([{}, {"beam_angle_deg": 25.0}]))
@example(_DATED_2200, [], 0, {})
@example(_DATED_2200 + [(1, "ship", False, None)], [], -2, {})
def test_fast_pd0_path_equals_the_record_based_reference(parts, damage, offset_s, options) -> None:
    data = _build(parts, damage)
    ctx = LogContext("follower", clock_offset_ns=offset_s * S1, options=options)
    assert _outputs(dvl.convert_pd0(data, ctx)) == _outputs(reference.convert_pd0_reference(data, ctx))


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600))
def test_any_bytes_scan_as_decode_does(data: bytes) -> None:
    good = pd0.assemble(_ensemble(0, 0, "ship", False))
    for blob in (data, good + data, data + good + good, good + data[:3] + good):
        assert _rows(list(pd0_blocks.scan(blob))) == _reference_rows(blob)
        ctx = LogContext("follower")
        assert _outputs(dvl.convert_pd0(blob, ctx)) == _outputs(reference.convert_pd0_reference(blob, ctx))


def test_an_ensemble_dated_2200_has_no_timestamp_on_either_path() -> None:
    data = _build(_DATED_2200, [])
    (ensemble,) = pd0.decode(data)
    assert isinstance(ensemble, pd0.Ensemble) and ensemble.variable is not None
    assert ensemble.variable.y2k_rtc is not None and ensemble.variable.y2k_rtc[:2] == (20, 200)
    ctx = LogContext("follower")
    for out in (next(dvl.convert_pd0(data, ctx)), next(reference.convert_pd0_reference(data, ctx))):
        assert isinstance(out, Output) and out.log_time_ns == 7_282_684_801_250_000_000  # 2200-10-12T08:00:01.25Z
        assert not out.message.HasField("timestamp")


def test_a_clean_deployment_is_one_block() -> None:
    data = b"".join(pd0.assemble(_ensemble(k, 0, "ship", k % 3 == 0)) for k in range(50))
    (block,) = pd0_blocks.scan(data)
    assert isinstance(block, pd0_blocks.Block) and len(block.offsets) == 50
    assert block.numbers[:2] == [65530, 65531] and block.time_ns[1] == T0 + S1 // 5


def test_rtc_seconds_match_datetime_on_every_kind_of_date() -> None:
    cases = [(2016, 2, 29), (2015, 2, 29), (2000, 2, 29), (2100, 2, 29), (2016, 13, 1), (2016, 0, 1),
             (2016, 4, 31), (2016, 12, 31), (1980, 1, 1), (2355, 12, 31)]
    for (y, mo, d) in cases:
        for clock in ((0, 0, 0, 0), (23, 59, 59, 99), (24, 0, 0, 0), (0, 60, 0, 0), (0, 0, 60, 0), (0, 0, 0, 100)):
            secs, ok = pd0_blocks.rtc_seconds(*(np.array([v]) for v in (y, mo, d, *clock)))
            want = pd0.rtc_to_ns(y, mo, d, *clock)
            assert bool(ok[0]) == (want is not None)
            if want is not None:
                assert int(secs[0]) * S1 + clock[3] * 10_000_000 == want


_CLOCK_BYTE = st.sampled_from([0, 1, 2, 12, 13, 18, 19, 20, 21, 22, 23, 28, 29, 30, 31, 59, 60, 79, 80, 99, 100, 255])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.lists(_CLOCK_BYTE, min_size=15, max_size=15), st.booleans(), st.booleans()),
                min_size=1, max_size=6))
def test_every_clock_reading_times_as_decode_does(clocks) -> None:
    blobs = []
    for k, (clock, y2k, century_only) in enumerate(clocks):
        var = bytearray(pd0.encode_variable(T0, k, y2k=y2k))
        var[4:11] = bytes(clock[:7])
        if y2k:  # a whole odd Y2K clock, or a good date under an odd century
            var[57 : 58 if century_only else 65] = bytes(clock[7 : 8 if century_only else 15])
        blobs.append(pd0.assemble([pd0.encode_fixed(), bytes(var), pd0.encode_bottom((0.0,) * 4, (1.0,) * 4)]))
    data = b"".join(blobs)
    assert _rows(list(pd0_blocks.scan(data))) == _reference_rows(data)
