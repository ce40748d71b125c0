"""The block path (ArchiveReader.blocks, Engine.push_block) against the per-message path, on the same trials.

The block path takes a window's INS, DVL and GPS samples as columns and
releases the followers' queues only where the per-message path would
release something (replay.engine.blocks). Nothing it computes may differ:
every listener call (positions compared per vehicle and source, as they come
as columns), every count, the scores, the runners' results and metrics.json
are compared bit for bit, on the sample trial (USBL, three leaders' worth of
ranges, training) and on a synthetic mission written with the awkward cases
(messages out of order in their chunk, fixes without a position, invalid and earth-frame
DVL samples, topics the engine passes over, diagnostics, a late first fix).
"""

from __future__ import annotations

import json
import math
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formats import schemas as S
from formats.mcap_blocks import COLUMN_FIELDS
from formats.mcap_reader import ArchiveReader
from formats.mcap_writer import ArchiveWriter
from recorders.manifest import load_manifest
from recorders.record import record
from replay.engine.config import RunConfig
from replay.engine.core import Engine
from replay.engine.layout import plan_trial
from replay.engine.tracks import Horizon, Track
from replay.events import Fix, Listener
from replay.run import pipeline as P
from replay.run.pipeline import replay_archive
from samples.scenario import Scenario
from samples.simulator import simulate_trial

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"


class Recorder(Listener):
    """Every listener call, in order; positions by (vehicle, source)."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self.pos: dict[tuple[str, str], list[tuple[float, ...]]] = {}

    def origin(self, *a: Any) -> None:
        self.calls.append(("origin", a))

    def epoch(self, f: str, r: Any, leader: Any) -> None:
        self.calls.append(("epoch", f, tuple(r), leader))

    def estimates(self, f: str, t: float, e: Any) -> None:
        self.calls.append(("estimates", f, t, dict(e)))

    def errors(self, f: str, s: Any) -> None:
        self.calls.append(("errors", f, tuple(s)))

    def usbl(self, e: Any, p: Any) -> None:
        self.calls.append(("usbl", e.t_s, e.target, e.nodes, dict(p)))

    def trained(self, f: str, m: Any, t: float) -> None:
        self.calls.append(("trained", f, t))

    def finished(self, f: str, r: Any) -> None:
        self.calls.append(("finished", f, pickle.dumps(r.epochs), pickle.dumps(r.rejected)))

    def event(self, t: float, level: str, text: str) -> None:
        self.calls.append(("event", t, level, text))

    def position(self, v: str, s: str, fix: Fix) -> None:
        self.pos.setdefault((v, s), []).append((fix.t_s, fix.lat_rad, fix.lon_rad, fix.depth_m))


def engine_run(archive: Path, blocks: bool, config: RunConfig | None = None) -> tuple[Recorder, Engine, Any]:
    """The engine over an archive as replay_archive sets it up, fed by blocks or message by message."""
    config = config or RunConfig()
    with ArchiveReader(archive) as reader:
        summary = reader.summary()
        trial = P.trial_metadata(reader.metadata_json("trial"))
        readable = P._readable_topics(summary, reader)
        positions = [t for t, v in summary.topics.items() if v["schema"] in P.POSITION_SCHEMAS]
        layout = plan_trial(trial, readable, config.stack.methods, positions)
        topics = [t for t in readable if t == "/diagnostics" or t in layout.sources
                  or any(t == f"/{v}/{s}" for v in layout.roles for s in P.SENSORS)]
        rec = Recorder()
        assert summary.start_ns is not None
        engine = Engine(layout, config, summary.start_ns, [rec])
        if blocks:
            columnar = [t for t in topics if summary.topics[t]["schema"] in COLUMN_FIELDS]
            for block in reader.blocks(topics, columns=columnar):
                engine.push_block(block)
        else:
            for m in reader.messages(topics):
                engine.push(m.topic, m.log_time_ns, m.message)
        results = engine.finish()
    return rec, engine, results


def assert_same_runs(archive: Path, config: RunConfig | None = None) -> Engine:
    ref, e_ref, res_ref = engine_run(archive, False, config)
    got, e_got, res_got = engine_run(archive, True, config)
    assert e_got.messages == e_ref.messages and e_got.last_s == e_ref.last_s
    assert dict(e_got.counts) == dict(e_ref.counts)
    for name, pipe in e_ref.followers.items():
        assert dict(e_got.followers[name].counts) == dict(pipe.counts)
    assert len(got.calls) == len(ref.calls)
    for a, b in zip(ref.calls, got.calls):
        assert pickle.dumps(b) == pickle.dumps(a), (a[:2], b[:2])
    assert got.pos == ref.pos
    assert pickle.dumps(e_got.scores()) == pickle.dumps(e_ref.scores())
    assert pickle.dumps({k: (r.epochs, r.rejected, r.thresholds) for k, r in res_got.items()}) == \
        pickle.dumps({k: (r.epochs, r.rejected, r.thresholds) for k, r in res_ref.items()})
    return e_ref


@pytest.fixture(scope="module")
def sample_archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    archive = tmp_path_factory.mktemp("blocks") / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), archive)
    return archive


def write_mission(path: Path, duration_s: float, seed: int = 3, out_of_order: bool = True) -> None:
    """A simulated trial written straight into an archive, with the awkward cases the engine must count
    (INS samples out of log-time order too, unless not `out_of_order`)."""
    trial = simulate_trial(Scenario().with_options(duration_s=duration_s), seed)
    rng = np.random.default_rng(seed)
    with ArchiveWriter(path, chunk_size=64 << 10) as w:
        w.write("/diagnostics", S.Log(timestamp=S.timestamp(0), level=S.Log.WARNING, message="noise", name="x"),
                trial.t_ns(np.array([5.0]))[0].item())
        for v in trial.vehicles:
            g, ins, dvl = v.gps, v.ins, v.dvl
            late = 30.0 if v.role == "follower" else 0.0     # the follower's first fix after others' samples
            for t, lat, lon, alt in zip(trial.t_ns(g.t_s).tolist(), g.lat_deg.tolist(), g.lon_deg.tolist(),
                                        g.altitude_m.tolist()):
                if (t - trial.t_ns(g.t_s)[0]) / 1e9 < late:
                    continue
                if rng.random() < 0.02:
                    lat = math.nan          # a fix without a position: counted, not a track point
                w.write(f"/{v.name}/gps", S.location_fix(t, v.name, lat, lon, alt), t)
                if rng.random() < 0.05:     # a topic the engine passes over
                    w.write(f"/{v.name}/gps/status", S.GnssStatus(timestamp=S.timestamp(t)), t)
            for t, lat, lon, depth, hdg in zip(trial.t_ns(ins.t_s).tolist(), ins.lat_deg.tolist(),
                                               ins.lon_deg.tolist(), ins.depth_m.tolist(),
                                               ins.heading_deg.tolist()):
                r = rng.random()
                if r < 0.01:
                    hdg = math.nan
                elif r < 0.02:
                    depth = math.nan
                elif r < 0.03 and out_of_order:
                    t -= 700_000_000        # out of log-time order in its chunk (the reader sorts it)
                w.write(f"/{v.name}/ins", S.InsState(timestamp=S.timestamp(t), frame_id=v.name, latitude=lat,
                                                     longitude=lon, depth_m=depth, heading_deg=hdg), t)
            for t, fwd, stbd in zip(trial.t_ns(dvl.t_s).tolist(), dvl.forward_mps.tolist(),
                                    dvl.starboard_mps.tolist()):
                r = rng.random()
                frame = S.DvlVelocity.EARTH_NED if r < 0.05 else S.DvlVelocity.BODY_FRD
                w.write(f"/{v.name}/dvl", S.DvlVelocity(timestamp=S.timestamp(t), frame_id=v.name, frame=frame,
                                                        velocity_x_mps=fwd, velocity_y_mps=stbd,
                                                        velocity_z_mps=0.0, valid=r > 0.97 or r < 0.9), t)
        rr = trial.ranges
        for t, f, ld, rng_m, tt in zip(trial.t_ns(rr.t_s).tolist(), rr.follower.tolist(), rr.leader.tolist(),
                                       rr.range_m.tolist(), rr.travel_time_s.tolist()):
            w.write(f"/{f}/modem/range", S.AcousticRange(timestamp=S.timestamp(t), source=ld, destination=f,
                                                         travel_time_s=tt, range_m=rng_m, kind="ping"), t)
        w.add_metadata("trial", {"name": "blocks", "vehicles": [{"name": v.name, "role": v.role}
                                                                for v in trial.vehicles]})


@pytest.fixture(scope="module")
def mission_archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    archive = tmp_path_factory.mktemp("blocks") / "mission.mcap"
    write_mission(archive, 900.0)
    return archive


@pytest.fixture(scope="module")
def ordered_mission(tmp_path_factory: pytest.TempPathFactory) -> Path:
    archive = tmp_path_factory.mktemp("blocks") / "ordered.mcap"
    write_mission(archive, 900.0, seed=5, out_of_order=False)
    return archive


def assert_blocks_are_messages(archive: Path) -> None:
    """ArchiveReader.blocks hands out what messages() does, in its order, the columns equal to the fields."""
    with ArchiveReader(archive) as reader:
        ref = list(reader.messages())
        columnar = [t for t, v in reader.summary().topics.items() if v["schema"] in COLUMN_FIELDS]
        k = 0
        for block in reader.blocks(columns=columnar):
            for i in range(len(block)):
                m = ref[k]
                k += 1
                topic = block.topics[block.topic_index[i]]
                row = int(block.row[i])
                assert (topic, int(block.log_ns[i])) == (m.topic, m.log_time_ns)
                assert block.message(topic, row) == m.message
                for name, col in block.columns.get(topic, {}).items():
                    want = float(getattr(m.message, name))
                    assert col[row] == want or (math.isnan(want) and math.isnan(col[row]))
        assert k == len(ref)


def test_blocks_read_what_messages_read(sample_archive: Path, mission_archive: Path) -> None:
    assert_blocks_are_messages(sample_archive)
    assert_blocks_are_messages(mission_archive)


def test_sample_trial_block_path_equals_per_message_path(sample_archive: Path) -> None:
    engine = assert_same_runs(sample_archive)
    assert engine.usbl_epochs > 0          # the USBL stops were exercised


def test_mission_block_path_equals_per_message_path(mission_archive: Path) -> None:
    engine = assert_same_runs(mission_archive)
    counts = {**engine.counts, **{k: v for p in engine.followers.values() for k, v in p.counts.items()}}
    # the awkward cases happened (else the test would not test them)
    assert counts["gps_without_position"] > 0 and "dvl_frame_unusable" not in counts
    assert counts["dvl_invalid"] > 0


@pytest.mark.parametrize("t_a", [600.0, 601.7])
def test_releases_merged_equal_releases_one_by_one(ordered_mission: Path, monkeypatch: pytest.MonkeyPatch,
                                                   t_a: float) -> None:
    """In order, the releases that only move the follower's dead reckoning go as one (blocks._merged_release):
    the same calls, results and counts as message by message, before and after the training at t_a (601.7 s:
    between two range epochs, so that only the training stops a merge there)."""
    from replay.engine import blocks as B
    from replay.run.config import load_config

    spans: list[int] = []
    real = B._merged_release

    def spy(engine: Engine, j: int, *args: Any) -> int:
        out = real(engine, j, *args)
        spans.append(out - j)
        return out

    monkeypatch.setattr(B, "_merged_release", spy)
    engine = assert_same_runs(ordered_mission, load_config(None, [f"stack.training_window_s={t_a}"]))
    assert engine.counts["out_of_order_messages"] == 0
    assert sum(1 for x in spans if x > 0) > 100        # merged releases happened
    assert engine._trained        # the detectors were trained (at t_a, where merging stops until it is said)


def test_mission_block_path_with_usbl_fixes_to_filters(sample_archive: Path) -> None:
    from replay.run.config import load_config

    assert_same_runs(sample_archive, load_config(None, ["engine.usbl_update=kmcdf2"]))


@pytest.mark.parametrize("archive_name", ["sample_archive", "mission_archive"])
def test_replay_metrics_and_review_equal(archive_name: str, request: pytest.FixtureRequest,
                                         tmp_path: Path) -> None:
    archive = request.getfixturevalue(archive_name)
    ref = replay_archive(archive, output=tmp_path / "a.mcap", blocks=False, review=True)
    got = replay_archive(archive, output=tmp_path / "b.mcap", blocks=True, review=True)
    a = json.loads((tmp_path / "a.metrics.json").read_text())
    b = json.loads((tmp_path / "b.metrics.json").read_text())
    a.pop("wall_s")
    b.pop("wall_s")
    assert a == b
    for name in ("ranges", "detections", "errors", "anfis_epochs", "kmcdf", "events"):
        fa, fb = getattr(ref.review, name), getattr(got.review, name)
        assert pickle.dumps(fa) == pickle.dumps(fb), name     # NaN inside objects: not `equals`
    # track rows: positions come per block, so rows of different sources interleave otherwise
    key = ["vehicle", "source", "t_s"]
    ta = ref.review.tracks.sort_values(key, kind="stable").reset_index(drop=True)
    tb = got.review.tracks.sort_values(key, kind="stable").reset_index(drop=True)
    assert pickle.dumps(ta) == pickle.dumps(tb)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 500), st.booleans()), min_size=1, max_size=60),
       st.lists(st.floats(-10, 520), min_size=1, max_size=8), st.integers(1, 7))
def test_track_blocks_with_a_horizon_equal_fixes_one_by_one(rows: list[tuple[float, bool]], lookups: list[float],
                                                            cut: int) -> None:
    """Track.extend with rows visible from their message number gives every lookup `add` gave."""
    one = Track(keep_s=60.0)
    horizon = Horizon()
    many = Track(keep_s=60.0, horizon=horizon)
    t = np.array([r[0] for r in rows])
    lat = np.where([r[1] for r in rows], np.nan, t * 1e-6)
    lon, depth, seq = -t * 1e-6, t * 0.1, np.arange(1, len(rows) + 1, dtype=float)
    half = min(cut, len(rows))
    horizon.seq = 0
    many.extend(t[:half], lat[:half], lon[:half], depth[:half], seq[:half])
    for i, (ti, la, lo, de) in enumerate(zip(t.tolist(), lat.tolist(), lon.tolist(), depth.tolist())):
        if i == half:       # the next block comes once the stream has reached the end of this one
            many.extend(t[half:], lat[half:], lon[half:], depth[half:], seq[half:])
        one.add(Fix(ti, la, lo, de))
        horizon.seq = i + 1
        for x in lookups:
            assert many.at(x, 5.0) == one.at(x, 5.0)


@pytest.mark.parametrize("archive_name", ["sample_archive", "mission_archive"])
@pytest.mark.parametrize("min_dt", [1.0, 0.05, 7.0])
def test_navigation_columns_from_blocks_equal_messages(archive_name: str, min_dt: float,
                                                        request: pytest.FixtureRequest) -> None:
    """ColumnCollector.add_block gathers what add gathers message by message (INS samples kept and held)."""
    from replay.navigation.columns import ColumnCollector

    archive = request.getfixturevalue(archive_name)
    with ArchiveReader(archive) as reader:
        summary = reader.summary()
        vehicles = sorted({t.strip("/").split("/")[0] for t in summary.topics if t.endswith("/ins")})
        assert summary.start_ns is not None
        one, many = (ColumnCollector(vehicles, summary.start_ns, min_dt) for _ in range(2))
        topics = [t for t in one.topics if t in summary.topics]
        for m in reader.messages(topics):
            one.add(m.topic, m.log_time_ns, m.message)
        columnar = [t for t in topics if summary.topics[t]["schema"] in COLUMN_FIELDS]
        for block in reader.blocks(topics, columns=columnar):
            many.add_block(block)
    for v in vehicles:
        assert pickle.dumps(many.columns(v)) == pickle.dumps(one.columns(v)), v


def test_long_track_blocks_equal_fixes_one_by_one() -> None:
    """A day's worth of rows through a short keep_s: pruning and compaction keep every lookup `add`'s."""
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.01, 0.05, 30_000))
    lat, lon, depth = t * 1e-7, -t * 1e-7, t * 1e-3
    one, horizon = Track(keep_s=5.0), Horizon()
    many = Track(keep_s=5.0, horizon=horizon)
    cuts = list(range(0, t.size, 1000)) + [t.size]
    for a, b in zip(cuts, cuts[1:]):
        horizon.seq = a
        many.extend(t[a:b], lat[a:b], lon[a:b], depth[a:b], np.arange(a + 1, b + 1, dtype=float))
        for i in range(a, b):
            one.add(Fix(float(t[i]), float(lat[i]), float(lon[i]), float(depth[i])))
            horizon.seq = i + 1
            if i % 97 == 0:
                for x in (t[i] - 1.2, t[i] - 0.013, t[i], t[i] + 0.01, t[i] - 6.0):
                    assert many.at(float(x), 0.2) == one.at(float(x), 0.2)


class _RegroupEveryStep:
    """The runner's DR step as before its method groups were kept: the methods grouped again at every step."""

    def __enter__(self) -> None:
        from replay.stack.runner import CooperativeRunner

        self.cls, self.orig = CooperativeRunner, CooperativeRunner._propagate

        def propagate(runner: Any, t_s: float) -> None:
            runner._groups = None
            self.orig(runner, t_s)

        CooperativeRunner._propagate = propagate  # type: ignore[method-assign]

    def __exit__(self, *exc: object) -> None:
        self.cls._propagate = self.orig  # type: ignore[method-assign]


@pytest.mark.parametrize("archive_name", ["sample_archive", "mission_archive"])
def test_kept_method_groups_equal_grouping_every_step(archive_name: str, request: pytest.FixtureRequest) -> None:
    """The DR time update moves each group of equal states once and keeps the groups until an update: every
    listener call, score and result equals grouping the methods again at every DR step, on both paths."""
    archive = request.getfixturevalue(archive_name)
    with _RegroupEveryStep():
        ref, e_ref, res_ref = engine_run(archive, False)
    for blocks in (False, True):
        got, e_got, res_got = engine_run(archive, blocks)
        assert len(got.calls) == len(ref.calls)
        for a, b in zip(ref.calls, got.calls):
            assert pickle.dumps(b) == pickle.dumps(a), (a[:2], b[:2])
        assert pickle.dumps(e_got.scores()) == pickle.dumps(e_ref.scores())
        assert pickle.dumps({k: (r.epochs, r.rejected) for k, r in res_got.items()}) == \
            pickle.dumps({k: (r.epochs, r.rejected) for k, r in res_ref.items()})


_STATE = st.tuples(st.floats(-1.5, 1.5), st.floats(-3.0, 3.0), st.floats(1e-16, 1e-6), st.floats(-1e-7, 1e-7),
                   st.floats(1e-16, 1e-6))


@settings(max_examples=100, deadline=None)
@given(st.lists(_STATE, min_size=1, max_size=7), st.floats(1e-3, 30.0), st.floats(-5.0, 5.0), st.floats(-2.0, 2.0),
       st.floats(-7.0, 7.0), st.floats(0.0, 300.0))
def test_filters_moved_together_equal_one_at_a_time(states: list[tuple[float, ...]], dt: float, fwd: float,
                                                    lat_v: float, hdg: float, depth: float) -> None:
    """dr_predict_moved over several states gives each state's own dr_predict, bit for bit."""
    from replay.stack.filters.ckf import State2, dr_displacement, dr_predict, dr_predict_moved

    s2 = [State2(*s) for s in states]
    north, east = dr_displacement(dt, fwd, lat_v, hdg)
    together = dr_predict_moved(s2, dt, north, east, depth, (0.3, 0.4))
    assert together == [dr_predict(s, dt, fwd, lat_v, hdg, depth, (0.3, 0.4)) for s in s2]


def _decimated_one_at_a_time(ts: list[float], last: float, gap: float) -> tuple[list[int], float]:
    keep = []
    for i, t in enumerate(ts):
        if not t - last < gap:
            keep.append(i)
            last = t
    return keep, last


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0.0, 1e-3), max_size=80), st.sampled_from([0.02, 0.1, 0.2, 0.9999999999, 1.0]),
       st.sampled_from([0.0, 1e4, 123456.789]), st.sampled_from([-math.inf, -0.5, 0.3, 0.0]), st.booleans())
def test_block_positions_decimated_as_one_at_a_time(jitter: list[float], step: float, t0: float, last: float,
                                                    swap: bool) -> None:
    """The review collector's bisection over a block's times keeps the points the one-at-a-time rule keeps."""
    from replay.review.collector import DECIMATE_SLACK_S, INS_DECIMATE_S, decimated

    ts = [t0 + step * k + j for k, j in enumerate(jitter)]
    if swap and len(ts) > 3:
        ts[1], ts[2] = ts[2], ts[1]       # out of order: the one-at-a-time loop
    gap = INS_DECIMATE_S - DECIMATE_SLACK_S
    assert decimated(ts, t0 + last, gap) == _decimated_one_at_a_time(ts, t0 + last, gap)
