"""EvoLogics S2C decoder and encoders: notifications from the AT reference and a real data-mode log."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.evologics import notifications as ev
from formats.records import Reject, Where

# a published data-mode session (S2C USBL, target address 3); lengths as the modem wrote them
REAL = (
    "+++AT:124:USBLLONG,10446.991981,10446.534643,3,-0.0604,-1.0888,-0.5851,-0.4233,-1.0020,-0.5901,"
    "0.0063,0.0269,-0.3295,825,-36,77,1.2375\r\n"
    "+++AT:99:USBLPHYD,10446.992626,10446.534642,3,0,-39278,-10591,16777215,-12608,-27941,23818,"
    "16777215,16777215\r\n"
    "+++AT:245:USBLPHYP,10446.992626,10446.534642,3,0,1000000.0000,1000000.0000,1000000.0000,"
    "2000000.0000,2000000.0000,2000000.0000,3000000.0000,3000000.0000,3000000.0000,-0.0806,-1.0113,"
    "-0.7086,-5000000.0000,-3535534.0000,10606602.0000,-0.0394,-1.1508,-0.4533\r\n"
    "+++AT:23:SENDSTART,3,im,182272,0\r\n"
    "+++AT:30:SENDEND,3,im,1853167139,182272\r\n"
    "+++AT:32:RECVEND,1853461060,139376,-36,77\r\n"
    "+++AT:13:DELIVEREDIM,3\r\n"
)


def test_real_data_mode_session() -> None:
    recs = list(ev.decode(REAL.encode()))
    names = [type(r).__name__ for r in recs]
    assert names == ["UsblLong", "UsblPhaseDelays", "UsblPhasePositions", "OtherNotification",
                     "SendEnd", "ReceiveEnd", "Delivery"]
    fix = recs[0]
    assert isinstance(fix, ev.UsblLong)
    assert (fix.address, fix.east_m, fix.north_m, fix.up_m) == (3, -0.4233, -1.0020, -0.5901)
    assert fix.propagation_time_us == 825 and fix.integrity == 77 and fix.accuracy_m == 1.2375
    # 825 µs at 1500 m/s is the 1.24 m the X/Y/Z vector measures
    assert math.hypot(fix.x_m, fix.y_m, fix.z_m) == pytest.approx(825e-6 * 1500, abs=0.01)
    phyd = recs[1]
    assert isinstance(phyd, ev.UsblPhaseDelays) and phyd.delays_ns[0] == -39278
    assert math.isnan(phyd.delays_ns[2]) and math.isnan(phyd.delays_ns[6])
    assert recs[4] == ev.SendEnd(recs[4].where, 3, "im", 1853167139, 182272)
    assert recs[6] == ev.Delivery(recs[6].where, "DELIVEREDIM", 3, True)


def test_command_mode_lines_with_host_prefixes() -> None:
    data = (
        b"2016-10-12T08:00:00.000Z USBLANGLES,100.5,100.2,2,0.1,-0.2,0.7853982,-0.1,0,0,0,-40,90,0.5\n"
        b"2016-10-12T08:00:01.000Z DELIVEREDIM,2\n"
        b"2016-10-12T08:00:01.100Z AT?T\n"
        b"2016-10-12T08:00:01.200Z 333333\n"
    )
    recs = list(ev.decode(data))
    ang = recs[0]
    assert isinstance(ang, ev.UsblAngles) and ang.address == 2 and ang.bearing_rad == 0.7853982
    assert ev.bearing_from_vendor(ang.bearing_rad) == pytest.approx(45.0)
    assert ev.bearing_from_vendor(ang.bearing_rad, "compass") == pytest.approx(45.0)
    assert ev.bearing_from_vendor(0.0) == pytest.approx(90.0)  # east
    prop = recs[2]
    assert isinstance(prop, ev.PropagationTime) and prop.propagation_time_us == 333333 and prop.peer == 2
    assert prop.where.host_time_ns == 1476259201_200_000_000


def test_recvim_layouts_are_told_apart_by_length() -> None:
    new = "RECVIM,7,2,1,ack,120000,-45,88,0.12,ab,cd\nx"  # payload has a comma and a newline
    rec = list(ev.decode(f"+++AT:{len(new)}:{new}\r\nDELIVEREDIM,5\r\n".encode()))
    assert isinstance(rec[0], ev.ReceivedIM)
    assert rec[0].payload == b"ab,cd\nx" and rec[0].ack and rec[0].duration_us == 120000
    assert math.isnan(rec[0].propagation_time_us)
    assert isinstance(rec[1], ev.Delivery) and rec[1].dest == 5
    old = ev.decode_notification("RECVIM,3,2,1,noack,500,-40,90,1234,0.1,xyz", Where(0))
    assert isinstance(old, ev.ReceivedIM) and old.propagation_time_us == 1234 and old.payload == b"xyz"
    ims = ev.decode_notification("RECVIMS,2,4,1,9000000,60000,-50,70,0.0,hi", Where(0))
    assert isinstance(ims, ev.ReceivedIM) and ims.timestamp_us == 9000000 and ims.src == 4
    pbm = ev.decode_notification("RECVPBM,2,4,1,60000,-50,70,0.0,hi", Where(0))
    assert isinstance(pbm, ev.ReceivedIM) and pbm.kind == "RECVPBM" and pbm.payload == b"hi"


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        ("USBLLONG,1,1,3,0,0,0,0,0,0,0,0,0,825,-36,77", "truncated USBLLONG"),
        ("USBLLONG,1,1,3,0,0,0,0,0,0,0,0,0,825,-36,77,1.2,9", "17 fields"),
        ("USBLLONG,1,1,3,0,0,0,,0,0,0,0,0,825,-36,77,1.2", "empty field"),
        ("USBLLONG,1,1,-3,0,0,0,0,0,0,0,0,0,825,-36,77,1.2", "address"),
        ("USBLLONG,1,1,3,0,0,0,0,0,0,0,0,0,-825,-36,77,1.2", "negative propagation"),
        ("USBLANGLES,1,1,3,0,0,inf,0,0,0,0,-40,90,0.5", "not finite"),
        ("RECVIM,9,2,1,ack,1,2,3,4,short", "declared payload length"),
        ("RECVIM,2,2,1,maybe,1,2,3,4,ab", "ack flag"),
        ("DELIVEREDIM,", "truncated DELIVEREDIM"),
        ("\x00\x01\xfe rubbish", "not an S2C notification"),
    ],
)
def test_bad_lines_are_rejected(line: str, reason: str) -> None:
    rec = ev.decode_notification(line, Where(0, 1))
    assert isinstance(rec, Reject) and reason in rec.reason


def test_truncated_frame_costs_one_line_only() -> None:
    good = ev.encode_usbllong(3, 1.0, 2.0, -3.0, 0.0025, framed=True)
    data = ("+++AT:124:USBLLONG,10446.99\r\n" + good + "+++AT:5:OK\r\n").encode()
    recs = list(ev.decode(data))
    assert isinstance(recs[0], Reject) and "declares 124" in recs[0].reason
    assert isinstance(recs[1], ev.UsblLong) and recs[1].north_m == 2.0
    assert isinstance(recs[2], Reject) and recs[2].where.line == 3


def test_propagation_time_without_peer_and_framed_reply() -> None:
    recs = list(ev.decode(ev.encode_propagation_time(0.5).encode()))
    assert recs == [ev.PropagationTime(recs[0].where, 500000, None)]
    recs = list(ev.decode(b"+++AT?T:3:12x\r\n"))
    assert isinstance(recs[0], Reject) and "not a number" in recs[0].reason


finite = st.floats(-1000, 1000, allow_nan=False)


@given(
    address=st.integers(0, 254), e=finite, n=finite, u=finite, tt=st.floats(0, 10, allow_nan=False),
    ct=st.floats(0, 1e6, allow_nan=False), framed=st.booleans(),
)
def test_usbllong_round_trip(address: int, e: float, n: float, u: float, tt: float, ct: float, framed: bool) -> None:
    (rec,) = ev.decode(ev.encode_usbllong(address, e, n, u, tt, current_time_s=ct, framed=framed).encode())
    assert isinstance(rec, ev.UsblLong) and rec.address == address
    assert (rec.east_m, rec.north_m, rec.up_m) == pytest.approx((e, n, u), abs=5.1e-5)
    assert rec.propagation_time_us * 1e-6 == pytest.approx(tt, abs=5.1e-7)
    assert rec.current_time_s == pytest.approx(ct, abs=5.1e-7)


@given(bearing=st.floats(0, 359.99), elevation=st.floats(-89, 89), convention=st.sampled_from(["enu", "compass"]))
def test_usblangles_round_trip(bearing: float, elevation: float, convention: str) -> None:
    (rec,) = ev.decode(ev.encode_usblangles(1, bearing, elevation, convention=convention).encode())
    assert isinstance(rec, ev.UsblAngles)
    back = ev.bearing_from_vendor(rec.bearing_rad, convention)
    assert min(abs(back - bearing), 360 - abs(back - bearing)) < 1e-4
    assert math.degrees(rec.elevation_rad) == pytest.approx(elevation, abs=1e-4)


@given(
    px=st.floats(-60, 60, allow_nan=False), py=st.floats(-60, 60, allow_nan=False),
    carrier=st.floats(10e3, 100e3), framed=st.booleans(),
)
def test_usblphyd_carries_phases(px: float, py: float, carrier: float, framed: bool) -> None:
    (rec,) = ev.decode(ev.encode_usblphyd(7, px, py, carrier, framed=framed).encode())
    assert isinstance(rec, ev.UsblPhaseDelays) and rec.address == 7
    # integer-ns delays: one ns is 2 pi f 1e-9 rad
    tol = 2 * math.pi * carrier * 1e-9
    assert ev.phases_from_delays(rec.delays_ns, carrier) == pytest.approx((px, py), abs=tol)


def test_phases_from_partial_delays() -> None:
    delays = ev.delays_from_phases(1.0, -0.5, 75e3)
    partial = [math.nan if i in (2, 6) else d for i, d in enumerate(delays)]  # element pairs with 3 missing
    assert ev.phases_from_delays(partial, 75e3) == pytest.approx((1.0, -0.5))
    assert all(math.isnan(p) for p in ev.phases_from_delays([math.nan] * 8, 75e3))


@given(payload=st.binary(max_size=64), src=st.integers(0, 254), framed=st.booleans())
def test_recvim_round_trip(payload: bytes, src: int, framed: bool) -> None:
    recs = list(ev.decode(ev.encode_recvim(src, 1, payload, framed=framed).encode("latin-1")))
    if b"\n" in payload or b"\r" in payload:
        return  # a newline splits unframed lines; covered for framed lines above
    assert isinstance(recs[0], ev.ReceivedIM) and recs[0].payload == payload and recs[0].src == src


_NOTIFICATIONISH = st.text(alphabet="+ATUSBLONGRECVIMDELPHY?*:,.-0123456789\r\n\x00\xff", max_size=200)


@settings(max_examples=300)
@given(data=st.one_of(st.binary(max_size=300), _NOTIFICATIONISH.map(lambda s: s.encode("latin-1"))))
def test_no_input_makes_the_decoder_raise(data: bytes) -> None:
    for rec in ev.decode(data):
        assert isinstance(rec, (Reject, *ev.Record.__args__))


@settings(max_examples=200)
@given(
    keyword=st.sampled_from(["USBLLONG", "USBLANGLES", "USBLPHYD", "USBLPHYP", "RECVIM", "RECVIMS",
                             "RECVPBM", "RECVEND", "SENDEND", "DELIVEREDIM", "FAILEDIM"]),
    fields=st.lists(st.text(alphabet="0123456789.-eackno", max_size=8), max_size=24),
)
def test_every_keyword_survives_arbitrary_fields(keyword: str, fields: list[str]) -> None:
    rec = ev.decode_notification(",".join([keyword, *fields]), Where(0))
    assert isinstance(rec, (Reject, *ev.Record.__args__))
