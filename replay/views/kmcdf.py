"""Rerun views of the KMCDF reproduction: success probability against abnormal nodes.

The only module of the KMCDF work that imports `rerun` (rerun-sdk 0.41):
curves go out with the columnar `send_columns` API on a sequence timeline
`abnormal_nodes`, one time-series view per layout, saved with the blueprint
inside the .rrd.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

Curves = Mapping[str, Mapping[str, Mapping[str, float]]]   # layout -> method -> k -> rate

METHOD_COLORS: dict[str, tuple[int, int, int]] = {
    "kmcdf1": (214, 39, 40), "kmcdf2": (255, 127, 14), "gar": (31, 119, 180),
    "ear": (44, 160, 44), "lms": (148, 103, 189), "lhc": (140, 86, 75),
}
TIMELINE = "abnormal_nodes"


def _send_series(rec: rr.RecordingStream, entity: str, points: Mapping[str, float]) -> None:
    """One curve as columns: abnormal-node count -> success in percent."""
    ks = sorted(int(k) for k in points)
    values = np.array([100.0 * points[str(k)] for k in ks], dtype=np.float64)
    rr.send_columns(entity, indexes=[rr.TimeColumn(TIMELINE, sequence=ks)],
                    columns=rr.Scalars.columns(scalars=values), recording=rec)


def blueprint(layouts: Curves) -> rrb.Blueprint:
    """One time-series view per layout, side by side."""
    views = [rrb.TimeSeriesView(origin=f"/kmcdf/N{layout}", name=f"N = {layout}: success (%)")
             for layout in layouts]
    return rrb.Blueprint(rrb.Horizontal(*views), collapse_panels=True)


def save_success_curves(path: str | Path, layouts: Curves, paper: Curves | None = None,
                        recording_id: str = "reproduce-kmcdf") -> None:
    """Write the curves (and the paper's published points, as markers) to an .rrd file."""
    rec = rr.RecordingStream("auvreplay", recording_id=recording_id, send_properties=False)
    rec.save(str(path), default_blueprint=blueprint(layouts))
    for layout, methods in layouts.items():
        for method, points in methods.items():
            entity = f"kmcdf/N{layout}/{method}"
            color = METHOD_COLORS.get(method, (128, 128, 128))
            rec.log(entity, rr.SeriesLines(names=method, colors=[color]), static=True)
            _send_series(rec, entity, points)
        for method, points in (paper or {}).get(layout, {}).items():
            entity = f"kmcdf/N{layout}/paper/{method}"
            color = METHOD_COLORS.get(method, (128, 128, 128))
            rec.log(entity, rr.SeriesPoints(names=f"{method} (paper)", colors=[color],
                                            markers="Diamond", marker_sizes=6.0), static=True)
            _send_series(rec, entity, points)
    rec.flush()
    rec.disconnect()
