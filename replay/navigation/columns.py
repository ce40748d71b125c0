"""One vehicle's navigation sensors as columns (numpy arrays in mission seconds), read from an archive.

The review computes on columns, never on messages: `read_columns` makes one
pass over the vehicle's topics and keeps only the numbers it needs (8 bytes
a value), so memory grows with the samples kept, not with the messages.
Times are the archive's log times in mission seconds (seconds from the
trial start). Rows whose time or position is not finite are dropped and
counted in `VehicleColumns.dropped`; each column set is sorted by time.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from formats.mcap_blocks import MessageBlock
from formats.mcap_reader import ArchiveReader
from formats.units import NS

BODY_FRD, EARTH_NED = 1, 2  # auvreplay.DvlVelocity.Frame; INSTRUMENT (3) and UNKNOWN (0) cannot be rotated to earth

__all__ = ["BODY_FRD", "EARTH_NED", "DvlColumns", "FixColumns", "InsColumns", "SeriesColumns", "VehicleColumns",
           "read_columns"]


def _f64(values: Any) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).reshape(-1)


def _col(values: Any, n: int, dtype: Any = np.float64) -> np.ndarray:
    """A column of n rows from an array-like of n values or one scalar for all of them."""
    return np.broadcast_to(np.asarray(values, dtype=dtype).reshape(-1) if np.ndim(values) else
                           np.asarray(values, dtype=dtype), (n,)).copy()


def _sorted(t_s: np.ndarray, *cols: np.ndarray) -> tuple[np.ndarray, ...]:
    """Columns in time order (stable, so equal times keep the archive's order)."""
    order = np.argsort(t_s, kind="stable")
    return (t_s[order],) + tuple(c[order] for c in cols)


@dataclass(frozen=True)
class FixColumns:
    """GPS fixes: time (mission s), latitude and longitude (deg)."""

    t_s: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray

    @classmethod
    def build(cls, t_s: Any, lat_deg: Any, lon_deg: Any) -> FixColumns:
        """Fixes from array-likes: non-finite rows dropped, sorted by time."""
        t, la, lo = _f64(t_s), _f64(lat_deg), _f64(lon_deg)
        keep = np.isfinite(t) & np.isfinite(la) & np.isfinite(lo)
        return cls(*_sorted(t[keep], la[keep], lo[keep]))


@dataclass(frozen=True)
class DvlColumns:
    """DVL samples: time, velocity x/y (m/s) in `frame` (DvlVelocity.Frame), bottom-lock flag, altitude (m).

    A sample is usable when its `valid` flag is set, x and y are finite and
    its frame is BODY_FRD or EARTH_NED: `usable` is that mask.
    """

    t_s: np.ndarray
    vx_mps: np.ndarray
    vy_mps: np.ndarray
    valid: np.ndarray
    frame: np.ndarray
    altitude_m: np.ndarray

    @classmethod
    def build(cls, t_s: Any, vx_mps: Any, vy_mps: Any, valid: Any, frame: Any = BODY_FRD,
              altitude_m: Any = np.nan) -> DvlColumns:
        """DVL columns from array-likes (any but the time may be one scalar): rows without a time dropped, sorted."""
        t = _f64(t_s)
        n = t.size
        vx, vy, ok = _col(vx_mps, n), _col(vy_mps, n), _col(valid, n, bool)
        fr, alt = _col(frame, n, np.int64), _col(altitude_m, n)
        keep = np.isfinite(t)
        return cls(*_sorted(t[keep], vx[keep], vy[keep], ok[keep], fr[keep], alt[keep]))

    @property
    def usable(self) -> np.ndarray:
        """Samples with bottom lock, finite x/y and a frame that can be put on the earth (bool per sample)."""
        return (self.valid & np.isfinite(self.vx_mps) & np.isfinite(self.vy_mps)
                & ((self.frame == BODY_FRD) | (self.frame == EARTH_NED)))

    @property
    def ranging(self) -> np.ndarray:
        """Altitude-only samples (a rangefinder archived on the DVL topic: no velocity at all, an altitude)."""
        return ~np.isfinite(self.vx_mps) & ~np.isfinite(self.vy_mps) & np.isfinite(self.altitude_m)

    def velocities(self) -> DvlColumns:
        """The samples that measure velocity (rangefinder samples left out): what bottom lock is judged on."""
        keep = ~self.ranging
        if keep.all():
            return self
        return DvlColumns(self.t_s[keep], self.vx_mps[keep], self.vy_mps[keep], self.valid[keep], self.frame[keep],
                          self.altitude_m[keep])


@dataclass(frozen=True)
class InsColumns:
    """INS solutions: time, position (deg), heading (deg true), depth (m), NED velocity (m/s); NaN where absent."""

    t_s: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    heading_deg: np.ndarray
    depth_m: np.ndarray
    vn_mps: np.ndarray
    ve_mps: np.ndarray

    @classmethod
    def build(cls, t_s: Any, lat_deg: Any = np.nan, lon_deg: Any = np.nan, heading_deg: Any = np.nan,
              depth_m: Any = np.nan, vn_mps: Any = np.nan, ve_mps: Any = np.nan) -> InsColumns:
        """INS columns from array-likes (any but the time may be one scalar): rows without a time dropped, sorted."""
        t = _f64(t_s)
        cols = [_col(c, t.size) for c in (lat_deg, lon_deg, heading_deg, depth_m, vn_mps, ve_mps)]
        keep = np.isfinite(t)
        return cls(*_sorted(t[keep], *(c[keep] for c in cols)))


@dataclass(frozen=True)
class SeriesColumns:
    """One scalar over time (e.g. a depth sensor): time (mission s) and value; non-finite rows dropped."""

    t_s: np.ndarray
    values: np.ndarray

    @classmethod
    def build(cls, t_s: Any, values: Any) -> SeriesColumns:
        """A series from array-likes, finite rows only, sorted by time."""
        t, v = _f64(t_s), _f64(values)
        keep = np.isfinite(t) & np.isfinite(v)
        return cls(*_sorted(t[keep], v[keep]))


def _empty_ins() -> InsColumns:
    return InsColumns.build(np.empty(0))


def _empty_dvl() -> DvlColumns:
    return DvlColumns.build(np.empty(0), np.empty(0), np.empty(0), np.empty(0, dtype=bool))


@dataclass(frozen=True)
class VehicleColumns:
    """Everything the review reads of one vehicle; absent sensors are empty columns.

    `start_ns` is the trial start (UTC ns) the mission seconds count from;
    `dropped` counts rows left out per topic and reason.
    """

    fixes: FixColumns
    dvl: DvlColumns = field(default_factory=_empty_dvl)
    ins: InsColumns = field(default_factory=_empty_ins)
    depth: SeriesColumns | None = None
    start_ns: int = 0
    dropped: dict[str, int] = field(default_factory=dict)


def _depth_value(msg: Any) -> float:
    for name in ("depth_m", "depth"):
        value = getattr(msg, name, None)
        if isinstance(value, (int, float)):
            return float(value)
    return float("nan")


# the fields of a row `_append` makes of an INS state and of a fix (after the time), read from a block's columns
INS_FIELDS = ("latitude", "longitude", "heading_deg", "depth_m", "velocity_north_mps", "velocity_east_mps")
GPS_FIELDS = ("latitude", "longitude")


def _block_columns(block: MessageBlock, topic: str, schema: str, names: tuple[str, ...]
                   ) -> tuple[np.ndarray, ...] | None:
    """A block's columns `names` of `topic` when it holds them for messages of `schema`, else None."""
    cols = block.columns.get(topic)
    if cols is None or block.schemas[block.topics.index(topic)] != schema or not all(n in cols for n in names):
        return None
    return tuple(cols[n] for n in names)


def _rows(cols: tuple[np.ndarray, ...], rows: np.ndarray) -> list[tuple[float, ...]]:
    """The values of some rows of columns, row by row (plain floats)."""
    return list(zip(*(c[rows].tolist() for c in cols)))


INS_MIN_DT_S = 1.0   # INS solutions kept one a second (and the last before each fix): heading gaps up to 5 s are fine


class ColumnCollector:
    """The navigation columns of some vehicles, gathered from messages as they pass (`add`), in one pass.

    The replay hands it each message it reads, so the review needs no second pass over the archive.
    INS solutions closer than `ins_min_dt_s` to the last one kept are passed over, but for the last two
    before each GPS fix (the INS error at a fix is measured from them): a 50 Hz INS over a day would
    otherwise hold gigabytes, where the heading between DVL samples needs no more. A depth topic is
    read from a ``depth_m`` (or ``depth``) field of its messages.
    """

    def __init__(self, vehicles: list[str], start_ns: int, ins_min_dt_s: float = INS_MIN_DT_S) -> None:
        """Columns for `vehicles`, in seconds from `start_ns`."""
        self.start_ns, self.ins_min_dt_s = start_ns, ins_min_dt_s
        self.vehicles = list(vehicles)
        self.topics = {f"/{v}/{name}": (v, name) for v in vehicles for name in ("gps", "dvl", "ins", "depth")}
        self._cols: dict[str, dict[str, list[array[Any]]]] = {v: {
            "gps": [array("d") for _ in range(3)],
            "dvl": [array("d") for _ in range(4)] + [array("b"), array("b")],
            "ins": [array("d") for _ in range(7)],
            "depth": [array("d") for _ in range(2)],
        } for v in vehicles}
        self._last_ins = dict.fromkeys(vehicles, -math.inf)
        # the last two INS passed over: an INS without velocity is carried to a fix by its last two positions
        self._held: dict[str, list[tuple[int, Any]]] = {v: [] for v in vehicles}
        self.dropped: dict[str, Counter[str]] = {v: Counter() for v in vehicles}

    def add(self, topic: str, log_time_ns: int, msg: Any) -> None:
        """One message; one of another topic is passed over."""
        where = self.topics.get(topic)
        if where is None:
            return
        vehicle, kind = where
        t = (log_time_ns - self.start_ns) / NS
        if kind == "ins":
            held = self._held[vehicle]
            if t - self._last_ins[vehicle] < self.ins_min_dt_s - 1e-6:     # a 1 Hz INS with ns jitter kept whole
                held.append((log_time_ns, msg))    # decoded only if a fix comes before the next one kept
                if len(held) > 2:
                    del held[0]
                return
            self._last_ins[vehicle] = t
            held.clear()
        elif kind == "gps" and self._held[vehicle]:
            for held_ns, held in self._held[vehicle]:
                self._append_held(vehicle, held_ns, held)
            self._held[vehicle].clear()
        self._append(vehicle, kind, t, msg, topic)

    def add_block(self, block: MessageBlock) -> None:
        """A block of messages (formats.mcap_blocks): what `add` would gather of each, the INS sample rule run
        over the block's times; only the rows kept are decoded."""
        where_of = {topic: np.flatnonzero(block.topic_index == i) for i, topic in enumerate(block.topics)
                    if topic in self.topics}
        if not where_of:
            return
        t_all = (block.log_ns - self.start_ns) / NS
        for topic, where in where_of.items():
            vehicle, kind = self.topics[topic]
            if kind == "gps":
                self._ins_and_fixes(vehicle, block, where_of.get(f"/{vehicle}/ins"), where, t_all)
            elif kind == "ins":
                if f"/{vehicle}/gps" not in where_of:
                    self._ins_and_fixes(vehicle, block, where, None, t_all)
            elif kind == "dvl" and block.schemas[block.topics.index(topic)] == "auvreplay.DvlVelocity" \
                    and topic in block.columns:
                self._dvl_columns(vehicle, t_all[where], block.columns[topic])
            else:
                for at, t in zip(where.tolist(), t_all[where].tolist()):
                    self._append(vehicle, kind, t, block.message(topic, int(block.row[at])), topic)

    def _dvl_columns(self, vehicle: str, t: np.ndarray, cols: dict[str, np.ndarray]) -> None:
        """A block's DVL samples from its columns: the rows `_append` makes of each message."""
        frame = cols["frame"]
        self._store_dvl_block(vehicle, (t, cols["velocity_x_mps"], cols["velocity_y_mps"], cols["altitude_m"],
                                        (cols["valid"] != 0).astype(np.int8),
                                        np.where((frame >= 0) & (frame <= 3), frame, 0).astype(np.int8)))

    def _store_dvl_block(self, vehicle: str, cols: tuple[np.ndarray, ...]) -> None:
        """Keep a block's DVL rows, given as the six columns `_store` keeps of one (the last two int8)."""
        c = self._cols[vehicle]["dvl"]
        for k, (col, values) in enumerate(zip(c, cols)):
            col.frombytes(np.ascontiguousarray(values, dtype=np.int8 if k >= 4 else float).tobytes())

    def _ins_and_fixes(self, vehicle: str, block: MessageBlock, ins_at: np.ndarray | None,
                       gps_at: np.ndarray | None, t_all: np.ndarray) -> None:
        """One vehicle's INS samples and GPS fixes of a block, by the rule of `add`: the samples kept are found
        by bisection (times are in stream order), the two held before each fix by position."""
        ins_topic, gps_topic = f"/{vehicle}/ins", f"/{vehicle}/gps"
        pos = ins_at.tolist() if ins_at is not None else []
        ts = t_all[ins_at].tolist() if ins_at is not None else []
        fixes = gps_at.tolist() if gps_at is not None else []
        last = self._last_ins[vehicle]
        gap = self.ins_min_dt_s - 1e-6
        kept: list[int] = []
        i = 0
        while i < len(ts):
            ref = last
            i = bisect_left(ts, gap, i, key=lambda x: x - ref)     # the first with t - last >= gap
            if i == len(ts):
                break
            kept.append(i)
            last = ts[i]
            i += 1
        # what is appended, in stream order: (position, 0 INS kept | 1 INS held | 2 fix, index)
        out: list[tuple[int, int, int]] = [(pos[k], 0, k) for k in kept]
        carried: list[tuple[int, Any]] = list(self._held[vehicle])
        floor = 0        # INS samples before this index are kept, flushed or passed over
        for f in fixes:
            j = bisect_left(pos, f)
            k = bisect_left(kept, j) - 1      # the last kept sample before the fix
            lo = max(floor, kept[k] + 1 if k >= 0 else 0)
            if k >= 0:
                carried = []      # a kept sample let go of what was held
            held = list(range(max(lo, j - 2), j))
            if len(held) < 2 and carried:
                out.extend((f, 1, -1 - c) for c in range(len(carried))[-(2 - len(held)):])
            out.extend((f, 1, h) for h in held)
            out.append((f, 2, f))
            carried = []
            floor = j
        out.sort(key=lambda e: e[0])      # stable: a fix's held samples stay before it
        ins_cols = _block_columns(block, ins_topic, "auvreplay.InsState", INS_FIELDS)
        gps_cols = _block_columns(block, gps_topic, "foxglove.LocationFix", GPS_FIELDS)
        # the rows of the INS samples used, from the block's columns (each message decoded only without them)
        used = [k for _, kind, k in out if kind != 2 and k >= 0]
        ins_rows = iter(_rows(ins_cols, block.row[[pos[k] for k in used]]) if ins_cols is not None else ())
        fix_at = [at for at, kind, _ in out if kind == 2]
        fix_rows = iter(_rows(gps_cols, block.row[fix_at]) if gps_cols is not None else ())
        for at, kind, k in out:
            if kind == 2:
                if gps_cols is not None:
                    self._store(vehicle, "gps", (float(t_all[at]), *next(fix_rows)))
                else:
                    self._append(vehicle, "gps", float(t_all[at]), block.message(gps_topic, int(block.row[at])),
                                 gps_topic)
            elif k < 0:
                self._append_held(vehicle, *self._held[vehicle][-1 - k])
            elif ins_cols is not None:
                self._store(vehicle, "ins", (ts[k], *next(ins_rows)))
            else:
                self._append(vehicle, "ins", ts[k], block.message(ins_topic, int(block.row[pos[k]])), ins_topic)
        # the samples held at the end of the block: after the last kept one and the last fix, the last two
        k = len(kept) - 1
        lo = max(floor, kept[k] + 1 if k >= 0 else 0)
        if kept or fixes:
            carried = []
        tail = list(range(max(lo, len(ts) - 2), len(ts)))
        keep_carried = carried[len(carried) - (2 - len(tail)):] if len(tail) < 2 and carried else []
        tail_rows = (_rows(ins_cols, block.row[[pos[h] for h in tail]]) if ins_cols is not None
                     else [block.message(ins_topic, int(block.row[pos[h]])) for h in tail])
        self._held[vehicle] = keep_carried + [(int(block.log_ns[pos[h]]), r) for h, r in zip(tail, tail_rows)]
        self._last_ins[vehicle] = last

    def _append_held(self, vehicle: str, log_ns: int, held: Any) -> None:
        """An INS sample held back (`add`): a message, or its row's values but the time (a block's columns)."""
        t = (log_ns - self.start_ns) / NS
        if isinstance(held, tuple):
            self._store(vehicle, "ins", (t, *held))
        else:
            self._append(vehicle, "ins", t, held, f"/{vehicle}/ins")

    def _append(self, vehicle: str, kind: str, t: float, msg: Any, topic: str) -> None:
        try:
            if kind == "gps":
                row: tuple[float, ...] = (t, msg.latitude, msg.longitude)
            elif kind == "ins":
                row = (t, msg.latitude, msg.longitude, msg.heading_deg, msg.depth_m, msg.velocity_north_mps,
                       msg.velocity_east_mps)
            elif kind == "dvl":
                row = (t, msg.velocity_x_mps, msg.velocity_y_mps, msg.altitude_m, 1 if msg.valid else 0,
                       int(msg.frame) if 0 <= int(msg.frame) <= 3 else 0)
            else:
                row = (t, _depth_value(msg))
        except AttributeError:  # a topic of that name holding another schema
            self.dropped[vehicle][f"{topic}: not a {kind} message"] += 1
            return
        self._store(vehicle, kind, row)

    def _store(self, vehicle: str, kind: str, row: tuple[float, ...]) -> None:
        """Keep one row (time first; a DVL row ends with its valid flag and frame): here, in whole-mission columns."""
        for col, value in zip(self._cols[vehicle][kind], row):
            col.append(value)

    def columns(self, vehicle: str) -> VehicleColumns:
        """The columns gathered for one vehicle, once: the collector lets go of them (a day's worth is large)."""
        gathered = self._cols.pop(vehicle)
        g, d, i, z = (gathered[k] for k in ("gps", "dvl", "ins", "depth"))
        dropped = Counter(self.dropped[vehicle])
        fixes = FixColumns.build(*g)
        if len(g[0]) - fixes.t_s.size:
            dropped[f"/{vehicle}/gps: fixes without a finite position"] += len(g[0]) - fixes.t_s.size
        return VehicleColumns(
            fixes=fixes,
            dvl=DvlColumns.build(d[0], d[1], d[2], np.asarray(d[4], dtype=bool), np.asarray(d[5]), d[3]),
            ins=InsColumns.build(*i),
            depth=SeriesColumns.build(*z) if len(z[0]) else None,
            start_ns=self.start_ns,
            dropped=dict(dropped),
        )


def read_columns(reader: ArchiveReader, vehicle: str, start_ns: int, ins_min_dt_s: float = INS_MIN_DT_S
                 ) -> VehicleColumns:
    """The columns of `vehicle` from `/<v>/gps`, `/<v>/dvl`, `/<v>/ins` and `/<v>/depth` (where present), in one
    pass over those topics (`ColumnCollector`); times are log times in seconds from `start_ns`."""
    collector = ColumnCollector([vehicle], start_ns, ins_min_dt_s)
    present = set(reader.summary().topics)
    for m in reader.messages([t for t in collector.topics if t in present]):
        collector.add(m.topic, m.log_time_ns, m.message)
    return collector.columns(vehicle)
