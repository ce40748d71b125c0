"""WHOI Micro-Modem (1 and 2) NMEA sentences: ping ranging, time of arrival, data cycle.

Field orders follow the Micro-Modem Software Interface Guide (sentence
descriptions as quoted by Goby's driver, GobySoft/goby3
src/acomms/modemdriver/mm_driver.cpp) and, for the Micro-Modem 2 ping
($CCCMD,PNG / $CACMR,PNR), logs published by users:

- ``$CCMPC,SRC,DEST`` ping command (host to modem), ``$CAMPC`` its echo;
  ``$CAMPA,SRC,DEST`` a ping was received by this modem;
  ``$CAMPR,SRC,DEST,TRAVELTIME`` reply to a ping, SRC the modem that replied.
  TRAVELTIME: the guide's field is read as ONE-WAY travel time in seconds
  (Goby stores it as ``one_way_travel_time``); a log written by firmware or a
  logger that reports the round trip is read with ``campr_round_trip=True``.
- ``$CCCMD,PNG,SRC,DEST,RATE,CDR,NBYTES`` / ``$CACMD,PNG,...`` (MM2 ping command and echo);
  ``$CACMA,TIME,PNG,SRC,DEST,...`` ping heard; ``$CACMR,PNR,TIME,SRC,DEST,OWTT,...``
  ping reply with the reception time (ISO 8601 UTC) and one-way travel time
  (seconds). Firmware versions differ in whether TIME or the PNG/PNR tag comes
  first; both orders are read.
- ``$CATOA,TIME,MODE`` time of arrival of the previous packet (HHMMSS.SSSS or ISO 8601).
- ``$CACYC,CMD,SRC,DEST,RATE,ACK,NFRAMES`` cycle init; ``$CARXD,SRC,DEST,ACK,FRAME,HEX``
  received data; ``$CAMUA,SRC,DEST,HEX`` received mini-packet.
- ``$CAXST`` transmit statistics (date YYYYMMDD and time HHMMSS.SSSS; version 6
  inserts a version field first); ``$CACST`` receive statistics (time of
  arrival HHMMSS.SSSS, clock mode, source, destination...).
- ``$CACLK,YYYY,MM,DD,HH,MM,SS`` the modem clock.

Ping sentences carry no time: the recorder uses the host-timestamp prefix.
Well-framed sentences of other types are yielded as `OtherSentence`.
"""

from __future__ import annotations

import calendar
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime

from ..lines import iter_lines
from ..nmea.framing import build, frame
from ..numbers import finite, integer
from ..records import Reject, Where
from ..regex_lines import parse_iso8601_ns, parse_tod_s
from ..units import DAY_NS, NS


@dataclass(frozen=True, slots=True)
class PingCommand:
    """$CCMPC (host command) or $CAMPC (modem echo): SRC pings DEST."""

    where: Where
    src: int
    dest: int
    echo: bool


@dataclass(frozen=True, slots=True)
class PingHeard:
    """$CAMPA / $CACMA,PNG: this modem received a ping from SRC to DEST (MM2 adds its time)."""

    where: Where
    src: int
    dest: int
    utc_ns: int | None = None


@dataclass(frozen=True, slots=True)
class PingReply:
    """$CAMPR or $CACMR,PNR: SRC replied to DEST's ping; travel time as written and one way.

    `utc_ns` is the reception time when the sentence carries one (MM2), UTC
    without any clock offset.
    """

    where: Where
    src: int
    dest: int
    travel_time_s: float
    one_way_travel_time_s: float
    utc_ns: int | None = None


@dataclass(frozen=True, slots=True)
class TimeOfArrival:
    """$CATOA: time of arrival of the previous packet (time of day or absolute) and timing mode."""

    where: Where
    tod_s: float | None
    utc_ns: int | None
    mode: int | None


@dataclass(frozen=True, slots=True)
class CycleInit:
    """$CACYC / $CCCYC: a data cycle from SRC to DEST at a rate with a frame count."""

    where: Where
    command_src: int
    src: int
    dest: int
    rate: int
    ack: bool
    n_frames: int


@dataclass(frozen=True, slots=True)
class ReceivedData:
    """$CARXD (frame >= 1) or $CAMUA (frame 0, mini-packet): payload received from SRC."""

    where: Where
    src: int
    dest: int
    ack: bool
    frame: int
    payload: bytes


@dataclass(frozen=True, slots=True)
class TransmitStats:
    """$CAXST: what this modem transmitted, with the modem's date and time of day."""

    where: Where
    version: int
    date: date
    tod_s: float
    clock_mode: int
    rate: int
    src: int
    dest: int


@dataclass(frozen=True, slots=True)
class ReceiveStats:
    """$CACST: a packet received, with its time of arrival (time of day) and quality figures."""

    where: Where
    version: int
    mode: int
    tod_s: float
    clock_mode: int
    rate: int
    src: int
    dest: int
    snr_in_db: float
    snr_out_db: float
    doppler_mps: float


@dataclass(frozen=True, slots=True)
class Clock:
    """$CACLK: the modem's date and time (UTC ns, no clock offset)."""

    where: Where
    utc_ns: int


@dataclass(frozen=True, slots=True)
class OtherSentence:
    """A well-framed sentence this module does not interpret ($CAREV, $CACFG, $CATXF...)."""

    where: Where
    address: str
    fields: tuple[str, ...]


Record = (
    PingCommand | PingHeard | PingReply | TimeOfArrival | CycleInit | ReceivedData
    | TransmitStats | ReceiveStats | Clock | OtherSentence
)


def _int(text: str, name: str) -> int:
    text = text.strip()
    if not text or not text.lstrip("+-").isdigit():
        raise ValueError(f"{name} is not an integer: {text!r}" if text else f"empty {name}")
    return integer(text, name)


def _float(text: str, name: str) -> float:
    if not text.strip():
        raise ValueError(f"empty {name}")
    return finite(text, name)


def _opt_float(f: Sequence[str], i: int) -> float:
    try:
        return _float(f[i], "field") if i < len(f) else math.nan
    except ValueError:
        return math.nan


def _travel(text: str) -> float:
    tt = _float(text, "travel time")
    if tt < 0:
        raise ValueError(f"negative travel time {tt}")
    return tt


def _hex(text: str) -> bytes:
    return bytes.fromhex(text.strip())


def _yyyymmdd(text: str) -> date:
    t = text.strip()
    if len(t) != 8 or not t.isdigit():
        raise ValueError(f"date is not YYYYMMDD: {text!r}")
    return date(int(t[:4]), int(t[4:6]), int(t[6:]))


def _stamp(text: str) -> tuple[float | None, int | None]:
    """A time field that is either a time of day or ISO 8601."""
    return (None, parse_iso8601_ns(text)) if "-" in text else (parse_tod_s(text), None)


def _tagged(f: Sequence[str], tag: str) -> tuple[int, list[str]] | None:
    """MM2 sentences put the tag (PNG/PNR) before or after TIME: (utc_ns, rest) or None."""
    if len(f) >= 2 and f[0] == tag:
        return parse_iso8601_ns(f[1]), list(f[2:])
    if len(f) >= 2 and f[1] == tag:
        return parse_iso8601_ns(f[0]), list(f[2:])
    return None


# ---- per-sentence parsers: fields after the address -> record (ValueError/IndexError on bad input)

def _mpc(w: Where, f: Sequence[str], echo: bool) -> Record:
    return PingCommand(w, _int(f[0], "source"), _int(f[1], "destination"), echo)


def _mpa(w: Where, f: Sequence[str]) -> Record:
    return PingHeard(w, _int(f[0], "source"), _int(f[1], "destination"))


def _mpr(w: Where, f: Sequence[str], round_trip: bool) -> Record:
    tt = _travel(f[2])
    return PingReply(w, _int(f[0], "source"), _int(f[1], "destination"), tt, tt / 2 if round_trip else tt)


def _cmd(w: Where, f: Sequence[str], echo: bool) -> Record:
    if f[0] != "PNG":
        return OtherSentence(w, "CCCMD" if not echo else "CACMD", tuple(f))
    return PingCommand(w, _int(f[1], "source"), _int(f[2], "destination"), echo)


def _cma(w: Where, f: Sequence[str]) -> Record:
    tagged = _tagged(f, "PNG")
    if tagged is None:
        return OtherSentence(w, "CACMA", tuple(f))
    t, rest = tagged
    return PingHeard(w, _int(rest[0], "source"), _int(rest[1], "destination"), t)


def _cmr(w: Where, f: Sequence[str]) -> Record:
    tagged = _tagged(f, "PNR")
    if tagged is None:
        return OtherSentence(w, "CACMR", tuple(f))
    t, rest = tagged
    tt = _travel(rest[2])
    return PingReply(w, _int(rest[0], "source"), _int(rest[1], "destination"), tt, tt, t)


def _toa(w: Where, f: Sequence[str]) -> Record:
    tod, utc = _stamp(f[0])
    mode = _int(f[1], "mode") if len(f) > 1 and f[1].strip() else None
    return TimeOfArrival(w, tod, utc, mode)


def _cyc(w: Where, f: Sequence[str]) -> Record:
    return CycleInit(
        w, _int(f[0], "command source"), _int(f[1], "source"), _int(f[2], "destination"),
        _int(f[3], "rate"), bool(_int(f[4], "ack")), _int(f[5], "frame count"),
    )


def _rxd(w: Where, f: Sequence[str]) -> Record:
    frame_no = _int(f[3], "frame")
    if frame_no < 1:
        raise ValueError(f"frame numbers start at 1, got {frame_no}")
    return ReceivedData(w, _int(f[0], "source"), _int(f[1], "destination"), bool(_int(f[2], "ack")), frame_no,
                        _hex(f[4]))


def _mua(w: Where, f: Sequence[str]) -> Record:
    return ReceivedData(w, _int(f[0], "source"), _int(f[1], "destination"), False, 0, _hex(f[2]))


def _xst(w: Where, f: Sequence[str]) -> Record:
    first = _int(f[0], "first field")
    version, o = (0, 0) if first > 19700000 else (first, 1)
    return TransmitStats(
        w, version, _yyyymmdd(f[o]), parse_tod_s(f[o + 1]), _int(f[o + 2], "clock mode"),
        _int(f[o + 7], "rate"), _int(f[o + 8], "source"), _int(f[o + 9], "destination"),
    )


def _cst(w: Where, f: Sequence[str]) -> Record:
    first = _int(f[0], "first field")
    version, o = (0, 0) if first < 6 else (first, 1)
    return ReceiveStats(
        w, version, _int(f[o], "mode"), parse_tod_s(f[o + 1]), _int(f[o + 2], "clock mode"),
        _int(f[o + 12], "rate"), _int(f[o + 13], "source"), _int(f[o + 14], "destination"),
        _opt_float(f, o + 20), _opt_float(f, o + 21), _opt_float(f, o + 25),
    )


def _clk(w: Where, f: Sequence[str]) -> Record:
    y, mo, d, h, mi = (_int(f[i], "clock field") for i in range(5))
    s = _float(f[5], "seconds")
    whole = int(s)
    dt = datetime(y, mo, d, h, mi, whole, tzinfo=UTC)
    return Clock(w, calendar.timegm(dt.timetuple()) * NS + round((s - whole) * NS))


_PARSERS: dict[str, Callable[[Where, Sequence[str], bool], Record]] = {
    "CCMPC": lambda w, f, rt: _mpc(w, f, False),
    "CAMPC": lambda w, f, rt: _mpc(w, f, True),
    "CAMPA": lambda w, f, rt: _mpa(w, f),
    "CAMPR": _mpr,
    "CCCMD": lambda w, f, rt: _cmd(w, f, False),
    "CACMD": lambda w, f, rt: _cmd(w, f, True),
    "CACMA": lambda w, f, rt: _cma(w, f),
    "CACMR": lambda w, f, rt: _cmr(w, f),
    "CATOA": lambda w, f, rt: _toa(w, f),
    "CACYC": lambda w, f, rt: _cyc(w, f),
    "CCCYC": lambda w, f, rt: _cyc(w, f),
    "CARXD": lambda w, f, rt: _rxd(w, f),
    "CAMUA": lambda w, f, rt: _mua(w, f),
    "CAXST": lambda w, f, rt: _xst(w, f),
    "CACST": lambda w, f, rt: _cst(w, f),
    "CACLK": lambda w, f, rt: _clk(w, f),
}


def decode_sentence(text: str, where: Where, campr_round_trip: bool = False) -> Record | Reject:
    """Decode one line's sentence (noise before '$' ignored); a Reject when it is unusable."""
    s = frame(text, "$")
    if s is None:
        return Reject(where, "no sentence start '$'")
    if s.has_checksum and not s.checksum_ok:
        return Reject(where, f"bad checksum in ${s.address}", bad_checksum=True)
    parser = _PARSERS.get(s.address)
    if parser is None:
        if not s.address.isalnum() or not 2 <= len(s.address) <= 6:
            return Reject(where, f"not a sentence address: {s.address[:16]!r}")
        return OtherSentence(where, s.address, tuple(s.fields))
    try:
        return parser(where, s.fields, campr_round_trip)
    except IndexError:
        return Reject(where, f"truncated ${s.address}: {len(s.fields)} fields")
    except (ValueError, OverflowError) as exc:
        return Reject(where, f"bad ${s.address}: {exc}")


def decode(data: bytes, prefix: str = "auto", campr_round_trip: bool = False) -> Iterator[Record | Reject]:
    """Stream Micro-Modem records and Rejects from a log (host prefixes, CRLF/LF, noise)."""
    for line in iter_lines(data, prefix):
        yield decode_sentence(line.text, line.where, campr_round_trip)


# ---- encoders (trial simulator, round-trip tests)

def _fmt_iso(t_ns: int) -> str:
    sec, ns = divmod(int(t_ns), NS)
    stamp = datetime.fromtimestamp(sec, tz=UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{stamp}.{ns // 1000:06d}"


def _fmt_tod(t_ns: int) -> str:
    ns_of_day = int(t_ns) % DAY_NS
    h, rem = divmod(ns_of_day, 3600 * NS)
    m, rem = divmod(rem, 60 * NS)
    return f"{h:02d}{m:02d}{rem // NS:02d}.{(rem % NS) // 100_000:04d}"


def host_line(t_ns: int, sentence: str) -> str:
    """Prefix a sentence with an ISO 8601 host timestamp (µs) as a data logger writes it."""
    return f"{_fmt_iso(t_ns)}Z {sentence}"


def encode_ccmpc(src: int, dest: int) -> str:
    """$CCMPC: the host asks modem SRC to ping modem DEST."""
    return build("CCMPC", [str(src), str(dest)])


def encode_campc(src: int, dest: int) -> str:
    """$CAMPC: the modem's echo of a ping command."""
    return build("CAMPC", [str(src), str(dest)])


def encode_campa(src: int, dest: int) -> str:
    """$CAMPA: modem DEST heard a ping from SRC."""
    return build("CAMPA", [str(src), str(dest)])


def encode_campr(src: int, dest: int, one_way_travel_time_s: float, round_trip: bool = False, decimals: int = 4) -> str:
    """$CAMPR: modem SRC replied to DEST's ping; writes one-way time (or the round trip if asked)."""
    tt = one_way_travel_time_s * (2 if round_trip else 1)
    return build("CAMPR", [str(src), str(dest), f"{tt:.{decimals}f}"])


def encode_cccmd_png(src: int, dest: int, rate: int = 1, cdr: int = 0, num_bytes: int = 0) -> str:
    """$CCCMD,PNG: Micro-Modem 2 ping command."""
    return build("CCCMD", ["PNG", str(src), str(dest), str(rate), str(cdr), str(num_bytes)])


def encode_cacmr_pnr(t_ns: int, src: int, dest: int, one_way_travel_time_s: float) -> str:
    """$CACMR,PNR: Micro-Modem 2 ping reply from SRC received at t_ns (UTC) by DEST."""
    return build("CACMR", ["PNR", _fmt_iso(t_ns), str(src), str(dest), f"{one_way_travel_time_s:.6f}"])


def encode_catoa(t_ns: int, mode: int = 3) -> str:
    """$CATOA: time of arrival (time of day, 0.1 ms) and timing mode."""
    return build("CATOA", [_fmt_tod(t_ns), str(mode)])


def encode_cacyc(src: int, dest: int, rate: int = 1, ack: bool = False, n_frames: int = 1) -> str:
    """$CACYC: cycle init from SRC to DEST."""
    return build("CACYC", [str(src), str(src), str(dest), str(rate), str(int(ack)), str(n_frames)])


def encode_carxd(src: int, dest: int, payload: bytes, frame_no: int = 1, ack: bool = False) -> str:
    """$CARXD: data frame received from SRC."""
    return build("CARXD", [str(src), str(dest), str(int(ack)), str(frame_no), payload.hex().upper()])


def encode_caclk(t_ns: int) -> str:
    """$CACLK: the modem clock (whole seconds)."""
    d = datetime.fromtimestamp(int(t_ns) // NS, tz=UTC)
    return build("CACLK", [f"{d.year}", f"{d.month:02d}", f"{d.day:02d}",
                           f"{d.hour:02d}", f"{d.minute:02d}", f"{d.second:02d}"])


def ping_exchange_lines(
    t_ns: int, src: int, dest: int, one_way_travel_time_s: float, turnaround_s: float = 0.0,
    round_trip: bool = False,
) -> list[str]:
    """Host-prefixed lines of one Micro-Modem 1 ping exchange whose range epoch is `t_ns`.

    The recorder dates a $CAMPR at its host time minus the one-way travel
    time (the instant the remote modem replied), so for a range epoch `t_ns`
    the command goes out at t - owtt - turnaround and the reply is logged at
    t + owtt.
    """
    owtt_ns = round(one_way_travel_time_s * NS)
    t_cmd = int(t_ns) - owtt_ns - round(turnaround_s * NS)
    return [
        host_line(t_cmd, encode_ccmpc(src, dest)),
        host_line(t_cmd + 5_000_000, encode_campc(src, dest)),
        host_line(int(t_ns) + owtt_ns, encode_campr(dest, src, one_way_travel_time_s, round_trip)),
    ]
