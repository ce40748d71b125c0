"""NMEA RMC/VTG velocity on /<v>/gps/velocity, and every sentence of a log counted by address and outcome."""

from __future__ import annotations

import json
import math
from datetime import date

from hypothesis import given, settings
from hypothesis import strategies as st

from formats.log_blocks import blocks_of
from formats.nmea import counts as C
from formats.nmea import sentences as nmea
from formats.nmea.framing import build, frame
from formats.nmea.sentences import KNOT_MPS, VALUES
from formats.units import NS
from recorders.base import Ignored, LogContext, Output
from recorders.gnss_velocity import NO_VELOCITY
from recorders.gps import convert_nmea, convert_nmea_blocks
from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from tests.reference_converters import convert_nmea_reference

T0 = 1476259200 * NS  # 2016-10-12T08:00:00Z
DAY = date(2016, 10, 12)


def _ctx() -> LogContext:
    return LogContext("boat", trial_date=DAY)


def _plain(items) -> list:
    return [(i.topic, i.message.SerializeToString(), i.log_time_ns, i.publish_time_ns, i.where)
            if isinstance(i, Output) else i for i in items]


# ---------------------------------------------------------------- velocity

def _number(x: float | None) -> str:
    return "" if x is None else f"{x:.2f}"


speeds = st.one_of(st.none(), st.floats(0.0, 60.0))
courses = st.one_of(st.none(), st.floats(0.0, 359.99))


def _rmc(status: str, knots: float | None, course: float | None) -> str:
    return build("GPRMC", ["080000.00", status, "4542.0000", "N", "12636.0000", "E", _number(knots), _number(course),
                           "121016", "", "", "A"])


def _vtg(course: float | None, knots: float | None, kmh: float | None, mode: str) -> str:
    return build("GPVTG", [_number(course), "T", "", "M", _number(knots), "N", _number(kmh), "K", mode])


def _expected(knots_text: str, kmh_text: str, course_text: str, valid: bool) -> tuple[float, float] | None:
    """The slow, obvious rule: speed from knots (else km/h), north = speed cos(course), east = speed sin(course)."""
    if not valid or not course_text or not (knots_text or kmh_text):
        return None
    speed = float(knots_text) * 1852.0 / 3600.0 if knots_text else float(kmh_text) / 3.6
    course = float(course_text)
    return speed * math.cos(course * math.pi / 180.0), speed * math.sin(course * math.pi / 180.0)


def _velocities(line: str) -> list:
    """Velocity outputs and ignored epochs of a GGA plus `line`, through the columnar and line paths and the
    reference; all three must agree."""
    gga = nmea.encode_gga(T0, 45.7, 126.6, hdop=0.9)
    data = (gga + line).encode()
    for log in (data, b"junk\n" + data):  # clean: the columns; a line of noise: the per-line path
        assert _plain(convert_nmea(log, _ctx())) == _plain(convert_nmea_reference(log, _ctx()))
    items = list(convert_nmea(data, _ctx()))
    return [i for i in items if (isinstance(i, Output) and i.topic == "/boat/gps/velocity") or isinstance(i, Ignored)]


@settings(max_examples=120, deadline=None)
@given(status=st.sampled_from("AV"), knots=speeds, course=courses)
def test_rmc_velocity_is_speed_along_course(status, knots, course):
    line = _rmc(status, knots, course)
    found = _velocities(line)
    expected = _expected(_number(knots), "", _number(course), status == "A")
    assert len(found) == 1
    if expected is None:
        assert found[0] == Ignored(found[0].where, NO_VELOCITY)
        return
    msg = found[0].message
    assert math.isclose(msg.velocity_north_mps, expected[0], rel_tol=1e-12, abs_tol=1e-12)
    assert math.isclose(msg.velocity_east_mps, expected[1], rel_tol=1e-12, abs_tol=1e-12)
    assert msg.speed_over_ground_mps == float(_number(knots)) * KNOT_MPS
    assert msg.course_over_ground_deg == float(_number(course)) and math.isnan(msg.velocity_up_mps)
    assert found[0].log_time_ns == T0 and msg.frame_id == "boat" and msg.source_format == "nmea:GGA,RMC"


@settings(max_examples=120, deadline=None)
@given(course=courses, knots=speeds, kmh=speeds, mode=st.sampled_from(["A", "D", "E", "N", "V", ""]))
def test_vtg_velocity_from_knots_else_kmh(course, knots, kmh, mode):
    found = _velocities(_vtg(course, knots, kmh, mode))
    expected = _expected(_number(knots), _number(kmh), _number(course), mode not in ("N", "V"))
    assert len(found) == 1
    if expected is None:
        assert isinstance(found[0], Ignored) and found[0].reason == NO_VELOCITY
        return
    msg = found[0].message
    assert math.isclose(msg.velocity_north_mps, expected[0], rel_tol=1e-12, abs_tol=1e-12)
    assert math.isclose(msg.velocity_east_mps, expected[1], rel_tol=1e-12, abs_tol=1e-12)
    assert math.isclose(math.hypot(msg.velocity_north_mps, msg.velocity_east_mps), msg.speed_over_ground_mps,
                        rel_tol=1e-12, abs_tol=1e-12)


def test_a_valid_vtg_comes_before_rmc_and_an_invalid_one_leaves_it():
    rmc = _rmc("A", 10.0, 90.0)
    [vtg_first] = _velocities(_vtg(0.0, 5.0, None, "A") + rmc)
    assert vtg_first.message.velocity_north_mps == 5.0 * KNOT_MPS and vtg_first.message.course_over_ground_deg == 0.0
    [rmc_used] = _velocities(_vtg(0.0, 5.0, None, "N") + rmc)
    assert rmc_used.message.course_over_ground_deg == 90.0
    assert rmc_used.message.speed_over_ground_mps == 10.0 * KNOT_MPS


def test_gga_alone_gives_no_velocity_and_nothing_ignored():
    items = list(convert_nmea(nmea.encode_gga(T0, 45.7, 126.6).encode(), _ctx()))
    assert [i.topic for i in items] == ["/boat/gps", "/boat/gps/status"]


# ---------------------------------------------------------------- sentence counts

def reference_counts(data: bytes) -> dict[str, dict[str, int]]:
    """Every line counted the slow, obvious way: frame it, look its type up, parse it (logs without prefixes or
    sentences glued together)."""
    table: dict[str, dict[str, int]] = {}
    lines = data.decode("latin-1").split("\n")
    if lines[-1] == "":
        lines.pop()
    for raw in lines:
        text = raw.rstrip("\r")
        sentence = frame(text, "$") if text.strip() else None
        if not text.strip():
            key, outcome = C.BLANK, C.IGNORED
        elif sentence is None or not (sentence.address.isascii() and sentence.address.isalnum()
                                      and sentence.address.isupper() and len(sentence.address) >= 3):
            key, outcome = C.NO_SENTENCE, C.REJECTED
        elif sentence.address[0] == "P" or sentence.address[-3:] not in VALUES:
            key, outcome = sentence.address, C.skipped_outcome(sentence.address)
        elif not sentence.checksum_ok:
            key, outcome = sentence.address, C.BAD_CHECKSUM
        else:
            key = sentence.address
            try:
                VALUES[key[-3:]](sentence.fields)
                outcome = C.USED
            except (ValueError, IndexError, OverflowError):
                outcome = C.REJECTED
        per = table.setdefault(key, {})
        per[outcome] = per.get(outcome, 0) + 1
    return dict(sorted(table.items()))


def _clean_line(k: int, choice: str) -> str:
    t = T0 + k * NS
    return {
        "GGA": nmea.encode_gga(t, 45.7, 126.6, hdop=0.9), "RMC": nmea.encode_rmc(t, 45.7, 126.6, speed_knots=3.0,
                                                                                  course_deg=40.0),
        "VTG": nmea.encode_vtg(40.0, 3.0), "GSV": build("GPGSV", ["3", "1", "11", "03", "03", "111", "00"]),
        "GSA": build("GNGSA", ["A", "3", "04", "05", "", "1.6", "0.9", "1.3"]), "TXT": build("GPTXT", ["01", "01",
                                                                                                        "02", "hi"]),
        "PGRME": build("PGRME", ["1.0", "M"]), "XYZ": build("GPXYZ", ["1"]), "blank": "\r\n",
    }[choice]


def _damaged_line(k: int, choice: str) -> str:
    good = nmea.encode_gga(T0 + k * NS, 45.7, 126.6)
    return {"noise": "hello there\n", "bad checksum": good[:-4] + "00\r\n",
            "bad field": build("GPGGA", ["080000.00", "99x", "N"]), "bad address": build("gp", ["1"])}.get(choice) \
        or _clean_line(k, choice)


line_kinds = st.sampled_from(["GGA", "RMC", "VTG", "GSV", "GSA", "TXT", "PGRME", "XYZ", "blank"])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 5), line_kinds), max_size=40),
       st.lists(st.sampled_from(["noise", "bad checksum", "bad field", "bad address"]), max_size=3),
       st.integers(100, 400), st.booleans())  # blocks longer than a line: a line cut in two is two pieces
def test_counts_add_up_to_the_lines_and_match_the_reference(lines, damage, block, last_newline):
    log = "".join(_clean_line(k, c) for k, c in sorted(lines)) + "".join(_damaged_line(0, d) for d in damage)
    if not last_newline and log.endswith("\n"):
        log = log[:-1]
    data = log.encode()
    expected = reference_counts(data)
    n_lines = data.count(b"\n") + (0 if data.endswith(b"\n") or not data else 1)
    for convert in (lambda ctx: convert_nmea(data, ctx), lambda ctx: convert_nmea_blocks(blocks_of(data, block), ctx)):
        ctx = _ctx()
        for _ in convert(ctx):
            pass
        assert ctx.counts.as_dict() == expected
        assert ctx.counts.total() == n_lines


def test_addresses_past_the_bound_are_counted_together():
    data = "".join(build(f"GP{i:03d}", ["1"]) for i in range(C.MAX_ADDRESSES + 50)).encode()
    ctx = _ctx()
    list(convert_nmea(data, ctx))
    table = ctx.counts.as_dict()
    assert len(table) == C.MAX_ADDRESSES + 1 and table[C.OTHERS] == {C.UNKNOWN: 50}
    assert ctx.counts.total() == C.MAX_ADDRESSES + 50


def test_record_counts_sentences_in_the_metadata_the_note_and_info(tmp_path, capsys):
    mix = []
    for k in range(30):
        t = T0 + k * NS
        mix += [nmea.encode_rmc(t, 45.7, 126.6, speed_knots=3.0, course_deg=40.0), nmea.encode_vtg(40.0, 3.0),
                nmea.encode_gga(t, 45.7, 126.6, hdop=0.9),
                *(build("GPGSV", ["3", str(i), "11", "03", "03", "111", "00"]) for i in (1, 2, 3)),
                build("GPTXT", ["01", "01", "02", "ANTENNA OK"])]
    mix += ["\r\n", "garbage\n", nmea.encode_gga(T0 + 40 * NS, 45.7, 126.6)[:-4] + "00\r\n"]
    (tmp_path / "gps.log").write_text("".join(mix))
    (tmp_path / "trial.toml").write_text('[trial]\nname = "t"\ndate = "2016-10-12"\n[[vehicles]]\nname = "boat"\n'
                                         'role = "leader"\n[[vehicles.logs]]\nsensor = "gps"\nformat = "nmea"\n'
                                         'path = "gps.log"\n')
    summary = record(load_manifest(tmp_path / "trial.toml"), tmp_path / "t.mcap", workers=1)
    sentences = summary.files[0].sentences
    assert sentences == {
        C.BLANK: {C.IGNORED: 1}, C.NO_SENTENCE: {C.REJECTED: 1}, "GPGGA": {C.USED: 30, C.BAD_CHECKSUM: 1},
        "GPGSV": {C.IGNORED: 90}, "GPRMC": {C.USED: 30}, "GPTXT": {C.IGNORED: 30}, "GPVTG": {C.USED: 30}}
    lines = (tmp_path / "gps.log").read_bytes().count(b"\n")
    assert sum(sum(v.values()) for v in sentences.values()) == lines == 213
    assert summary.files[0].parsed == 30 and summary.files[0].messages == 90  # epochs; fix, status, velocity
    assert main(["info", str(tmp_path / "t.mcap"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["diagnostics"]["gps.log"]["sentences"] == sentences
    assert info["topics"]["/boat/gps/velocity"] == {"count": 30, "schema": "auvreplay.GnssVelocity"}
    assert main(["info", str(tmp_path / "t.mcap")]) == 0
    assert "gps.log: 213 lines: (blank line) 1 ignored" in capsys.readouterr().out
    assert main(["record", str(tmp_path / "trial.toml"), "-o", str(tmp_path / "t2.mcap"), "--workers", "1"]) == 0
    assert "note: gps.log: 213 lines: " in capsys.readouterr().out


def test_host_prefixes_and_glued_sentences_are_counted_like_their_sentences():
    lines = [nmea.encode_gga(T0, 45.7, 126.6), nmea.encode_vtg(40.0, 3.0),
             build("GPGSV", ["3", "1", "11", "03", "03", "111", "00"]), build("PGRME", ["1.0", "M"]), "noise\n"]
    plain = "".join(lines).encode()
    prefixed = "".join(f"{T0 / NS:.3f} {line}" for line in lines).encode()
    counted = []
    for data in (plain, prefixed):
        ctx = _ctx()
        list(convert_nmea(data, ctx))
        counted.append(ctx.counts.as_dict())
    assert counted[0] == counted[1] == reference_counts(plain)
    glued = (nmea.encode_gga(T0, 45.7, 126.6).rstrip() + build("GPGSV", ["3", "1", "11"])).encode()
    ctx = _ctx()
    list(convert_nmea(glued, ctx))
    assert ctx.counts.as_dict() == {"GPGGA": {C.USED: 1}, "GPGSV": {C.IGNORED: 1}}  # one line, two sentences
