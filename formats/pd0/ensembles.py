"""Teledyne RDI PD0 binary ensembles: decode (fast path) and encode (simulation).

Layout (all little-endian) from the RDI WorkHorse / Pathfinder "PD0 output
data format" chapters:

* header ``7F 7F``, uint16 ensemble byte count (checksum excluded), spare,
  number of data types, then one uint16 offset per data type;
* data types identified by their first uint16: fixed leader 0x0000,
  variable leader 0x0080, velocity 0x0100, correlation 0x0200, echo 0x0300,
  percent good 0x0400, status 0x0500, bottom track 0x0600; anything else
  (VmDAS 0x2000, WinRiver 0x21xx, Pathfinder 0x5803/0x2013/0x3001, ...) is
  listed in ``Ensemble.data_ids`` and skipped: the offset table locates every
  type, so unknown ones never need their size;
* a uint16 checksum (sum of every byte of the ensemble, modulo 65536).

A type's length is the distance to the next offset, so firmware variants
with shorter or longer leaders are read field by field as far as they go.

Bottom-track conventions (Pathfinder DVL Guide, "Special output data
formats"): PD0 bottom-track velocity is the velocity of the BOTTOM relative
to the instrument (the vehicle velocity negated); bad velocity is -32768
(0x8000); the per-beam range is the VERTICAL range in cm (0 = no bottom),
extended by an MSB byte per beam in newer firmware (+65536 cm per count).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from functools import lru_cache

import numpy as np

from ..records import Reject, Where
from ..units import NS

HEADER = b"\x7f\x7f"
BAD_VELOCITY = -32768
FIXED_ID, VARIABLE_ID, VELOCITY_ID, BOTTOM_ID = 0x0000, 0x0080, 0x0100, 0x0600
COORDINATES = ("beam", "instrument", "ship", "earth")
_FREQ_KHZ = (75, 150, 300, 600, 1200, 2400, 38, 0)
_ANGLES = (15.0, 20.0, 30.0, math.nan)
MAX_DATA_TYPES = 64

_HDR = struct.Struct("<HHBB")
_FIXED = struct.Struct("<HBBHBBBBHHHBBBBHBBBBhhBBHHBBBBH")  # bytes 0..41
_VAR = struct.Struct("<HHBBBBBBBBHHHHhhHh")  # bytes 0..27
_Y2K = struct.Struct("<8B")  # bytes 57..64
_BT = struct.Struct("<HHHBBBBH4x4H4h4B4B4B")  # bytes 0..43


@dataclass(frozen=True, slots=True)
class FixedLeader:
    """Instrument configuration (data type 0x0000)."""

    firmware: tuple[int, int]
    system_config: int
    n_beams: int
    n_cells: int
    pings_per_ensemble: int
    cell_size_m: float
    blank_m: float
    coord_transform: int  # EX byte: bits 4-3 coordinates, 2 tilts, 1 3-beam, 0 bin mapping
    heading_alignment_deg: float
    heading_bias_deg: float
    bin1_distance_m: float
    beam_angle_deg: float  # from byte 58 when present, else the system-config bits (NaN: "other")
    frequency_khz: int
    upward: bool
    serial_number: int | None = None

    @property
    def coordinates(self) -> str:
        """'beam', 'instrument', 'ship' or 'earth' from the EX coordinate bits."""
        return COORDINATES[(self.coord_transform >> 3) & 3]

    @property
    def convex(self) -> bool:
        """Convex transducer head (system-config bit 3); sets the beam-transform sign."""
        return bool(self.system_config & 0x08)


@dataclass(frozen=True, slots=True)
class VariableLeader:
    """Per-ensemble state (data type 0x0080): number, RTC, sensors."""

    ensemble_number: int
    rtc: tuple[int, ...]  # yy, mm, dd, HH, MM, SS, hundredths as written
    y2k_rtc: tuple[int, ...] | None  # century, yy, mm, dd, HH, MM, SS, hundredths
    time_ns: int | None  # UTC from the Y2K RTC when present, else the RTC; None if invalid
    bit_result: int
    sound_speed_mps: float
    depth_m: float
    heading_deg: float
    pitch_deg: float
    roll_deg: float
    salinity_ppt: float
    temperature_c: float
    pressure_dbar: float = math.nan


@dataclass(frozen=True, slots=True)
class BottomTrack:
    """Bottom-track data (0x0600): bottom velocity relative to the instrument, vertical ranges."""

    pings: int
    velocity_mps: tuple[float, float, float, float]  # in the EX coordinates; NaN where 0x8000
    range_m: tuple[float, float, float, float]  # vertical, per beam; NaN where 0 (no bottom)
    correlation: tuple[int, ...]
    amplitude: tuple[int, ...]
    percent_good: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class Ensemble:
    """One checksum-verified PD0 ensemble."""

    where: Where
    data_ids: tuple[int, ...]
    fixed: FixedLeader | None
    variable: VariableLeader | None
    bottom_track: BottomTrack | None
    # water-profile velocity (cells x beams, m/s, NaN bad); only with decode(profiles=True)
    velocity_profile: np.ndarray | None = field(default=None, compare=False)

    @property
    def time_ns(self) -> int | None:
        """Ensemble time (UTC ns, no clock offset) from the variable leader's RTC."""
        return self.variable.time_ns if self.variable is not None else None


def checksum(data: bytes | memoryview) -> int:
    """PD0 checksum: the sum of the bytes modulo 65536."""
    return int(np.frombuffer(data, np.uint8).sum(dtype=np.uint64)) & 0xFFFF


def rtc_to_ns(year: int, month: int, day: int, hour: int, minute: int, second: int,
              hundredths: int) -> int | None:
    """UTC ns for an RTC reading, or None when a field is out of range."""
    try:
        dt = datetime(year, month, day, hour, minute, second, tzinfo=UTC)
    except ValueError:
        return None
    if not 0 <= hundredths <= 99:
        return None
    return int(dt.timestamp()) * NS + hundredths * 10_000_000


def _two_digit_year(yy: int) -> int:
    # the pre-Y2K RTC holds two digits; RDI instruments post-date 1980
    return 2000 + yy if yy < 80 else 1900 + yy


def parse_fixed(buf: bytes, start: int, length: int) -> FixedLeader | None:
    """Fixed leader from `length` bytes at `start`; None when shorter than the 42-byte core."""
    if length < _FIXED.size:
        return None
    f = _FIXED.unpack_from(buf, start)
    config = f[3]
    angle = _ANGLES[(config >> 8) & 3]
    if length >= 59 and buf[start + 58]:
        angle = float(buf[start + 58])
    serial = struct.unpack_from("<I", buf, start + 54)[0] if length >= 58 else None
    return FixedLeader(
        firmware=(f[1], f[2]), system_config=config, n_beams=f[6], n_cells=f[7],
        pings_per_ensemble=f[8], cell_size_m=f[9] / 100, blank_m=f[10] / 100,
        coord_transform=f[19], heading_alignment_deg=f[20] / 100, heading_bias_deg=f[21] / 100,
        bin1_distance_m=f[24] / 100, beam_angle_deg=angle, frequency_khz=_FREQ_KHZ[config & 7],
        upward=bool(config & 0x80), serial_number=serial,
    )


@lru_cache(maxsize=16)
def _fixed_cached(raw: bytes) -> FixedLeader | None:
    # the fixed leader repeats byte for byte in every ensemble of a deployment
    return parse_fixed(raw, 0, len(raw))


def parse_variable(buf: bytes, start: int, length: int) -> VariableLeader | None:
    """Variable leader; the Y2K RTC (bytes 57-64) is used when present and plausible."""
    if length < _VAR.size:
        return None
    v = _VAR.unpack_from(buf, start)
    rtc = v[2:9]
    y2k = None
    time_ns = None
    if length >= 65:
        y2k = _Y2K.unpack_from(buf, start + 57)
        if 19 <= y2k[0] <= 21:
            time_ns = rtc_to_ns(y2k[0] * 100 + y2k[1], *y2k[2:])
    if time_ns is None:
        time_ns = rtc_to_ns(_two_digit_year(rtc[0]), *rtc[1:])
    pressure = math.nan
    if length >= 52:
        pressure = struct.unpack_from("<I", buf, start + 48)[0] * 0.001  # decapascal -> dbar
    return VariableLeader(
        ensemble_number=v[1] + 65536 * v[9], rtc=tuple(rtc), y2k_rtc=y2k, time_ns=time_ns,
        bit_result=v[10], sound_speed_mps=float(v[11]), depth_m=v[12] / 10,
        heading_deg=v[13] / 100, pitch_deg=v[14] / 100, roll_deg=v[15] / 100,
        salinity_ppt=float(v[16]), temperature_c=v[17] / 100, pressure_dbar=pressure,
    )


def parse_bottom(buf: bytes, start: int, length: int) -> BottomTrack | None:
    """Bottom track; ranges include the MSB bytes (77-80) when the type is long enough."""
    if length < _BT.size:
        return None
    b = _BT.unpack_from(buf, start)
    ranges_cm = list(b[8:12])
    if length >= 81:
        for k in range(4):
            ranges_cm[k] += buf[start + 77 + k] * 65536
    v1, v2, v3, v4 = (math.nan if x == BAD_VELOCITY else x / 1000 for x in b[12:16])
    r1, r2, r3, r4 = (r / 100 if r else math.nan for r in ranges_cm)
    return BottomTrack(b[1], (v1, v2, v3, v4), (r1, r2, r3, r4), b[16:20], b[20:24], b[24:28])


def _parse_profile(buf: bytes, start: int, length: int, fixed: FixedLeader | None) -> np.ndarray:
    beams = fixed.n_beams if fixed is not None and fixed.n_beams else 4
    count = (length - 2) // 2
    if fixed is not None and fixed.n_cells:
        count = min(count, fixed.n_cells * beams)
    count -= count % beams
    raw = np.frombuffer(buf, "<i2", count, start + 2)
    vel = np.where(raw == BAD_VELOCITY, np.nan, raw / 1000.0)
    return vel.reshape(-1, beams)


def _parse_ensemble(buf: bytes, i: int, nbytes: int, ndt: int, profiles: bool) -> Ensemble:
    offsets = struct.unpack_from(f"<{ndt}H", buf, i + 6)
    ends = sorted(set(offsets) | {nbytes})
    ids: list[int] = []
    fixed = variable = bottom = profile = None
    for off in offsets:
        if off < 6 + 2 * ndt or off + 2 > nbytes:
            raise ValueError(f"data-type offset {off} outside the ensemble")
        length = ends[ends.index(off) + 1] - off
        start = i + off
        tid = buf[start] | buf[start + 1] << 8
        ids.append(tid)
        if tid == FIXED_ID:
            fixed = _fixed_cached(buf[start : start + length])
        elif tid == VARIABLE_ID:
            variable = parse_variable(buf, start, length)
        elif tid == BOTTOM_ID:
            bottom = parse_bottom(buf, start, length)
        elif tid == VELOCITY_ID and profiles:
            profile = _parse_profile(buf, start, length, fixed)
    return Ensemble(Where(i), tuple(ids), fixed, variable, bottom, profile)


def _frame_problem(buf: bytes, i: int) -> tuple[str, int, int] | None:
    """Why the header at `i` cannot start an ensemble (reason, nbytes, ndt) or None if it can."""
    if i + 6 > len(buf):
        return ("truncated header", 0, 0)
    nbytes, _spare, ndt = struct.unpack_from("<HBB", buf, i + 2)
    if ndt == 0 or ndt > MAX_DATA_TYPES or nbytes < 6 + 2 * ndt + 2:
        return (f"implausible header (bytes={nbytes}, data types={ndt})", nbytes, ndt)
    if i + nbytes + 2 > len(buf):
        return (f"truncated ensemble: {len(buf) - i} of {nbytes + 2} bytes", nbytes, ndt)
    return None


def decode(data: bytes, *, profiles: bool = False) -> Iterator[Ensemble | Reject]:
    """Yield every ensemble in a PD0 byte stream, resyncing on 7F 7F after damage.

    Bytes between ensembles are reported as one Reject per gap; an ensemble
    with a bad checksum is one Reject (bad_checksum) and the search resumes
    just after its header. `profiles=True` also decodes water-profile velocity.
    """
    buf = bytes(data)
    view = memoryview(buf)

    def intact(i: int, nbytes: int) -> bool:
        return checksum(view[i : i + nbytes]) == struct.unpack_from("<H", buf, i + nbytes)[0]

    pos = 0
    while True:
        rejects, frame = next_frame(buf, pos, intact)
        yield from rejects
        if frame is None:
            return
        i, nbytes, ndt = frame
        try:
            yield _parse_ensemble(buf, i, nbytes, ndt, profiles)
        except (struct.error, ValueError, IndexError) as exc:
            yield Reject(Where(i), f"malformed ensemble: {exc}")
        pos = i + nbytes + 2


def next_frame(buf: bytes, pos: int, intact: Callable[[int, int], bool],
               ) -> tuple[list[Reject], tuple[int, int, int] | None]:
    """The next whole ensemble from `pos`: Rejects for what lies before it, and (offset, bytes, data types) or None.

    Bytes between ensembles are one Reject per gap; an ensemble whose header
    is damaged or whose checksum fails (`intact(offset, nbytes)` false) is one
    Reject, and the search resumes just after its header. Shared by `decode`
    and `pd0_blocks.scan`, which check checksums differently.
    """
    rejects: list[Reject] = []
    gap_reported = False
    while True:
        i = buf.find(HEADER, pos)
        if i < 0:
            if pos < len(buf) and not gap_reported:
                rejects.append(Reject(Where(pos), f"{len(buf) - pos} trailing bytes without an ensemble header"))
            return rejects, None
        problem = _frame_problem(buf, i)
        if problem is None:
            nbytes, ndt = struct.unpack_from("<H", buf, i + 2)[0], buf[i + 5]
            if not intact(i, nbytes):
                problem = ("bad ensemble checksum", nbytes, ndt)
        if problem is not None:
            if i > pos and not gap_reported:
                rejects.append(Reject(Where(pos), f"{i - pos} bytes of noise before a header"))
            rejects.append(Reject(Where(i), problem[0], bad_checksum=problem[0].startswith("bad")))
            pos, gap_reported = i + 2, True
            continue
        if i > pos and not gap_reported:
            rejects.append(Reject(Where(pos), f"{i - pos} bytes of noise between ensembles"))
        return rejects, (i, nbytes, ndt)


# --- encoding ----------------------------------------------------------------------------


def _mm(v: float) -> int:
    if not math.isfinite(v):
        return BAD_VELOCITY
    return max(-32767, min(32767, round(v * 1000)))


def encode_fixed(*, n_beams: int = 4, n_cells: int = 0, coordinates: str = "ship",
                 beam_angle_deg: int = 30, frequency_khz: int = 600, upward: bool = False,
                 convex: bool = True, cell_size_m: float = 1.0, blank_m: float = 0.5,
                 bin1_distance_m: float = 1.5, pings: int = 1, serial_number: int = 0,
                 firmware: tuple[int, int] = (51, 30), tilts_used: bool = True) -> bytes:
    """A 59-byte fixed leader (WorkHorse/Pathfinder layout, beam angle in byte 58)."""
    freq = _FREQ_KHZ.index(frequency_khz) if frequency_khz in _FREQ_KHZ[:6] else 3
    angle_bits = {15: 0, 20: 1, 30: 2}.get(int(beam_angle_deg), 3)
    config = freq | (0x08 if convex else 0) | 0x40 | (0x80 if upward else 0)
    config |= (angle_bits | 0x40) << 8  # 0x4 in bits 12-15: 4-beam Janus
    ex = (COORDINATES.index(coordinates) << 3) | (0x04 if tilts_used else 0) | 0x02
    core = _FIXED.pack(
        FIXED_ID, firmware[0], firmware[1], config, 0, 1, n_beams, n_cells, pings,
        round(cell_size_m * 100), round(blank_m * 100), 1, 64, 1, 0, 2000, 0, 0, 0, ex,
        0, 0, 0x7D, 0x3D, round(bin1_distance_m * 100), 0, 1, 5, 50, 0, 0,
    )
    return core + bytes(8) + struct.pack("<HBBIB", 0, 255, 0, serial_number, int(beam_angle_deg))


def encode_variable(time_ns: int, ensemble_number: int, *, sound_speed_mps: float = 1500.0,
                    depth_m: float = 0.0, heading_deg: float = 0.0, pitch_deg: float = 0.0,
                    roll_deg: float = 0.0, salinity_ppt: float = 0.0, temperature_c: float = 10.0,
                    pressure_dbar: float = 0.0, y2k: bool = True) -> bytes:
    """A variable leader with both RTCs (65 bytes), or the 58-byte pre-Y2K form; time to 0.01 s."""
    sec, rem = divmod(int(time_ns), NS)
    dt = datetime.fromtimestamp(sec, tz=UTC)
    hund = rem // 10_000_000
    n = int(ensemble_number)
    head = _VAR.pack(
        VARIABLE_ID, n & 0xFFFF, dt.year % 100, dt.month, dt.day, dt.hour, dt.minute,
        dt.second, hund, (n >> 16) & 0xFF, 0, round(sound_speed_mps), round(depth_m * 10),
        round((heading_deg % 360) * 100) % 36000, round(pitch_deg * 100), round(roll_deg * 100),
        round(salinity_ppt), round(temperature_c * 100),
    )
    tail = bytes(20) + struct.pack("<II", round(pressure_dbar * 1000), 0) + bytes(1)
    if y2k:
        tail += _Y2K.pack(dt.year // 100, dt.year % 100, dt.month, dt.day, dt.hour, dt.minute,
                          dt.second, hund)
    else:
        tail += bytes(1)
    return head + tail


def encode_bottom(velocity_mps: Sequence[float], range_m: Sequence[float], *, pings: int = 1,
                  correlation: Sequence[int] = (250, 250, 250, 250),
                  amplitude: Sequence[int] = (80, 80, 80, 80),
                  percent_good: Sequence[int] = (100, 100, 100, 100), msb: bool = True) -> bytes:
    """An 85-byte bottom-track type (81 without the range MSB bytes): mm/s and cm, 0x8000 bad."""
    cm = [round(r * 100) if math.isfinite(r) and r > 0 else 0 for r in range_m]
    cm = [min(c, 0xFFFFFF) for c in cm]
    vel = [_mm(v) for v in velocity_mps]
    body = _BT.pack(BOTTOM_ID, pings, 0, 220, 30, 0, 5, 1000, *[c & 0xFFFF for c in cm], *vel,
                    *correlation, *amplitude, *percent_good)
    body += struct.pack("<HHH", 20, 80, 160) + bytes(8 + 12) + struct.pack("<H", 0) + bytes(5)
    if msb:
        body += bytes(c >> 16 for c in cm) + bytes(4)
    return body


def encode_profile(velocity_mps: np.ndarray) -> bytes:
    """A velocity type (0x0100) from a cells x beams array in m/s (NaN -> 0x8000)."""
    v = np.asarray(velocity_mps, dtype=float)
    raw = np.where(np.isfinite(v), np.clip(np.round(v * 1000), -32767, 32767), BAD_VELOCITY)
    return struct.pack("<H", VELOCITY_ID) + raw.astype("<i2").tobytes()


def assemble(types: Sequence[bytes]) -> bytes:
    """Header, offset table, the data types and the checksum: one PD0 ensemble."""
    head_len = 6 + 2 * len(types)
    offsets, off = [], head_len
    for t in types:
        offsets.append(off)
        off += len(t)
    body = _HDR.pack(0x7F7F, off, 0, len(types)) + struct.pack(f"<{len(types)}H", *offsets)
    body += b"".join(types)
    return body + struct.pack("<H", checksum(body))


def encode_ensemble(time_ns: int, ensemble_number: int, velocity_mps: Sequence[float],
                    range_m: Sequence[float], *, coordinates: str = "ship",
                    beam_angle_deg: int = 30, sound_speed_mps: float = 1500.0,
                    depth_m: float = 0.0, heading_deg: float = 0.0, pitch_deg: float = 0.0,
                    roll_deg: float = 0.0, temperature_c: float = 10.0,
                    salinity_ppt: float = 0.0, profile: np.ndarray | None = None,
                    extra: Sequence[bytes] = (), include_fixed: bool = True,
                    y2k: bool = True, serial_number: int = 0) -> bytes:
    """One valid PD0 ensemble: fixed leader, variable leader (RTC = time_ns), bottom track.

    `velocity_mps` are the four bottom-track values AS PD0 STORES THEM in
    `coordinates` (the bottom relative to the instrument; NaN -> 0x8000); use
    `bottom_velocity_from_frd` to get them from a vehicle's body velocity.
    `range_m` are the four vertical ranges (NaN or <= 0: no bottom). `profile`
    (cells x 4, m/s) adds a velocity type; `extra` appends raw data types
    (e.g. vendor types) before the checksum.
    """
    n_cells = 0 if profile is None else int(np.asarray(profile).shape[0])
    types = []
    if include_fixed:
        types.append(encode_fixed(n_cells=n_cells, coordinates=coordinates,
                                  beam_angle_deg=beam_angle_deg, serial_number=serial_number))
    types.append(encode_variable(
        time_ns, ensemble_number, sound_speed_mps=sound_speed_mps, depth_m=depth_m,
        heading_deg=heading_deg, pitch_deg=pitch_deg, roll_deg=roll_deg,
        salinity_ppt=salinity_ppt, temperature_c=temperature_c, y2k=y2k))
    if profile is not None:
        types.append(encode_profile(profile))
    types.append(encode_bottom(velocity_mps, range_m))
    types.extend(extra)
    return assemble(types)
