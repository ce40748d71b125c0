"""NMEA records of one epoch: its time, date, position and motion (the record-based rules).

`recorders.ins.convert_nmea` and the reference converter in
tests/reference_converters.py work on records grouped by
`recorders.epochs.group_epochs` with `nmea_key`; `recorders.gps`'s fast
paths apply the same rules to scanned values and columns.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

from formats.log_blocks import LogText
from formats.nmea.sentences import (
    KNOT_MPS,
    Gga,
    Gll,
    Gst,
    Hdt,
    NmeaRecord,
    Rmc,
    Ths,
    Vtg,
    Zda,
    decode,
)
from formats.records import Reject

from .base import LogContext
from .clock import DayClock
from .epochs import group_epochs, host_time_ns

NAN = math.nan
NO_DATE = "no date for time of day {:.3f} s: no RMC/ZDA date yet and no [trial] date in the manifest"
NO_TIME = "no time: the epoch has no timed sentence and no host timestamp"


def record_epochs(data: LogText, prefix: str) -> Iterator[list[NmeaRecord] | Reject]:
    """A log's NMEA records (`sentences.decode`) grouped into epochs by `nmea_key`; Rejects pass through."""
    epochs: Iterator[list[NmeaRecord] | Reject] = group_epochs(decode(data, prefix), nmea_key)
    return epochs


def nmea_key(rec: NmeaRecord) -> tuple[str, int | None]:
    """Epoch key of an NMEA record: its sentence type and time of day in ms (None if untimed)."""
    t = getattr(rec, "time_s", NAN)
    return type(rec).__name__, (None if math.isnan(t) else round(t * 1000))


@dataclass(frozen=True, slots=True)
class NmeaEpoch:
    """One epoch's records in arrival order, and its record of each sentence type (None if absent)."""

    records: list[NmeaRecord]
    gga: Gga | None
    rmc: Rmc | None
    zda: Zda | None
    vtg: Vtg | None
    gst: Gst | None
    hdt: Hdt | None
    ths: Ths | None
    gll: Gll | None

    @classmethod
    def of(cls, records: list[NmeaRecord]) -> NmeaEpoch:
        """The epoch of a group of records (each sentence type at most once, as `group_epochs` makes them)."""
        gga = rmc = zda = vtg = gst = hdt = ths = gll = None
        for r in records:
            if isinstance(r, Gga):
                gga = r
            elif isinstance(r, Rmc):
                rmc = r
            elif isinstance(r, Zda):
                zda = r
            elif isinstance(r, Vtg):
                vtg = r
            elif isinstance(r, Gst):
                gst = r
            elif isinstance(r, Hdt):
                hdt = r
            elif isinstance(r, Ths):
                ths = r
            elif isinstance(r, Gll):
                gll = r
        return cls(records, gga, rmc, zda, vtg, gst, hdt, ths, gll)

    @property
    def only_zda(self) -> bool:
        """True for an epoch of a ZDA alone (a date, nothing to emit)."""
        return len(self.records) == 1 and self.zda is not None


def nmea_update_date(epoch: NmeaEpoch, clock: DayClock) -> None:
    """Give the clock the date of the epoch's ZDA, else of a valid RMC (an invalid RMC's date may be stale)."""
    if epoch.zda is not None and epoch.zda.date is not None:
        clock.set_date(epoch.zda.date, epoch.zda.time_s)
    elif epoch.rmc is not None and epoch.rmc.date is not None and epoch.rmc.valid:
        clock.set_date(epoch.rmc.date, epoch.rmc.time_s)


def nmea_epoch_time(epoch: NmeaEpoch, clock: DayClock, ctx: LogContext) -> int | Reject:
    """UTC ns (offset applied) of an NMEA epoch, updating the clock's date; a Reject when unknown."""
    nmea_update_date(epoch, clock)
    for rec in epoch.records:
        t = getattr(rec, "time_s", NAN)
        if not math.isnan(t):
            resolved = clock.resolve(t)
            if resolved is None:
                return Reject(rec.where, NO_DATE.format(t))
            return resolved
    host = host_time_ns(epoch.records, ctx)
    if host is None:
        return Reject(epoch.records[0].where, NO_TIME)
    return host


def nmea_position(epoch: NmeaEpoch) -> Gga | Gll | Rmc | None:
    """The epoch's position record: GGA with a fix, else a valid GLL, else a valid RMC."""
    g = epoch.gga
    if g is not None and g.quality != 0 and not (math.isnan(g.latitude) or math.isnan(g.longitude)):
        return g
    for rec in (epoch.gll, epoch.rmc):
        if rec is not None and rec.valid and not (math.isnan(rec.latitude) or math.isnan(rec.longitude)):
            return rec
    return None


def vtg_valid(mode: str) -> bool:
    """Whether a VTG's values may be used: its NMEA 2.3 mode indicator is not 'N' (data not valid) or 'V'."""
    return mode != "N" and mode != "V"


def vtg_speed(knots: float, kmh: float) -> float:
    """A VTG's speed over ground in m/s: from knots, else from km/h when only that is given."""
    return kmh / 3.6 if math.isnan(knots) else knots * KNOT_MPS


def nmea_motion(epoch: NmeaEpoch) -> tuple[float, float, float]:
    """Speed over ground (m/s), course (deg true) and heading (deg true) of an epoch, NaN when absent.

    Motion from a valid VTG (`vtg_valid`), else a valid RMC (status A); heading from HDT, else THS not 'V'.
    `gnss_velocity.components` turns a finite speed and course into the epoch's velocity.
    """
    vtg, rmc = epoch.vtg, epoch.rmc
    speed = course = NAN
    if vtg is not None and vtg_valid(vtg.mode):
        speed, course = vtg_speed(vtg.speed_knots, vtg.speed_kmh), vtg.course_true_deg
    elif rmc is not None and rmc.valid:
        speed, course = rmc.speed_knots * KNOT_MPS, rmc.course_deg
    heading = NAN
    if epoch.hdt is not None:
        heading = epoch.hdt.heading_deg
    elif epoch.ths is not None and epoch.ths.mode != "V":
        heading = epoch.ths.heading_deg
    return speed, course, heading


def gga_altitude(gga: Gga) -> float:
    """Ellipsoidal height (MSL altitude plus geoid separation) when the separation is given, else MSL."""
    sep = gga.geoid_separation_m
    return gga.altitude_msl_m if math.isnan(sep) else gga.altitude_msl_m + sep
