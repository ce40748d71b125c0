"""EvoLogics S2C modem and USBL notifications (AT command interface), command or data mode.

Layouts (S2C AT command reference, as used by LSTS DUNE's Evologics driver,
the goby3 Evologics driver and EvoLogics' own evins framework):

- ``USBLLONG,<ctime>,<mtime>,<addr>,<X>,<Y>,<Z>,<E>,<N>,<U>,<roll>,<pitch>,<yaw>,
  <propagation time µs>,<rssi dB>,<integrity>,<accuracy m>``: a full fix; X/Y/Z in
  the device frame, E/N/U after attitude compensation (metres), angles in radians.
- ``USBLANGLES,<ctime>,<mtime>,<addr>,<lbearing>,<lelevation>,<bearing>,<elevation>,
  <roll>,<pitch>,<yaw>,<rssi>,<integrity>,<accuracy>``: direction only (radians).
- ``USBLPHYD,<ctime>,<mtime>,<addr>,<fix type>,<d15>,<d25>,<d35>,<d45>,<d12>,<d41>,<d32>,<d34>``:
  arrival-time differences between transducer elements, nanoseconds; 16777215
  (0xFFFFFF) marks an element pair without a measurement.
- ``USBLPHYP,<ctime>,<mtime>,<addr>,<fix type>,`` then X,Y,Z of the target from six
  element triples (123, 432, 341, 412, 153, 254).
- ``RECVIM,<len>,<src>,<dst>,<ack|noack>,<duration>,<rssi>,<integrity>,<velocity>,<data>``
  (firmware 1.6: ``...,<flag>,<bitrate>,<rssi>,<integrity>,<propagation time>,<velocity>,<data>``),
  ``RECVIMS,<len>,<src>,<dst>,<timestamp>,<duration>,<rssi>,<integrity>,<velocity>,<data>``,
  ``RECVPBM,<len>,<src>,<dst>,<duration>,<rssi>,<integrity>,<velocity>,<data>`` (1.6 adds bitrate
  and propagation time as for RECVIM); the declared length decides which layout a line has.
- ``RECVEND,<timestamp>,<duration>,<rssi>,<integrity>``, ``SENDEND,<addr>,<type>,<timestamp>,<duration>``,
  ``DELIVEREDIM,<addr>``, ``FAILEDIM,<addr>``, ``DELIVERED,<count>,<addr>``...
- ``AT?T`` reply: the propagation time (µs, one way) of the last acoustic exchange. In data
  mode it is framed ``+++AT?T:<len>:<value>``; in command mode a logger that writes the
  command line ``AT?T`` is followed by the bare number.

Data mode frames every notification as ``+++AT:<len>:<text>`` (and command replies as
``+++AT<cmd>:<len>:<reply>``); the length is checked. The modem's <ctime>/<mtime> are its
own clock (seconds since power-up), not UTC: the recorder needs host timestamps.

Phase convention (an assumption, not in the vendor reference): the four outer elements form a
cross with 1 at +x, 3 at -x, 2 at +y, 4 at -y (x east, y north when the head is aligned) and 5
in the centre, ``d_ij`` = arrival time at i minus at j. The across-array delays are then
``tau_x = t3 - t1`` and ``tau_y = t4 - t2``, and the phase differences
``phase = 2 pi f tau`` (f the carrier), which is the seed's ``psi = kappa d0 (x - x_i)/r``
(KMCDF, K.2, docs/design.md section 13) for a baseline d0 between opposite elements.
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

from ..lines import Line, iter_lines
from ..numbers import finite, integer
from ..records import Reject, Where

INVALID_DELAY = 16777215
_FRAMED = re.compile(r"\+\+\+AT([^:]*):(\d+):")
_KEYWORD = re.compile(r"[A-Z][A-Z0-9_]*(?:[ ,]|$)")
_QUERY_T = re.compile(r"\s*(?:[<>]\s*)?(?:\+\+\+)?AT\?T\s*$")
_MAX_JOIN = 8  # lines a framed payload with embedded newlines may span


@dataclass(frozen=True, slots=True)
class UsblLong:
    """USBLLONG: full USBL fix of target `address` (metres, radians, µs)."""

    where: Where
    current_time_s: float
    measurement_time_s: float
    address: int
    x_m: float
    y_m: float
    z_m: float
    east_m: float
    north_m: float
    up_m: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    propagation_time_us: float
    rssi_db: float
    integrity: float
    accuracy_m: float


@dataclass(frozen=True, slots=True)
class UsblAngles:
    """USBLANGLES: direction of target `address` in the device frame and after compensation."""

    where: Where
    current_time_s: float
    measurement_time_s: float
    address: int
    local_bearing_rad: float
    local_elevation_rad: float
    bearing_rad: float
    elevation_rad: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    rssi_db: float
    integrity: float
    accuracy_m: float


@dataclass(frozen=True, slots=True)
class UsblPhaseDelays:
    """USBLPHYD: element-pair arrival-time differences (ns; NaN where the modem had none)."""

    where: Where
    current_time_s: float
    measurement_time_s: float
    address: int
    fix_type: int
    delays_ns: tuple[float, ...]  # d15, d25, d35, d45, d12, d41, d32, d34


@dataclass(frozen=True, slots=True)
class UsblPhasePositions:
    """USBLPHYP: target X, Y, Z (m) from six element triples (123, 432, 341, 412, 153, 254)."""

    where: Where
    current_time_s: float
    measurement_time_s: float
    address: int
    fix_type: int
    positions_m: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class ReceivedIM:
    """RECVIM / RECVIMS / RECVPBM: an instant message received from `src`."""

    where: Where
    kind: str
    src: int
    dest: int
    ack: bool
    duration_us: float
    rssi_db: float
    integrity: float
    velocity_mps: float
    timestamp_us: float
    propagation_time_us: float
    payload: bytes


@dataclass(frozen=True, slots=True)
class ReceiveEnd:
    """RECVEND: end of a reception (modem timestamp µs, duration µs, rssi dB, integrity)."""

    where: Where
    timestamp_us: float
    duration_us: float
    rssi_db: float
    integrity: float


@dataclass(frozen=True, slots=True)
class SendEnd:
    """SENDEND: end of a transmission to `dest` of a given type (im, ims, pbm, ...)."""

    where: Where
    dest: int
    kind: str
    timestamp_us: float
    duration_us: float


@dataclass(frozen=True, slots=True)
class Delivery:
    """DELIVEREDIM / FAILEDIM / DELIVERED / FAILED...: delivery report for `dest`."""

    where: Where
    kind: str
    dest: int
    delivered: bool


@dataclass(frozen=True, slots=True)
class PropagationTime:
    """AT?T reply: one-way propagation time (µs) to `peer`, the last modem heard or delivered to."""

    where: Where
    propagation_time_us: float
    peer: int | None


@dataclass(frozen=True, slots=True)
class OtherNotification:
    """A well-formed line this module does not interpret (OK, RECVSTART, SENDSTART, BITRATE...)."""

    where: Where
    keyword: str
    text: str


Record = (
    UsblLong | UsblAngles | UsblPhaseDelays | UsblPhasePositions | ReceivedIM | ReceiveEnd
    | SendEnd | Delivery | PropagationTime | OtherNotification
)


def _num(text: str, name: str = "field") -> float:
    t = text.strip()
    if not t:
        raise ValueError(f"empty {name}")
    return finite(t, name)


def _addr(text: str) -> int:
    t = text.strip()
    if not t.isdigit():
        raise ValueError(f"address is not a non-negative integer: {t!r}")
    return integer(t, "address")


def _fields(parts: Sequence[str], n: int, keyword: str) -> list[float]:
    if len(parts) < n:
        raise IndexError(keyword)
    if len(parts) > n:
        raise ValueError(f"{len(parts)} fields, expected {n}")
    return [_num(p) for p in parts]


def _usbllong(w: Where, p: Sequence[str]) -> Record:
    v = _fields(p, 16, "USBLLONG")
    if v[12] < 0:
        raise ValueError(f"negative propagation time {v[12]}")
    return UsblLong(w, v[0], v[1], _addr(p[2]), *v[3:])


def _usblangles(w: Where, p: Sequence[str]) -> Record:
    v = _fields(p, 13, "USBLANGLES")
    return UsblAngles(w, v[0], v[1], _addr(p[2]), *v[3:])


def _usblphyd(w: Where, p: Sequence[str]) -> Record:
    v = _fields(p, 12, "USBLPHYD")
    delays = tuple(math.nan if abs(d) == INVALID_DELAY else d for d in v[4:])
    return UsblPhaseDelays(w, v[0], v[1], _addr(p[2]), int(v[3]), delays)


def _usblphyp(w: Where, p: Sequence[str]) -> Record:
    v = _fields(p, 22, "USBLPHYP")
    return UsblPhasePositions(w, v[0], v[1], _addr(p[2]), int(v[3]), tuple(v[4:]))


def _split_payload(body: str, n_head: int) -> tuple[list[str], str] | None:
    parts = body.split(",", n_head)
    if len(parts) < n_head + 1:
        return None
    return parts[:n_head], parts[n_head]


def _recv(w: Where, kind: str, body: str) -> Record:
    """RECVIM/RECVIMS/RECVPBM: try the current layout, then firmware 1.6's, by declared length."""
    layouts = {"RECVIM": (8, 9), "RECVIMS": (8,), "RECVPBM": (7, 8)}[kind]
    for n_head in layouts:
        split = _split_payload(body, n_head)
        if split is None or not split[0][0].strip().isdigit() or int(split[0][0]) != len(split[1]):
            continue
        h, payload = split
        old = n_head == layouts[-1] and len(layouts) == 2
        return _recv_record(w, kind, h, payload, old)
    if _split_payload(body, layouts[0]) is None:
        raise IndexError(kind)
    raise ValueError("declared payload length does not match the data")


def _recv_record(w: Where, kind: str, h: list[str], payload: str, old: bool) -> Record:
    src, dest = _addr(h[1]), _addr(h[2])
    nan = math.nan
    if kind == "RECVIMS":
        ts, dur, rssi, integ, vel = (_num(x) for x in h[3:8])
        return ReceivedIM(w, kind, src, dest, False, dur, rssi, integ, vel, ts, nan, payload.encode("latin-1"))
    flag = h[3].strip() if kind == "RECVIM" else "noack"
    if flag not in ("ack", "noack"):
        raise ValueError(f"ack flag is neither ack nor noack: {flag!r}")
    rest = [_num(x) for x in h[4 if kind == "RECVIM" else 3:]]
    if old:  # bitrate, rssi, integrity, propagation time, velocity
        return ReceivedIM(w, kind, src, dest, flag == "ack", nan, rest[1], rest[2], rest[4], nan, rest[3],
                          payload.encode("latin-1"))
    return ReceivedIM(w, kind, src, dest, flag == "ack", rest[0], rest[1], rest[2], rest[3], nan, nan,
                      payload.encode("latin-1"))


def _delivery(w: Where, kind: str, p: Sequence[str]) -> Record:
    if not p or not p[-1].strip():
        raise IndexError(kind)
    return Delivery(w, kind, _addr(p[-1]), kind.startswith("DELIVERED"))


def decode_notification(text: str, where: Where) -> Record | Reject:
    """Decode one unframed S2C notification line."""
    keyword, _, body = text.partition(",")
    keyword = keyword.strip()
    parts = body.split(",") if body else []
    try:
        if keyword == "USBLLONG":
            return _usbllong(where, parts)
        if keyword == "USBLANGLES":
            return _usblangles(where, parts)
        if keyword == "USBLPHYD":
            return _usblphyd(where, parts)
        if keyword == "USBLPHYP":
            return _usblphyp(where, parts)
        if keyword in ("RECVIM", "RECVIMS", "RECVPBM"):
            return _recv(where, keyword, body)
        if keyword == "RECVEND":
            return ReceiveEnd(where, *_fields(parts, 4, keyword))
        if keyword == "SENDEND":
            if len(parts) != 4:
                raise IndexError(keyword) if len(parts) < 4 else ValueError(f"{len(parts)} fields, expected 4")
            return SendEnd(where, _addr(parts[0]), parts[1].strip(), _num(parts[2]), _num(parts[3]))
        if keyword in ("DELIVEREDIM", "FAILEDIM", "DELIVERED", "FAILED", "DELIVEREDIMS", "FAILEDIMS"):
            return _delivery(where, keyword, parts)
    except IndexError:
        return Reject(where, f"truncated {keyword}: {len(parts)} fields")
    except (ValueError, OverflowError) as exc:
        return Reject(where, f"bad {keyword}: {exc}")
    if _KEYWORD.match(text.strip() or "-"):
        return OtherNotification(where, keyword.split(" ")[0], text)
    return Reject(where, "not an S2C notification")


class _Decoder:
    """Line-level state: a pending AT?T query, and the last peer for propagation times."""

    def __init__(self) -> None:
        self.query_pending = False
        self.peer: int | None = None

    def propagation(self, value: str, where: Where) -> Record | Reject:
        self.query_pending = False
        t = value.strip()
        if not (t.isascii() and t.isdigit()):  # '²' is a digit to isdigit(), not to float()
            return Reject(where, f"AT?T reply is not a number of microseconds: {t[:24]!r}")
        return PropagationTime(where, float(t), self.peer)

    def plain(self, text: str, where: Where) -> Record | Reject | None:
        if _QUERY_T.fullmatch(text):
            self.query_pending = True
            return None
        if self.query_pending and text.strip().isdigit():
            return self.propagation(text, where)
        self.query_pending = False
        rec = decode_notification(text, where)
        if isinstance(rec, Delivery) and rec.delivered:
            self.peer = rec.dest
        elif isinstance(rec, ReceivedIM):
            self.peer = rec.src
        return rec


class _Peek:
    """An iterator of lines with lookahead, so a frame can span lines without losing them."""

    def __init__(self, lines: Iterator[Line]) -> None:
        self._it = lines
        self._buf: deque[Line] = deque()

    def peek(self, k: int) -> Line | None:
        while len(self._buf) <= k:
            nxt = next(self._it, None)
            if nxt is None:
                return None
            self._buf.append(nxt)
        return self._buf[k]

    def drop(self, n: int) -> None:
        for _ in range(n):
            self._buf.popleft()


def _framed(peek: Callable[[int], str | None]) -> tuple[str, str, int, int] | None:
    """(command, payload, declared length, lines used) of a +++AT frame at the next line.

    `peek(k)` is the text of the k-th line from here (None past the end). A
    payload with embedded newlines (binary instant messages) spans several
    lines; they are joined only while that brings the payload to its declared length.
    """
    text = peek(0)
    assert text is not None
    start = text.find("+++AT")
    m = _FRAMED.match(text, start) if start >= 0 else None
    if m is None:
        return None
    want = int(m.group(2))
    payload, used = text[m.end():], 1
    joined = payload
    while len(joined) < want and used < _MAX_JOIN:
        nxt = peek(used)
        if nxt is None:
            break
        joined += "\n" + nxt
        used += 1
        if len(joined) == want:
            return m.group(1), joined, want, used
    return m.group(1), payload, want, 1


def decode(data: bytes, prefix: str = "auto") -> Iterator[Record | Reject]:
    """Stream S2C records and Rejects from a log (host prefixes, CRLF/LF, +++AT framing, noise)."""
    state = _Decoder()
    lines = _Peek(iter_lines(data, prefix))

    def peek(k: int) -> str | None:
        line = lines.peek(k)
        return None if line is None else line.text

    while (line := lines.peek(0)) is not None:
        framed = _framed(peek)
        if framed is None:
            lines.drop(1)
            rec = state.plain(line.text, line.where)
        else:
            command, payload, want, used = framed
            lines.drop(used)
            if len(payload) != want:
                yield Reject(line.where, f"+++AT frame declares {want} characters, has {len(payload)}")
                continue
            rec = _framed_record(state, command, payload, line.where)
        if rec is not None:
            yield rec


def _framed_record(state: _Decoder, command: str, payload: str, where: Where) -> Record | Reject | None:
    if command == "?T":
        return state.propagation(payload, where)
    if command == "":
        return state.plain(payload, where)
    return OtherNotification(where, "AT" + command, payload)


# ---- phases <-> delays (assumed cross geometry, see module docstring)

def phases_from_delays(delays_ns: Sequence[float], carrier_hz: float) -> tuple[float, float]:
    """Phase differences (rad) across the x and y element pairs from USBLPHYD delays.

    Each axis averages its available estimates: tau_x from d35 - d15, d32 - d12,
    d34 + d41 and, with the centre element midway, 2 d35 and -2 d15; tau_y likewise
    from d45 - d25, d41 + d12, d32 - d34, 2 d45 and -2 d25. NaN when none is available.
    """
    d15, d25, d35, d45, d12, d41, d32, d34 = map(float, delays_ns)
    tau_x = _nanmean((d35 - d15, d32 - d12, d34 + d41, 2 * d35, -2 * d15))
    tau_y = _nanmean((d45 - d25, d41 + d12, d32 - d34, 2 * d45, -2 * d25))
    k = 2 * math.pi * carrier_hz * 1e-9
    return k * tau_x, k * tau_y


def delays_from_phases(phase_x_rad: float, phase_y_rad: float, carrier_hz: float) -> tuple[float, ...]:
    """The eight USBLPHYD delays (ns) a cross array gives for the phase differences."""
    k = 2 * math.pi * carrier_hz * 1e-9
    hx, hy = phase_x_rad / k / 2, phase_y_rad / k / 2
    # arrival times relative to the centre element: t1=-hx, t3=+hx, t2=-hy, t4=+hy
    t1, t2, t3, t4 = -hx, -hy, hx, hy
    return (t1, t2, t3, t4, t1 - t2, t4 - t1, t3 - t2, t3 - t4)


def _nanmean(values: Sequence[float]) -> float:
    total = sum(values)
    if math.isfinite(total):  # every value finite: the mean below, without the list (the USBL hot path)
        return total / len(values)
    ok = [v for v in values if math.isfinite(v)]
    return sum(ok) / len(ok) if ok else math.nan


def bearing_from_vendor(bearing_rad: float, convention: str = "enu") -> float:
    """True bearing (deg, clockwise from north) of a vendor bearing.

    ``enu`` (default, an assumption): the vendor angle is atan2(N, E), counter-
    clockwise from east, as USBLLONG's E/N axes suggest; ``compass``: already
    clockwise from north.
    """
    deg = math.degrees(bearing_rad)
    return (90.0 - deg) % 360.0 if convention == "enu" else deg % 360.0


def bearing_to_vendor(bearing_deg: float, convention: str = "enu") -> float:
    """Inverse of `bearing_from_vendor` (radians in the vendor convention)."""
    deg = 90.0 - bearing_deg if convention == "enu" else bearing_deg
    return math.radians((deg + 180.0) % 360.0 - 180.0)


# ---- encoders (trial simulator, round-trip tests)

def _frame(text: str, framed: bool) -> str:
    return (f"+++AT:{len(text)}:{text}" if framed else text) + "\r\n"


def _f(x: float, d: int) -> str:
    return f"{x:.{d}f}"


def encode_usbllong(
    address: int, east_m: float, north_m: float, up_m: float, propagation_time_s: float, *,
    current_time_s: float = 0.0, measurement_time_s: float | None = None,
    xyz_m: tuple[float, float, float] | None = None, rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0),
    rssi_db: int = -50, integrity: int = 100, accuracy_m: float = 0.0, framed: bool = False,
) -> str:
    """USBLLONG line for a target at E/N/U metres; propagation time written in integer µs."""
    mt = current_time_s if measurement_time_s is None else measurement_time_s
    x, y, z = xyz_m if xyz_m is not None else (east_m, north_m, up_m)
    vals = [_f(current_time_s, 6), _f(mt, 6), str(address)]
    vals += [_f(v, 4) for v in (x, y, z, east_m, north_m, up_m, *rpy_rad)]
    vals += [str(round(propagation_time_s * 1e6)), str(rssi_db), str(integrity), _f(accuracy_m, 4)]
    return _frame("USBLLONG," + ",".join(vals), framed)


def encode_usblangles(
    address: int, bearing_deg: float, elevation_deg: float, *, current_time_s: float = 0.0,
    measurement_time_s: float | None = None, local: tuple[float, float] | None = None,
    rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0), rssi_db: int = -50, integrity: int = 100,
    accuracy_m: float = 0.0, convention: str = "enu", framed: bool = False,
) -> str:
    """USBLANGLES line for a true bearing / elevation in degrees (written in vendor radians)."""
    mt = current_time_s if measurement_time_s is None else measurement_time_s
    b, e = bearing_to_vendor(bearing_deg, convention), math.radians(elevation_deg)
    lb, le = local if local is not None else (b, e)
    vals = [_f(current_time_s, 6), _f(mt, 6), str(address)] + [_f(v, 6) for v in (lb, le, b, e, *rpy_rad)]
    vals += [str(rssi_db), str(integrity), _f(accuracy_m, 4)]
    return _frame("USBLANGLES," + ",".join(vals), framed)


def encode_usblphyd(
    address: int, phase_x_rad: float, phase_y_rad: float, carrier_hz: float, *,
    current_time_s: float = 0.0, measurement_time_s: float | None = None, fix_type: int = 0,
    framed: bool = False,
) -> str:
    """USBLPHYD line carrying the x/y phase differences as integer-ns element delays."""
    mt = current_time_s if measurement_time_s is None else measurement_time_s
    delays = [str(round(d)) for d in delays_from_phases(phase_x_rad, phase_y_rad, carrier_hz)]
    vals = [_f(current_time_s, 6), _f(mt, 6), str(address), str(fix_type), *delays]
    return _frame("USBLPHYD," + ",".join(vals), framed)


def encode_delivered_im(dest: int, framed: bool = False) -> str:
    """DELIVEREDIM: an instant message to `dest` was acknowledged."""
    return _frame(f"DELIVEREDIM,{dest}", framed)


def encode_propagation_time(propagation_time_s: float, framed: bool = True) -> str:
    """AT?T reply in integer µs: '+++AT?T:<len>:<µs>' (data mode) or 'AT?T' + the number."""
    us = str(round(propagation_time_s * 1e6))
    return f"+++AT?T:{len(us)}:{us}\r\n" if framed else f"AT?T\r\n{us}\r\n"


def encode_recvim(src: int, dest: int, payload: bytes, *, ack: bool = False, duration_us: int = 100000,
                  rssi_db: int = -50, integrity: int = 100, velocity_mps: float = 0.0, framed: bool = False) -> str:
    """RECVIM line (current firmware layout); payload bytes as latin-1 text: write the line as latin-1."""
    body = payload.decode("latin-1")
    head = (f"RECVIM,{len(body)},{src},{dest},{'ack' if ack else 'noack'},"
            f"{duration_us},{rssi_db},{integrity},{velocity_mps:.4f},")
    return _frame(head + body, framed)
