"""Shared pieces of the Rerun views: method colours and class ids, entity paths, time columns.

Every method (and the GPS truth) has one fixed colour and class id, whatever
the run, so a reviewer learns them once. Rerun's 2D views draw y downwards
and ignore view coordinates (rerun issue #1387), so the 2D views log
``y = -north`` (and ``-grade``, ``-probability``) to put north and "more" up.
"""

from __future__ import annotations

import re
import zlib
from dataclasses import dataclass

import numpy as np
import pandas as pd
import rerun as rr

from replay.review.data import ReviewData

# (name, RGB); the order fixes the class ids (1-based) and never changes
METHOD_STYLE: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("gps", (235, 235, 235)),
    ("ins", (150, 150, 150)),
    ("dead_reckoning", (166, 118, 29)),
    ("ckf", (31, 119, 230)),
    ("ackf", (23, 190, 207)),
    ("chi_square", (255, 127, 14)),
    ("dual_threshold", (148, 103, 189)),
    ("anfis", (44, 200, 44)),
    ("anfis_aqpso", (188, 230, 34)),
    ("anfis_compensation", (0, 150, 120)),
    ("kmcdf1", (214, 39, 40)),
    ("kmcdf2", (227, 119, 194)),
    ("gar", (240, 220, 60)),
    ("ear", (255, 152, 150)),
    ("lms", (128, 128, 0)),
    ("lhc", (120, 170, 255)),
    ("truth", (250, 250, 250)),
    ("measured", (255, 200, 80)),
)
_IDS = {name: i + 1 for i, (name, _) in enumerate(METHOD_STYLE)}
_RGB = dict(METHOD_STYLE)
FIRST_FREE_ID = 100
# KMCDF cluster of a preliminary fix: 1 = C1 (consistent, kept) green, 2 = C2 red; 0 = unclustered grey
CLUSTER_COLORS = np.array([[160, 160, 160], [60, 200, 90], [220, 60, 50], [230, 200, 60]], dtype=np.uint8)
_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def class_id(name: str) -> int:
    """The fixed class id of a method; an unknown name gets a stable id from its hash."""
    known = _IDS.get(name)
    return known if known is not None else FIRST_FREE_ID + zlib.crc32(name.encode()) % 900


def method_rgb(name: str, run_index: int = 0) -> tuple[int, int, int]:
    """A method's colour; the second run of a comparison gets it blended halfway to grey."""
    rgb = _RGB.get(name)
    if rgb is None:
        h = zlib.crc32(name.encode())
        rgb = (80 + h % 160, 80 + (h >> 8) % 160, 80 + (h >> 16) % 160)
    if run_index == 0:
        return rgb
    return tuple(int(0.5 * c + 0.5 * 110) for c in rgb)  # type: ignore[return-value]


def part(name: str) -> str:
    """An entity-path part from any name: runs of unsafe characters become one underscore."""
    return _SAFE.sub("_", str(name)).strip("_") or "_"


@dataclass(frozen=True)
class Run:
    """One ReviewData in a recording: its entity-path prefix, label and index (0 or 1)."""

    review: ReviewData
    prefix: str
    label: str
    index: int

    def path(self, *parts: str) -> str:
        """An entity path under this run's prefix, each part made safe."""
        return "/".join([self.prefix, *(part(p) for p in parts)])

    def times(self, t_s: np.ndarray | pd.Series) -> rr.TimeColumn:
        """The `time` timeline column: UTC timestamps from trial_start_ns + t_s."""
        ns = self.review.trial_start_ns + np.round(np.asarray(t_s, dtype=float) * 1e9).astype(np.int64)
        return rr.TimeColumn("time", timestamp=ns.astype("datetime64[ns]"))

    def name(self, method: str) -> str:
        """A series name: the method, tagged with the run label in a comparison."""
        return method if self.index == 0 and self.label == "" else f"{method} [{self.label}]"


def make_runs(reviews: list[ReviewData]) -> list[Run]:
    """Prefixes `/<run_id>` (unique even when two runs share an id); labels only for comparisons."""
    runs, seen = [], set()
    for i, review in enumerate(reviews):
        base = part(review.run_id or f"run{i}")
        prefix = base if base not in seen else f"{base}_{i}"
        seen.add(prefix)
        runs.append(Run(review, "/" + prefix, prefix if len(reviews) > 1 else "", i))
    return runs


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
    """(key tuple, rows sorted by t_s) for every group of a table; nothing for an empty table."""
    if frame.empty or any(k not in frame for k in keys):
        return []
    out = []
    for key, rows in frame.groupby(keys, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        out.append((key, rows.sort_values("t_s", kind="stable") if "t_s" in rows else rows))
    return out


def floats(rows: pd.DataFrame, column: str) -> np.ndarray:
    """A column as float64 (missing column: NaN)."""
    if column not in rows:
        return np.full(len(rows), np.nan)
    return pd.to_numeric(rows[column], errors="coerce").to_numpy(dtype=float)


def ragged(rows: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray]:
    """A column of per-row lists flattened, with the per-row lengths (for partitioned columns)."""
    cells = [np.asarray(v if isinstance(v, (list, tuple, np.ndarray)) else [], dtype=float).ravel()
             for v in rows[column]] if column in rows else []
    lengths = np.array([c.size for c in cells], dtype=np.int64)
    flat = np.concatenate(cells) if cells else np.zeros(0)
    return flat, lengths
