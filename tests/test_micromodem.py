"""WHOI Micro-Modem decoder and encoders: sentences from the interface guide and real logs."""

from __future__ import annotations

from datetime import date

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats.micromodem import sentences as mm
from formats.nmea.framing import nmea_checksum
from formats.records import Reject, Where

W = Where(0, 1)


def _one(text: str, **kw: bool) -> object:
    return mm.decode_sentence(text, W, **kw)


def test_campr_fields_and_one_way_default() -> None:
    # $CAMPR,SRC,DEST,TRAVELTIME: modem 3 replied to modem 1 after 0.5279 s
    body = "CAMPR,3,1,0.5279"
    rec = _one(f"${body}*{nmea_checksum(body):02X}")
    assert rec == mm.PingReply(W, 3, 1, 0.5279, 0.5279)


def test_campr_round_trip_is_halved() -> None:
    rec = _one("$CAMPR,3,1,1.0558", campr_round_trip=True)
    assert isinstance(rec, mm.PingReply)
    assert rec.travel_time_s == 1.0558 and rec.one_way_travel_time_s == pytest.approx(0.5279)


def test_real_mm2_sentences_with_their_checksums() -> None:
    # published Micro-Modem 2 log lines; their checksums were written by the modem
    cmd = _one("$CACMD,PNG,0,1,1,0,3*22")
    assert cmd == mm.PingCommand(W, 0, 1, True)
    heard = _one("$CACMA,2025-03-17T17:16:29.639994,PNG,0,1,56.7,6.62,3,0,0*74")
    assert isinstance(heard, mm.PingHeard) and (heard.src, heard.dest) == (0, 1)
    assert heard.utc_ns == 1742231789_639994000
    reply = _one("$CACMR,PNR,2025-05-29T15:09:05.461473,1,0,0.001997,6.3,7.65,1,0,*41")
    assert reply == mm.PingReply(W, 1, 0, 0.001997, 0.001997, 1748531345_461473000)
    other = _one("$CARFP,2025-03-17T17:16:29.672622,0,0,1,1,-1,0,0,1;5;08000106ff,1;3;ac4131,,*23")
    assert isinstance(other, mm.OtherSentence) and other.address == "CARFP"


def test_ping_command_echo_and_heard() -> None:
    assert _one("$CCMPC,1,2") == mm.PingCommand(W, 1, 2, False)
    assert _one("$CAMPC,1,2") == mm.PingCommand(W, 1, 2, True)
    assert _one("$CAMPA,1,2") == mm.PingHeard(W, 1, 2)


def test_statistics_time_of_arrival_and_clock() -> None:
    xst = _one("$CAXST,6,20161012,080001.2500,3,1,200,4000,25000,1,1,2,0,1,1,1,32")
    assert xst == mm.TransmitStats(W, 6, date(2016, 10, 12), 8 * 3600 + 1.25, 3, 1, 1, 2)
    old = _one("$CAXST,20161012,235959.0000,1,1,200,4000,25000,5,4,2,0,1,1,1,32")
    assert isinstance(old, mm.TransmitStats) and old.version == 0 and (old.rate, old.src, old.dest) == (5, 4, 2)
    cst = _one(
        "$CACST,6,0,080002.5000,3,1.0,2.0,3.0,4.0,5,6,7,8,9,1,2,1,0,1,1,0,10.0,11.0,12.0,13.0,14.0,15,0.3,16.0,25000,4000"
    )
    assert isinstance(cst, mm.ReceiveStats)
    assert (cst.tod_s, cst.rate, cst.src, cst.dest) == (8 * 3600 + 2.5, 1, 2, 1)
    assert (cst.snr_in_db, cst.snr_out_db, cst.doppler_mps) == (11.0, 12.0, 0.3)
    toa = _one("$CATOA,120000.1234,3")
    assert toa == mm.TimeOfArrival(W, 12 * 3600 + 0.1234, None, 3)
    clk = _one("$CACLK,2016,10,12,08,00,01")
    assert clk == mm.Clock(W, 1476259201 * 1_000_000_000)


def test_data_cycle_sentences() -> None:
    assert _one("$CACYC,1,1,2,1,0,3") == mm.CycleInit(W, 1, 1, 2, 1, False, 3)
    assert _one("$CARXD,2,1,0,1,48656C6C6F") == mm.ReceivedData(W, 2, 1, False, 1, b"Hello")
    assert _one("$CAMUA,2,1,0A0B") == mm.ReceivedData(W, 2, 1, False, 0, b"\n\x0b")


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("$CAMPR,3,1,0.5279*00", "bad checksum"),
        ("$CAMPR,3,1", "truncated $CAMPR"),
        ("$CAMPR,3,1,", "empty travel time"),
        ("$CAMPR,3,,0.5", "empty destination"),
        ("$CAMPR,3,1,-0.2", "negative travel time"),
        ("$CAMPR,3,1,nan", "not finite"),
        ("$CARXD,2,1,0,1,ABC", "bad $CARXD"),
        ("$CAXST,20161312,080001.0000,3,1,200,4000,25000,1,1,2", "bad $CAXST"),
        ("$CATOA,256199.0,3", "out of range"),
        ("\x00\x17garbage without a start", "no sentence start"),
    ],
)
def test_bad_records_are_rejected_with_a_reason(text: str, reason: str) -> None:
    rec = _one(text)
    assert isinstance(rec, Reject)
    assert reason in rec.reason
    assert rec.bad_checksum == (reason == "bad checksum")


def test_stream_with_prefixes_crlf_lf_and_noise() -> None:
    data = (
        b"2016-10-12T08:00:00.000Z $CCMPC,1,2*5D\r\n"
        b"\xff\xfe\x00binary noise\n"
        b"1476259200.500 \xa5\xa5$CAMPR,2,1,0.3333*7C\n"
        b"\r\n"
        b"$CAMPR,2,1,0.3*00\r\n"
    )
    recs = list(mm.decode(data))
    assert [type(r).__name__ for r in recs] == ["PingCommand", "Reject", "PingReply", "Reject"]
    assert recs[0].where.host_time_ns == 1476259200_000_000_000
    assert recs[2].where == Where(offset=56, line=3, host_time_ns=1476259200_500_000_000)
    assert recs[3].bad_checksum and recs[3].where.line == 5


def test_ping_exchange_lines_time_the_reply_after_the_epoch() -> None:
    t = 1476259200_000_000_000
    lines = mm.ping_exchange_lines(t, 1, 2, 0.25)
    recs = list(mm.decode("".join(lines).encode()))
    assert recs[0] == mm.PingCommand(recs[0].where, 1, 2, False)
    assert recs[0].where.host_time_ns == t - 250_000_000
    reply = recs[2]
    assert isinstance(reply, mm.PingReply) and (reply.src, reply.dest) == (2, 1)
    assert reply.where.host_time_ns == t + 250_000_000


@given(
    src=st.integers(0, 127), dest=st.integers(0, 127),
    owtt=st.floats(0, 20, allow_nan=False), round_trip=st.booleans(),
)
def test_campr_encode_decode_round_trip(src: int, dest: int, owtt: float, round_trip: bool) -> None:
    rec = _one(mm.encode_campr(src, dest, owtt, round_trip, decimals=6), campr_round_trip=round_trip)
    assert isinstance(rec, mm.PingReply) and (rec.src, rec.dest) == (src, dest)
    assert rec.one_way_travel_time_s == pytest.approx(owtt, abs=1.01e-6)


@given(
    t_ns=st.integers(946684800 * 10**9, 4102444800 * 10**9), src=st.integers(0, 127),
    dest=st.integers(0, 127), owtt=st.floats(0, 20, allow_nan=False),
)
def test_cacmr_and_catoa_round_trip(t_ns: int, src: int, dest: int, owtt: float) -> None:
    rec = _one(mm.encode_cacmr_pnr(t_ns, src, dest, owtt))
    assert isinstance(rec, mm.PingReply) and (rec.src, rec.dest) == (src, dest)
    assert rec.utc_ns == t_ns // 1000 * 1000
    assert rec.one_way_travel_time_s == pytest.approx(owtt, abs=1e-6)
    toa = _one(mm.encode_catoa(t_ns))
    assert isinstance(toa, mm.TimeOfArrival)
    assert toa.tod_s == pytest.approx((t_ns % (86400 * 10**9)) // 100_000 / 1e4, abs=1e-9)


@given(payload=st.binary(max_size=64), src=st.integers(0, 127), frame_no=st.integers(1, 8))
def test_carxd_round_trip(payload: bytes, src: int, frame_no: int) -> None:
    rec = _one(mm.encode_carxd(src, 1, payload, frame_no))
    assert rec == mm.ReceivedData(W, src, 1, False, frame_no, payload)


_SENTENCEISH = st.text(alphabet="$*,.-0123456789ABCDEFMPRCTXYSOGNZ:T \r\n\x00\xff", max_size=200)


@settings(max_examples=300)
@given(data=st.one_of(st.binary(max_size=300), _SENTENCEISH.map(lambda s: s.encode("latin-1"))))
def test_no_input_makes_the_decoder_raise(data: bytes) -> None:
    for rec in mm.decode(data):
        assert isinstance(rec, (Reject, *mm.Record.__args__))


@settings(max_examples=200)
@given(
    address=st.sampled_from(sorted(mm._PARSERS)),
    fields=st.lists(st.text(alphabet="0123456789.-:TZPNGR", max_size=12), max_size=32),
)
def test_every_parser_survives_arbitrary_fields(address: str, fields: list[str]) -> None:
    body = ",".join([address, *fields])
    rec = _one(f"${body}*{nmea_checksum(body):02X}")
    assert isinstance(rec, (Reject, *mm.Record.__args__))
