"""Time to log the sample trial to Rerun: columnar (`send_columns`) against row-by-row `log`.

The bundled sample trial is recorded and replayed with every method, and its
ReviewData (what `auvreplay demo` logs) is logged both ways and saved whole;
a synthetic ReviewData of the same size is timed too:

Sample-trial size: 1700 s at 1 Hz tracks (3 vehicles, 9 follower methods), 700
ranging epochs, 4 detectors, 2 ANFIS models x 100 training epochs, 340 USBL epochs.
The row-by-row comparison covers the bulk per-sample series (track positions on
the map and the local plot, range circles, range/residual/feature/lane/ANFIS/error
scalars), logged once each way into an in-memory sink; the full recording (CDFs,
ANFIS, KMCDF, blueprint) is timed columnar only, in memory and saved to .rrd.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import rerun as rr

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.common import median_time, print_table  # noqa: E402
from replay.views import recording as views
from replay.views.common import Run, class_id, floats, groups, make_runs  # noqa: E402
from replay.views.series import FEATURES, log_detections, log_ranges  # noqa: E402
from replay.views.tracks import log_range_circles, log_tracks  # noqa: E402
from tests.review_fixtures import synthetic_review  # noqa: E402

REPEATS = 3
GOAL_S = 2.0


def _stream() -> rr.RecordingStream:
    rec = rr.RecordingStream("bench_views", recording_id="bench", send_properties=False)
    rec._bench_memory = rec.memory_recording()  # type: ignore[attr-defined]  # keep it alive until drained
    return rec


def _finish(rec: rr.RecordingStream) -> int:
    """Flush and drain the in-memory sink, so encoding is inside the timing; the bytes produced."""
    rec.flush()
    return len(rec._bench_memory.drain_as_bytes())  # type: ignore[attr-defined]


def bulk_columnar(run: Run) -> int:
    """The bulk series with send_columns (the views' own functions); returns the rows logged."""
    rec = _stream()
    log_tracks(rec, run)
    log_range_circles(rec, run)
    log_ranges(rec, run)
    log_detections(rec, run)
    for (follower, method), rows in groups(run.review.errors, ["follower", "method"]):
        rec.send_columns(run.path("series", "error", str(follower), str(method)), indexes=[run.times(rows["t_s"])],
                         columns=rr.Scalars.columns(scalars=floats(rows, "error_m")))
    _finish(rec)
    return bulk_rows(run)


def bulk_rows(run: Run) -> int:
    """Rows in the bulk subset: two positions per track sample, circles, and every scalar."""
    rv = run.review
    n_det_epochs = len(rv.detections.drop_duplicates(["t_s", "follower", "leader"]))
    n_anfis = int(rv.detections.method.str.startswith("anfis").sum())
    return 2 * len(rv.tracks) + 4 * len(rv.ranges) + 4 * n_det_epochs + len(rv.detections) + 2 * n_anfis + len(
        rv.errors)


def _set(rec: rr.RecordingStream, run: Run, t: float) -> None:
    rec.set_time("time", timestamp=np.datetime64(run.review.trial_start_ns + int(round(t * 1e9)), "ns"))


def bulk_row_by_row(run: Run) -> int:
    """The same data with one `log` call per row and per entity."""
    rec = _stream()
    for (vehicle, source), rows in groups(run.review.tracks, ["vehicle", "source"]):
        cid = class_id(str(source))
        for r in rows.itertuples():
            _set(rec, run, r.t_s)
            rec.log(run.path("map", vehicle, source, "position"), rr.GeoPoints(lat_lon=[[r.lat_deg, r.lon_deg]],
                                                                                class_ids=[cid]))
            rec.log(run.path("local", vehicle, source, "position"), rr.Points2D([[r.east_m, -r.north_m]],
                                                                                 class_ids=[cid]))
    for (follower, leader), rows in groups(run.review.ranges, ["follower", "leader"]):
        for r in rows.itertuples():
            _set(rec, run, r.t_s)
            rec.log(run.path("local", "ranges", follower, leader),
                    rr.Ellipses2D(half_sizes=[[r.horizontal_m] * 2], centers=[[r.leader_east_m, -r.leader_north_m]]))
            for name, v in (("measured", r.measured_m), ("true", r.true_m), ("residual", r.residual_m)):
                rec.log(run.path("series", "range", follower, leader, name), rr.Scalars(v))
    for (follower, leader), rows in groups(run.review.detections, ["follower", "leader"]):
        for r in rows.drop_duplicates("t_s").itertuples():
            _set(rec, run, r.t_s)
            for f in FEATURES:
                rec.log(run.path("series", f, follower, leader), rr.Scalars(getattr(r, f)))
            rec.log(run.path("series", "lanes", follower, leader, "truth"), rr.Scalars(0.8 * (r.label == 1)))
        for r in rows.itertuples():
            _set(rec, run, r.t_s)
            rec.log(run.path("series", "lanes", follower, leader, r.method), rr.Scalars(1 + 0.8 * r.flagged))
            if r.method.startswith("anfis"):
                rec.log(run.path("series", "anfis", follower, leader, r.method, "output"), rr.Scalars(r.score))
                rec.log(run.path("series", "anfis", follower, leader, r.method, "T2"), rr.Scalars(r.threshold))
    for r in run.review.errors.itertuples():
        _set(rec, run, r.t_s)
        rec.log(run.path("series", "error", r.follower, r.method), rr.Scalars(r.error_m))
    _finish(rec)
    return bulk_rows(run)


def full_in_memory(review: object) -> None:
    """The whole recording, blueprint included, into memory."""
    rec = views.build_recording([review])
    memory = rec.memory_recording()     # the buffered data moves into it
    rec.flush()
    memory.drain_as_bytes()


def sample_trial_review(workdir: Path) -> object:
    """The bundled sample trial recorded and replayed with every method: the ReviewData `demo` logs."""
    from recorders.manifest import load_manifest
    from recorders.record import record
    from replay.run.pipeline import replay_archive

    archive = workdir / "lake.mcap"
    record(load_manifest(ROOT / "samples/lake_trial/trial.toml"), archive)
    return replay_archive(archive, write_output=False, review=True).review


def describe(name: str, review: object) -> str:
    """One line of the ReviewData's sizes."""
    return (f"{name}: tracks {len(review.tracks)}, ranges {len(review.ranges)}, detections "
            f"{len(review.detections)}, errors {len(review.errors)}, anfis epochs {len(review.anfis_epochs)}, "
            f"explain {len(review.anfis_explain)}, kmcdf {len(review.kmcdf)}")


def main() -> None:
    """Print the table."""
    review = synthetic_review(0, n_epochs=700, anfis_epochs=100)
    run = make_runs([review])[0]
    tmp = Path(tempfile.mkdtemp(prefix="bench_views_"))
    rows = bulk_rows(run)
    t_col = median_time(lambda: bulk_columnar(run), REPEATS)
    t_row = median_time(lambda: bulk_row_by_row(run), 2)
    t_full = median_time(lambda: full_in_memory(review), REPEATS)
    t_save = median_time(lambda: views.save_rrd([review], tmp / "trial.rrd"), REPEATS)
    t_two = median_time(lambda: views.save_rrd([review, synthetic_review(1, 700, 100, "run-b")], tmp / "two.rrd"),
                        REPEATS)
    size_mb = (tmp / "trial.rrd").stat().st_size / 1e6
    real = sample_trial_review(tmp)
    real_run = make_runs([real])[0]
    real_rows = bulk_rows(real_run)
    r_col = median_time(lambda: bulk_columnar(real_run), REPEATS)
    r_row = median_time(lambda: bulk_row_by_row(real_run), 2)
    r_save = median_time(lambda: views.save_rrd([real], tmp / "lake.rrd"), REPEATS)
    real_mb = (tmp / "lake.rrd").stat().st_size / 1e6
    print(describe("synthetic ReviewData", review) + f"; rerun-sdk {rr.__version__}")
    print(describe("sample trial ReviewData", real))
    print_table("the sample trial (samples/lake_trial, every method): bulk series both ways and the whole .rrd",
                ["logging", "rows", "time (s)", "rows/s", "ratio to columnar"],
                [["send_columns", real_rows, r_col, real_rows / r_col, 1.0],
                 ["row-by-row rr.log", real_rows, r_row, real_rows / r_row, r_row / r_col],
                 [f"whole recording saved .rrd ({real_mb:.1f} MB), goal < {GOAL_S:.0f} s", "-", r_save, "-",
                  "met" if r_save < GOAL_S else "NOT met"]])
    print_table("bulk per-sample series (same rows both ways, in-memory sink), median of repeats",
                ["logging", "rows", "time (s)", "rows/s", "ratio to columnar"],
                [["send_columns", rows, t_col, rows / t_col, 1.0],
                 ["row-by-row rr.log", rows, t_row, rows / t_row, t_row / t_col]])
    print_table(f"whole recording, columnar (goal < {GOAL_S:.0f} s)", ["case", "time (s)", "within goal"],
                [["one run, in memory", t_full, t_full < GOAL_S],
                 [f"one run, saved .rrd ({size_mb:.1f} MB)", t_save, t_save < GOAL_S],
                 ["two runs compared, saved .rrd (incl. building run b)", t_two, t_two < 2 * GOAL_S]])


if __name__ == "__main__":
    main()
