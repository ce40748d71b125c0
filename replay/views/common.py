"""Shared pieces of the Rerun views: method colours and class ids, entity paths, time columns.

Every method (and the GPS truth) has one fixed colour and class id, whatever
the run, so a reviewer learns them once. Rerun's 2D views draw y downwards
and ignore view coordinates (rerun issue #1387), so the 2D views log
``y = -north`` (and ``-grade``, ``-probability``) to put north and "more" up.
"""

from __future__ import annotations

import colorsys
import gc
import json
import re
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
import pandas as pd
import rerun as rr

from replay.review.data import ReviewData
from replay.review.naming import run_labels
from replay.review.palette import method_rgb as palette_rgb
from replay.review.palette import palette

# the palette's order fixes the class ids (1-based): sources, then the method table's order; a method
# registered later gets a stable id from its hash (class_id)
METHOD_STYLE: tuple[tuple[str, tuple[int, int, int]], ...] = tuple(palette().items())
_IDS = {name: i + 1 for i, (name, _) in enumerate(METHOD_STYLE)}
FIRST_FREE_ID = 100
# KMCDF cluster of a preliminary fix: 1 = C1 (consistent, kept) green, 2 = C2 red; 0 = unclustered grey
CLUSTER_COLORS = np.array([[160, 160, 160], [60, 200, 90], [220, 60, 50], [230, 200, 60]], dtype=np.uint8)
_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")
T = TypeVar("T")


def class_id(name: str) -> int:
    """The fixed class id of a method; an unknown name gets a stable id from its hash."""
    known = _IDS.get(name)
    return known if known is not None else FIRST_FREE_ID + zlib.crc32(name.encode()) % 900


def method_rgb(name: str, run_index: int = 0) -> tuple[int, int, int]:
    """A method's colour; in a comparison the second run gets the same hue, clearly lighter or darker."""
    rgb = palette_rgb(name)
    if run_index == 0:
        return rgb
    hue, light, sat = colorsys.rgb_to_hls(*(c / 255 for c in rgb))
    light = light * 0.55 if light > 0.45 else light + 0.3
    r, g, b = (round(255 * c) for c in colorsys.hls_to_rgb(hue, light, sat))
    return r, g, b


def part(name: str) -> str:
    """An entity-path part from any name: runs of unsafe characters become one underscore."""
    return _SAFE.sub("_", str(name)).strip("_") or "_"


MISSION = "mission_s"
"""The timeline every view's axis and the time panel use: whole seconds from the trial start."""


def mission_seconds(t_s: np.ndarray | pd.Series) -> np.ndarray:
    """Mission seconds as the `mission_s` timeline holds them: rounded to whole seconds (int64)."""
    return np.round(np.asarray(t_s, dtype=float)).astype(np.int64)


def mission_column(t_s: np.ndarray | pd.Series) -> rr.TimeColumn:
    """The `mission_s` timeline of rows at `t_s` seconds from the trial start.

    A sequence of whole seconds, not a duration: Rerun 0.41 writes a duration axis as "+10m", a
    sequence as plain numbers, so every plot's time axis reads in the seconds the events and the
    CLI use. Rows within one second share a tick (a view shows the later one at that second).
    """
    return rr.TimeColumn(MISSION, sequence=mission_seconds(t_s))


@dataclass(frozen=True)
class Run:
    """One ReviewData in a recording: its entity-path prefix, label and index (0 or 1)."""

    review: ReviewData
    prefix: str
    label: str
    index: int
    # (id of a table, keys) -> (the table, its groups): several views group the same rows the same way
    _groups: dict[tuple[int, tuple[str, ...]], tuple[pd.DataFrame, list[tuple[tuple, pd.DataFrame]]]] = field(
        default_factory=dict, init=False, repr=False, compare=False)
    # (name, ids of the tables it was derived from) -> (the tables, the value): several views derive the same
    _memo: dict[tuple, tuple[tuple, object]] = field(default_factory=dict, init=False, repr=False, compare=False)

    # the time columns of each distinct array of instants (its bytes)
    _times: dict[bytes, list[rr.TimeColumn]] = field(default_factory=dict, init=False, repr=False, compare=False)

    def memo(self, name: str, tables: tuple, make: Callable[[], T]) -> T:
        """`make()`, computed once per name and tables (the same objects; held, so their ids stay theirs)."""
        key = (name, *(id(t) for t in tables))
        hit = self._memo.get(key)
        if hit is None or any(a is not b for a, b in zip(hit[0], tables, strict=True)):
            hit = self._memo[key] = (tables, make())
        return hit[1]  # type: ignore[return-value]

    def groups(self, frame: pd.DataFrame, keys: list[str]) -> list[tuple[tuple, pd.DataFrame]]:
        """`groups(frame, keys)`, computed once per table and keys for this run (read it, never change it).

        A table is one of this run's or a group of one (the same object each time it is asked for); the
        cache holds it, so its id is not reused while it stands for it.
        """
        key = (id(frame), tuple(keys))
        hit = self._groups.get(key)
        if hit is None or hit[0] is not frame:
            hit = self._groups[key] = (frame, groups(frame, keys))
        return hit[1]

    def path(self, *parts: str) -> str:
        """An entity path under this run's prefix, each part made safe."""
        return "/".join([self.prefix, *(part(p) for p in parts)])

    def times(self, t_s: np.ndarray | pd.Series) -> list[rr.TimeColumn]:
        """The two timelines of every logged row: `time` (UTC, trial_start_ns + t_s) and `mission_s`."""
        t = np.ascontiguousarray(t_s, dtype=float)
        key = t.tobytes()               # the views send many series at the same instants (a pair's epochs)
        hit = self._times.get(key)
        if hit is None:
            ns = self.review.trial_start_ns + np.round(t * 1e9).astype(np.int64)
            hit = self._times[key] = [rr.TimeColumn("time", timestamp=ns.astype("datetime64[ns]")), mission_column(t)]
        return list(hit)

    @property
    def tag(self) -> str:
        """The run's letter in a comparison: "A" for the first run (the first argument everywhere), "B" for the
        second; "" for a run alone. Names and lines carry the letter; what differs (`label`) is said once."""
        return "AB"[self.index] if self.label else ""

    def name(self, method: str) -> str:
        """A series name: the method, tagged with the run's letter in a comparison."""
        return f"{method} [{self.tag}]" if self.tag else method


def make_runs(reviews: list[ReviewData]) -> list[Run]:
    """Prefixes `/<run_id>` (unique even when two runs share an id); in a comparison, labels by what differs.

    Runs whose configurations differ are named by `run_labels` ("r_m=2.5"); runs of one configuration
    (another input, another version) by their prefix.
    """
    prefixes, seen = [], set()
    for i, review in enumerate(reviews):
        base = part(review.run_id or f"run{i}")
        prefix = base if base not in seen else f"{base}_{i}"
        seen.add(prefix)
        prefixes.append(prefix)
    labels = [""] * len(reviews)
    if len(reviews) > 1:
        named = run_labels([r.parameters for r in reviews])
        differ = len({json.dumps(r.parameters, sort_keys=True, default=str) for r in reviews}) > 1
        labels = named if differ else prefixes
    return [Run(review, "/" + p, label, i) for i, (review, p, label) in enumerate(zip(reviews, prefixes, labels,
                                                                                    strict=True))]


def annotation_context(run: Run, names: list[str]) -> rr.AnnotationContext:
    """Class id -> (name, colour) for every method of a run (names tagged in a comparison)."""
    return rr.AnnotationContext([
        rr.AnnotationInfo(id=class_id(n), label=run.name(n), color=method_rgb(n, run.index)) for n in names
    ])


def run_names(review: ReviewData) -> list[str]:
    """Every method/source name a run's tables mention, in the fixed order, unknown names last."""
    found: set[str] = set(review.methods) | {"gps", "truth", "measured"}
    for frame, col in ((review.tracks, "source"), (review.detections, "method"), (review.errors, "method"),
                       (review.kmcdf, "method")):
        if col in frame:
            found |= set(frame[col].astype(str).unique())
    ordered = [n for n, _ in METHOD_STYLE if n in found]
    return ordered + sorted(found - set(ordered))


def groups(frame: pd.DataFrame, keys: list[str]) -> list[tuple[tuple, pd.DataFrame]]:
    """(key tuple, rows sorted by t_s) for every group of a table, keys in sorted order; nothing for an empty table.

    One stable sort of the whole table by (keys, t_s), then contiguous slices: a groupby and a sort per
    group cost several times as much on the string-keyed tables the views read.
    """
    if frame.empty or any(k not in frame for k in keys):
        return []
    codes = [pd.factorize(frame[k], sort=True) for k in keys]
    order_keys = [c for c, _ in codes[::-1]]
    if "t_s" in frame:
        order_keys = [frame["t_s"].to_numpy(dtype=float), *order_keys]
    order = np.lexsort(order_keys)
    code_matrix = np.stack([c[order] for c, _ in codes], axis=1)
    starts = np.flatnonzero(np.r_[True, (code_matrix[1:] != code_matrix[:-1]).any(axis=1)])
    ends = np.r_[starts[1:], order.size]
    ordered = frame.iloc[order]
    out = []
    for a, b in zip(starts, ends, strict=True):
        if (code_matrix[a] < 0).any():          # a missing key: pandas' groupby drops those rows too
            continue
        key = tuple(uniq[c] for (_, uniq), c in zip(codes, code_matrix[a], strict=True))
        out.append((key, ordered.iloc[a:b]))
    return out


@contextmanager
def no_cycle_collection() -> Iterator[None]:
    """Python's cycle collector paused while a recording is built: its full passes walk every object of the
    review tables (ANFIS parameters and explanations are lists per row) again and again, for garbage that
    reference counting frees anyway (any cycle made meanwhile is collected after)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def epochs_of(run: Run, rows: pd.DataFrame) -> pd.DataFrame:
    """The first row of each instant of a group's rows (one per ranging epoch), once per group and run."""
    return run.memo("epochs", (rows,), lambda: rows.drop_duplicates("t_s"))


def track_pairs(run: Run) -> list[tuple[str, str]]:
    """Every (vehicle, source) of a run's tracks, sorted (the tracks' groups, as the views draw them)."""
    return [(str(v), str(s)) for (v, s), _ in run.groups(run.review.tracks, ["vehicle", "source"])]


def floats(rows: pd.DataFrame, column: str) -> np.ndarray:
    """A column as float64 (missing column: NaN)."""
    if column not in rows:
        return np.full(len(rows), np.nan)
    col = rows[column]
    if col.dtype == np.float64:          # the tables' usual case: no conversion, no NA to fill
        return col.to_numpy()
    if pd.api.types.is_float_dtype(col.dtype) or pd.api.types.is_integer_dtype(col.dtype):
        return col.to_numpy(dtype=float, na_value=np.nan)
    return pd.to_numeric(col, errors="coerce").to_numpy(dtype=float)


def ragged(rows: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray]:
    """A column of per-row lists flattened, with the per-row lengths (for partitioned columns)."""
    cells = [np.asarray(v if isinstance(v, (list, tuple, np.ndarray)) else [], dtype=float).ravel()
             for v in rows[column]] if column in rows else []
    lengths = np.array([c.size for c in cells], dtype=np.int64)
    flat = np.concatenate(cells) if cells else np.zeros(0)
    return flat, lengths
