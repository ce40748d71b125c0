"""Time to log the sample trial to Rerun: columnar (`send_columns`) against row-by-row `log`.

The bundled sample trial is recorded and replayed with every method (every method of the table, as `demo`), and its
ReviewData (what `auvreplay demo` logs) is logged both ways and saved whole;
a synthetic ReviewData of the same size is timed too:

Sample-trial size: 1700 s at 1 Hz tracks (7 vehicles, 8 follower filters and 5
positioning methods), 700 ranging epochs, 5 detectors, 2 ANFIS models x 100 training
epochs, 340 USBL epochs. The row-by-row comparison covers the bulk per-sample series
(track positions and trails on the map and the local plot, range circles,
range/residual/feature/ANFIS/error scalars, detection-lane states, the new features where finite,
every detector's score and threshold, the why-documents per epoch), logged once each
way into an in-memory sink; the full recording (CDFs, ANFIS, KMCDF, scoreboard,
blueprint) is timed columnar only, in memory and saved to .rrd (wall and CPU time:
the CPU time says what the logging costs when other work shares the machine).

`--first-visible` times only what `auvreplay view ARCHIVE` takes before a viewer can draw anything (default
methods, as `view`): the bulk path (replay, then the whole .rrd: what `view` did before it streamed) against
the streamed one (`replay.views.stream`: the first stretch sent, and the recording complete), on the sample
trial and, with `--mission-s 3600`, a synthetic mission (bench/mission.py). A tree without the streamed path
prints the bulk rows only (run the script from there to compare).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import rerun as rr

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from bench.common import median_time, print_table
from recorders.manifest import load_manifest
from recorders.record import record
from replay.run.config import load_config
from replay.run.pipeline import replay_archive
from replay.stack.methods import runnable_names
from replay.views import recording as views
from replay.views.common import Run, class_id, floats, groups, make_runs
from replay.views.features import (
    FEATURE_GROUPS,
    log_detector_scores,
    log_features,
    log_why,
    present_features,
    scored,
    why_documents,
)
from replay.views.lanes import (
    epoch_states,
    lane_paths,
    log_lanes,
    training_end_s,
    truth_states,
)
from replay.views.series import FEATURES, log_detections, log_errors, log_ranges
from replay.views.tracks import log_range_circles, log_tracks, trail_indices
from tests.review_fixtures import synthetic_review

REPEATS = 3
GOAL_S = 1.0


def _stream() -> rr.RecordingStream:
    rec = rr.RecordingStream("bench_views", recording_id="bench", send_properties=False)
    rec._bench_memory = rec.memory_recording()  # type: ignore[attr-defined]  # keep it alive until drained
    return rec


def _finish(rec: rr.RecordingStream) -> int:
    """Flush and drain the in-memory sink, so encoding is inside the timing; the bytes produced."""
    rec.flush()
    return len(rec._bench_memory.drain_as_bytes())  # type: ignore[attr-defined]


def bulk_columnar(run: Run) -> None:
    """The bulk series with send_columns (the views' own functions); `bulk_rows` counts them."""
    run = replace(run)  # a Run as a recording starts with it: no groups cached by the previous call
    rec = _stream()
    log_tracks(rec, run)
    log_range_circles(rec, run)
    log_ranges(rec, run)
    log_detections(rec, run)
    log_lanes(rec, run)
    log_features(rec, run)
    log_detector_scores(rec, run)
    log_why(rec, run)
    log_errors(rec, run, 100.0)
    _finish(rec)


def _trail_rows(run: Run) -> int:
    return sum(trail_indices(floats(rows, "t_s")).size for _, rows in groups(run.review.tracks, ["vehicle", "source"]))


def bulk_rows(run: Run) -> int:
    """Rows in the bulk subset: two positions and two trail samples per track sample, circles, every scalar, lanes."""
    rv = run.review
    n_det_epochs = len(rv.detections.drop_duplicates(["t_s", "follower", "leader"]))
    n_anfis = int(rv.detections.method.str.startswith("anfis").sum())
    epochs = rv.detections.drop_duplicates(["t_s", "follower", "leader"])
    n_features = sum(int(np.isfinite(floats(epochs, f)).sum()) for f in present_features(rv.detections))
    n_scores = 2 * int(rv.detections.method.isin(list(scored())).sum())
    n_why = sum(len(why_documents(rows, training_end_s(run))[1]) for _, rows in groups(rv.detections,
                                                                                      ["follower", "leader"]))
    return (2 * len(rv.tracks) + 2 * _trail_rows(run) + 4 * len(rv.ranges) + 3 * n_det_epochs + n_det_epochs
            + len(rv.detections) + 2 * n_anfis + len(rv.errors) + n_features + n_scores + n_why)


def _set(rec: rr.RecordingStream, run: Run, t: float) -> None:
    rec.set_time("time", timestamp=np.datetime64(run.review.trial_start_ns + round(t * 1e9), "ns"))


def bulk_row_by_row(run: Run) -> None:
    """The same data with one `log` call per row and per entity."""
    rec = _stream()
    for (vehicle, source), rows in groups(run.review.tracks, ["vehicle", "source"]):
        cid = class_id(str(source))
        trail = set(trail_indices(floats(rows, "t_s")).tolist())
        for i, r in enumerate(rows.itertuples()):
            _set(rec, run, r.t_s)
            rec.log(run.path("map", vehicle, source, "position"), rr.GeoPoints(lat_lon=[[r.lat_deg, r.lon_deg]],
                                                                                class_ids=[cid]))
            rec.log(run.path("local", vehicle, source, "position"), rr.Points2D([[r.east_m, -r.north_m]],
                                                                                 class_ids=[cid]))
            if i in trail:
                rec.log(run.path("map", vehicle, source, "trail"), rr.GeoPoints(lat_lon=[[r.lat_deg, r.lon_deg]]))
                rec.log(run.path("local", vehicle, source, "trail"), rr.Points2D([[r.east_m, -r.north_m]]))
    for (follower, leader), rows in groups(run.review.ranges, ["follower", "leader"]):
        for r in rows.itertuples():
            _set(rec, run, r.t_s)
            rec.log(run.path("local", "ranges", follower, leader),
                    rr.Ellipses2D(half_sizes=[[r.horizontal_m] * 2], centers=[[r.leader_east_m, -r.leader_north_m]]))
            for name, v in (("measured", r.measured_m), ("true", r.true_m), ("residual", r.residual_m)):
                rec.log(run.path("series", "range", follower, leader, name), rr.Scalars(v))
    t_a = training_end_s(run)
    plotted = scored()
    have = present_features(run.review.detections)
    group_of = {f: key for key, _, names in FEATURE_GROUPS for f in names}
    for (follower, leader), rows in groups(run.review.detections, ["follower", "leader"]):
        methods = sorted(rows["method"].unique())
        paths = dict(zip(["truth", *methods], lane_paths(run, (), leader, methods), strict=True))
        for r in rows.drop_duplicates("t_s").itertuples():
            _set(rec, run, r.t_s)
            for f in FEATURES:
                rec.log(run.path("series", f, follower, leader), rr.Scalars(getattr(r, f)))
            for f in have:
                if np.isfinite(v := getattr(r, f)):
                    rec.log(run.path("features", follower, leader, group_of[f], f), rr.Scalars(v))
            rec.log(paths["truth"], rr.StateChange(state=truth_states(np.array([r.label]))[0]))
        for t, doc in zip(*why_documents(rows, t_a), strict=True):
            _set(rec, run, t)
            rec.log(run.path("why", follower, leader), rr.TextDocument(doc, media_type="text/markdown"))
        for r in rows.itertuples():
            _set(rec, run, r.t_s)
            state = epoch_states(np.array([r.flagged]), np.array([r.label]), np.array([r.t_s > t_a]))[0]
            rec.log(paths[r.method], rr.StateChange(state=state))
            if r.method.startswith("anfis"):
                rec.log(run.path("series", "anfis", follower, leader, r.method, "output"), rr.Scalars(r.score))
                rec.log(run.path("series", "anfis", follower, leader, r.method, "T2"), rr.Scalars(r.threshold))
            if r.method in plotted:
                base = run.path("scores", r.method, follower, leader)
                rec.log(base + "/score", rr.Scalars(r.score))
                rec.log(base + "/threshold", rr.Scalars(r.threshold))
    for r in run.review.errors.itertuples():
        _set(rec, run, r.t_s)
        rec.log(run.path("series", "error", r.follower, r.method), rr.Scalars(r.error_m))
    _finish(rec)


def timed(fn: Callable[[], object], repeats: int = REPEATS) -> tuple[float, float]:
    """Median wall time and median process CPU time (all threads) of fn, over the same calls."""
    wall, cpu = [], []
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return float(np.median(wall)), float(np.median(cpu))


def full_in_memory(review: object) -> None:
    """The whole recording, blueprint included, into memory."""
    rec = views.build_recording([review])
    memory = rec.memory_recording()     # the buffered data moves into it
    rec.flush()
    memory.drain_as_bytes()


def sample_trial_review(workdir: Path) -> object:
    """The bundled sample trial recorded and replayed with every method: the ReviewData `demo` logs."""
    archive = workdir / "lake.mcap"
    record(load_manifest(ROOT / "samples/lake_trial/trial.toml"), archive)
    config = load_config(default_methods=runnable_names())
    return replay_archive(archive, config, write_output=False, review=True).review


def describe(name: str, review: object) -> str:
    """One line of the ReviewData's sizes."""
    return (f"{name}: tracks {len(review.tracks)}, ranges {len(review.ranges)}, detections "
            f"{len(review.detections)}, errors {len(review.errors)}, anfis epochs {len(review.anfis_epochs)}, "
            f"explain {len(review.anfis_explain)}, kmcdf {len(review.kmcdf)}")


def first_visible(archive: Path, tmp: Path) -> list[object]:
    """One row: the bulk path's time to a complete .rrd (wall, CPU), and the streamed path's first stretch and
    complete recording (wall, CPU) with its stretches; '-' where this tree has no streamed path."""
    c0, t0 = time.process_time(), time.perf_counter()
    outcome = replay_archive(archive, load_config(), write_output=False, review=True, require_work=True)
    views.save_rrd([outcome.review], tmp / "bulk.rrd")
    bulk, bulk_cpu = time.perf_counter() - t0, time.process_time() - c0
    try:
        from replay.views.stream import stream_replay
    except ImportError:
        return [bulk, bulk_cpu, "-", "-", "-", "-", "-"]
    c0, t0 = time.process_time(), time.perf_counter()
    streamed = stream_replay(archive, tmp / "streamed.rrd", None)
    whole, whole_cpu = time.perf_counter() - t0, time.process_time() - c0
    return [bulk, bulk_cpu, streamed.first_s, whole, whole_cpu, bulk / (streamed.first_s or whole),
            streamed.stretches]


def main_first_visible(mission_s: float, rounds: int) -> None:
    """Print the time-to-first-data table (median of `rounds` rounds, the two paths alternating in each)."""
    tmp = Path(tempfile.mkdtemp(prefix="bench_views_first_"))
    cases = {"sample trial": tmp / "lake.mcap"}
    record(load_manifest(ROOT / "samples/lake_trial/trial.toml"), cases["sample trial"])
    if mission_s > 0:
        from bench.mission import write_mission

        cases[f"mission {mission_s / 3600:g} h"] = tmp / "mission.mcap"
        write_mission(cases[f"mission {mission_s / 3600:g} h"], mission_s)
    table = []
    for name, archive in cases.items():
        runs = [first_visible(archive, tmp) for _ in range(rounds)]
        table.append([name, *[statistics.median(col) if all(isinstance(v, float | int) for v in col) else "-"
                              for col in zip(*runs, strict=True)]])
    print_table(f"`view ARCHIVE` until a viewer can draw (median of {rounds}; default methods)",
                ["trial", "bulk: whole .rrd (s)", "bulk CPU (s)", "streamed: first stretch (s)",
                 "streamed: complete (s)", "streamed CPU (s)", "bulk / first stretch", "stretches"], table)


def main() -> None:
    """Print the tables (`--first-visible`: only the time to the first data a viewer can draw)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--first-visible", action="store_true")
    parser.add_argument("--mission-s", type=float, default=0.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    if args.first_visible:
        main_first_visible(args.mission_s, args.rounds)
        return
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
    bulk_columnar(real_run)                       # first use of each archetype pays rerun's set-up
    r_col, r_col_cpu = timed(lambda: bulk_columnar(real_run))
    r_row, r_row_cpu = timed(lambda: bulk_row_by_row(real_run), 2)
    r_save, r_cpu = timed(lambda: views.save_rrd([real], tmp / "lake.rrd"))
    real_mb = (tmp / "lake.rrd").stat().st_size / 1e6
    print(describe("synthetic ReviewData", review) + f"; rerun-sdk {rr.__version__}")
    print(describe("sample trial ReviewData", real))
    print_table("the sample trial (samples/lake_trial, every method): bulk series both ways and the whole .rrd",
                ["logging", "rows", "time (s)", "rows/s", "ratio to columnar"],
                [["send_columns", real_rows, r_col, real_rows / r_col, 1.0],
                 ["row-by-row rr.log", real_rows, r_row, real_rows / r_row, r_row / r_col],
                 ["send_columns, process CPU time", real_rows, r_col_cpu, real_rows / r_col_cpu, 1.0],
                 ["row-by-row rr.log, process CPU time", real_rows, r_row_cpu, real_rows / r_row_cpu,
                  r_row_cpu / r_col_cpu],
                 [f"whole recording saved .rrd ({real_mb:.1f} MB), goal < {GOAL_S:.0f} s", "-", r_save, "-",
                  "met" if r_save < GOAL_S else "NOT met"],
                 ["  the same, process CPU time", "-", r_cpu, "-", "met" if r_cpu < GOAL_S else "NOT met"]])
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
