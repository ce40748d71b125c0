"""Teledyne RDI PD4 and PD5 binary DVL output: decode and encode.

Layout (Pathfinder DVL Guide, "Pathfinder Output Data Format (PD4/PD5)"),
little-endian, 0-based bytes:

    0 0x7D  1 structure (0 PD4, 1 PD5)  2-3 byte count (checksum excluded)
    4 system config (bits 7-6: 00 beam, 01 instrument, 10 ship, 11 earth;
      bit 5 tilts used; bit 4 3-beam solution)
    5-12  bottom velocity x, y, z, error (int16 mm/s, -32768 bad)
    13-20 beam 1-4 range to bottom (uint16 cm, 0 = no detection)
    21    bottom status   22-29 reference-layer velocity   30-33 layer start/end (dm)
    34    layer status    35-38 time of first ping hh mm ss hundredths
    39-40 BIT   41-42 speed of sound (m/s)   43-44 temperature (0.01 °C)
    PD4: 45-46 checksum.   PD5: 45 salinity, 46-47 depth (dm), 48-53 pitch, roll
    (int16), heading (uint16) in 0.01°, 54-69 distance made good over the bottom
    E/N/U/error (int32 dm), 70-85 the same over the reference layer, 86-87 checksum.

Unlike PD0, PD4/PD5 report the VESSEL moving over a stationary bottom (same
guide, "Special output data formats"), so no negation is needed. The format
carries only a time of day (first ping): the recorder dates it with
`recorders.clock.DayClock`.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from .pd0.frames import beam_to_instrument
from .records import Reject, Where

SYNC = 0x7D
BAD_VELOCITY = -32768
COORDINATES = ("beam", "instrument", "ship", "earth")
PD4_BYTES, PD5_BYTES = 45, 86
_NOT_HEADER = "not a PD4/PD5 header"

_CORE = struct.Struct("<BBHB4h4HB4hHHB4BHHh")  # bytes 0..44
_PD5 = struct.Struct("<BHhhH4i4i")  # bytes 45..85


@dataclass(frozen=True, slots=True)
class DvlOutput:
    """One PD4 or PD5 record: vessel velocity over the bottom and ranges."""

    where: Where
    structure: int  # 0 = PD4, 1 = PD5
    system_config: int
    velocity_mps: tuple[float, float, float, float]  # x, y, z, error in `coordinates`; NaN bad
    range_m: tuple[float, float, float, float]  # beam 1-4 (vertical, as PD0); NaN none
    bottom_status: int
    reference_velocity_mps: tuple[float, float, float, float]
    tod_s: float  # time of first ping, seconds of the day
    bit_result: int
    sound_speed_mps: float
    temperature_c: float
    salinity_ppt: float = math.nan
    depth_m: float = math.nan
    pitch_deg: float = math.nan
    roll_deg: float = math.nan
    heading_deg: float = math.nan
    dmg_bottom_m: tuple[float, ...] = ()  # east, north, up, error (PD5 only)
    dmg_reference_m: tuple[float, ...] = ()

    @property
    def coordinates(self) -> str:
        """'beam', 'instrument', 'ship' or 'earth' from config bits 7-6."""
        return COORDINATES[(self.system_config >> 6) & 3]


def _vel(raw: Sequence[int]) -> tuple[float, float, float, float]:
    v1, v2, v3, v4 = (math.nan if x == BAD_VELOCITY else x / 1000 for x in raw)
    return v1, v2, v3, v4


def _parse(buf: bytes, i: int, nbytes: int) -> DvlOutput:
    c = _CORE.unpack_from(buf, i)
    hh, mm, ss, hund = c[20:24]
    if hh > 23 or mm > 59 or ss > 60 or hund > 99:
        raise ValueError(f"time of first ping {hh:02d}:{mm:02d}:{ss:02d}.{hund:02d} out of range")
    rec = dict(
        where=Where(i), structure=c[1], system_config=c[3], velocity_mps=_vel(c[4:8]),
        range_m=tuple(r / 100 if r else math.nan for r in c[8:12]), bottom_status=c[12],
        reference_velocity_mps=_vel(c[13:17]), tod_s=hh * 3600 + mm * 60 + ss + hund / 100,
        bit_result=c[24], sound_speed_mps=float(c[25]), temperature_c=c[26] / 100,
    )
    if c[1] == 1 and nbytes >= PD5_BYTES:
        p = _PD5.unpack_from(buf, i + 45)
        rec.update(salinity_ppt=float(p[0]), depth_m=p[1] / 10, pitch_deg=p[2] / 100,
                   roll_deg=p[3] / 100, heading_deg=p[4] / 100,
                   dmg_bottom_m=tuple(d / 10 for d in p[5:9]),
                   dmg_reference_m=tuple(d / 10 for d in p[9:13]))
    return DvlOutput(**rec)


def _candidate(buf: bytes, i: int) -> tuple[str | None, int]:
    """(problem or None, byte count) for a 0x7D at `i`."""
    if i + 4 > len(buf):
        return "truncated header", 0
    structure, nbytes = buf[i + 1], struct.unpack_from("<H", buf, i + 2)[0]
    if structure not in (0, 1) or not PD4_BYTES <= nbytes <= 512:
        return _NOT_HEADER, nbytes
    if i + nbytes + 2 > len(buf):
        return f"truncated record: {len(buf) - i} of {nbytes + 2} bytes", nbytes
    if sum(memoryview(buf)[i : i + nbytes]) & 0xFFFF != struct.unpack_from("<H", buf, i + nbytes)[0]:
        return "bad checksum", nbytes
    return None, nbytes


def decode(data: bytes) -> Iterator[DvlOutput | Reject]:
    """Yield every PD4/PD5 record, resyncing on 0x7D; noise gaps are one Reject each."""
    buf = bytes(data)
    pos = 0
    gap_start: int | None = 0  # the first byte not yet accounted for (None: none)
    while True:
        i = buf.find(b"\x7d", pos)
        if i < 0:
            if gap_start is not None and gap_start < len(buf):
                yield Reject(Where(gap_start), f"{len(buf) - gap_start} trailing bytes without a record")
            return
        problem, nbytes = _candidate(buf, i)
        if problem == _NOT_HEADER:
            pos = i + 1  # a stray 0x7D inside noise: the gap is reported when it ends
            continue
        if gap_start is not None and i > gap_start:
            yield Reject(Where(gap_start), f"{i - gap_start} bytes of noise before a record")
        if problem is not None:
            yield Reject(Where(i), problem, bad_checksum=problem == "bad checksum")
            pos, gap_start = i + 1, None
            continue
        try:
            yield _parse(buf, i, nbytes)
        except (struct.error, ValueError) as exc:
            yield Reject(Where(i), f"malformed record: {exc}")
        pos = gap_start = i + nbytes + 2


def vehicle_velocity(coordinates: str, velocity: Sequence[float], beam_angle_deg: float = 30.0
                     ) -> tuple[str, float, float, float, float]:
    """(frame, x, y, z, error) from PD4/PD5 vessel velocity.

    Ship (x port→starboard, y aft→forward, z to surface) becomes BODY_FRD as
    (y, x, -z); earth (east, north, up) becomes EARTH_NED the same way;
    instrument is kept; beam velocities go through the Janus transform
    (`formats.pd0.frames.beam_to_instrument`, convex head assumed) to INSTRUMENT.
    """
    v = tuple(velocity)
    if coordinates == "beam":
        v = beam_to_instrument(v, beam_angle_deg, True)
        coordinates = "instrument"
    if coordinates == "instrument":
        return ("INSTRUMENT", v[0], v[1], v[2], v[3])
    frame = "BODY_FRD" if coordinates == "ship" else "EARTH_NED"
    return (frame, v[1], v[0], -v[2], v[3])


def _mm(v: float) -> int:
    return BAD_VELOCITY if not math.isfinite(v) else max(-32767, min(32767, round(v * 1000)))


def encode(tod_s: float, velocity_mps: Sequence[float], range_m: Sequence[float], *,
           coordinates: str = "ship", pd5: bool = False, sound_speed_mps: float = 1500.0,
           temperature_c: float = 10.0, depth_m: float = 0.0, heading_deg: float = 0.0,
           pitch_deg: float = 0.0, roll_deg: float = 0.0, salinity_ppt: float = 0.0,
           dmg_bottom_m: Sequence[float] = (0.0, 0.0, 0.0, 0.0)) -> bytes:
    """One PD4 (or PD5) record with its checksum; velocities are the vessel's, in `coordinates`."""
    hund_total = int(round(tod_s * 100)) % 8_640_000
    hh, rem = divmod(hund_total, 360_000)
    mm, rem = divmod(rem, 6000)
    ss, hund = divmod(rem, 100)
    config = (COORDINATES.index(coordinates) << 6) | 0x20 | 0x03
    cm = [round(r * 100) if math.isfinite(r) and r > 0 else 0 for r in range_m]
    body = _CORE.pack(
        SYNC, 1 if pd5 else 0, PD5_BYTES if pd5 else PD4_BYTES, config,
        *[_mm(v) for v in velocity_mps], *[min(c, 65535) for c in cm], 0,
        *([BAD_VELOCITY] * 4), 0, 0, 0, hh, mm, ss, hund, 0, round(sound_speed_mps),
        round(temperature_c * 100),
    )
    if pd5:
        body += _PD5.pack(round(salinity_ppt), round(depth_m * 10), round(pitch_deg * 100),
                          round(roll_deg * 100), round((heading_deg % 360) * 100) % 36000,
                          *[round(d * 10) for d in dmg_bottom_m], 0, 0, 0, 0)
    return body + struct.pack("<H", sum(body) & 0xFFFF)
