"""Any trial, reviewed: one-vehicle logs of the shapes users bring, each recorded, replayed and viewed end to end.

Shapes (built here, seconds of data each): a ROS 1 bag of a ground robot (NavSatFix, Imu, Odometry on a manifest
origin); a MOOS alog of a boat that dives (GPS_LAT/GPS_LONG, NAV_LAT/NAV_LONG/NAV_YAW/NAV_DEPTH, an SBG's
INS_NAV key=value); an ArduSub tlog (GPS_RAW_INT, GLOBAL_POSITION_INT, ATTITUDE, DISTANCE_SENSOR); an ArduSub
dataflash `.BIN` without GPS (XKF1, BARO, `time_base = "boot"`). Each goes through the CLI as a user runs it:
`record`, `replay --json -o results.mcap`, `view results.mcap --save` and `view trial.mcap --save` (no display:
the recording is saved and the command to open it printed). The recordings are read back with Rerun's reader.

The INS error at the GPS fixes is checked against a slow reference written from the positions the test wrote:
for each fix, the last INS position strictly before it (at most 5 s old), carried to the fix time with the
velocity the log gives (or, where it gives none, the velocity of the two INS positions before), on a sphere.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from formats.geodesy import local_to_geodetic
from replay.cli import main
from tests.test_views import Rrd
from tests.trial_shapes import (
    NOGPS_ORIGIN,
    NS,
    enu_quaternion,
    imu,
    mavlink,
    navsatfix,
    odometry,
    ros1_typestore,
    tlog_bytes,
    write_nogps_bin,
    write_ros1,
)

T0 = 1476237600  # 2016-10-12 02:00:00 UTC, s
LAT0, LON0 = 45.7, 126.6
R = 6_378_137.0  # the reference's sphere (the recorders' local frame uses the same radius)
NEEDS_RANGES = "needs modem ranges from a leader with a position"
NEEDS_DVL_AND_RANGES = "needs DVL velocities on the vehicle and modem ranges from a leader with a position"
NEEDS_USBL = "needs USBL fixes"
COOPERATIVE = ("ckf", "ackf")
DETECTORS = ("chi_square", "dual_threshold", "anfis", "anfis_aqpso", "anfis_compensation")
POSITIONING = ("kmcdf1", "kmcdf2", "gar", "ear", "lms", "lhc")
# the review measures on WGS84 radii at the mid latitude, the reference on the sphere above: at 45.7 deg they
# differ by at most 0.35 % of a distance, under 3 cm for the errors of these trials (all below 8 m)
TOLERANCE_M = 0.03
MAX_ERROR_M = 8.0


# ---------------------------------------------------------------- the reference

def geodetic(north: float, east: float) -> tuple[float, float]:
    """Latitude and longitude (deg) of a point north/east (m) of (LAT0, LON0), on the sphere."""
    return (LAT0 + math.degrees(north / R), LON0 + math.degrees(east / (R * math.cos(math.radians(LAT0)))))


def recorded(north: float, east: float) -> tuple[float, float]:
    """Latitude and longitude (deg) a recorder gives a local north/east (m) about (LAT0, LON0): the WGS84 radii of
    the origin (formats.geodesy), which differ from `geodetic`'s sphere by a few tenths of a percent."""
    lat, lon = local_to_geodetic(east, north, LAT0, LON0)
    return float(lat), float(lon)


def local(lat: float, lon: float) -> tuple[float, float]:
    """North and east (m) of (LAT0, LON0) of a latitude and longitude, on the sphere: the inverse of `geodetic`."""
    return math.radians(lat - LAT0) * R, math.radians(lon - LON0) * R * math.cos(math.radians(LAT0))


@dataclass
class Written:
    """What a shape's log holds, in mission seconds from its first message: GPS fixes (t, lat, lon) and INS
    positions (t, lat, lon, v_north, v_east), the velocity NaN where the log gives none."""

    fixes: list[tuple[float, float, float]] = field(default_factory=list)
    ins: list[tuple[float, float, float, float, float]] = field(default_factory=list)


def reference_ins_errors(w: Written, max_age_s: float = 5.0) -> list[float]:
    """The INS error (m) at each GPS fix, slowly: NaN where no INS position is recent enough (module text)."""
    out = []
    for t, lat, lon in w.fixes:
        before = [s for s in w.ins if s[0] < t and t - s[0] <= max_age_s]
        if not before:
            out.append(math.nan)
            continue
        ti, la, lo, vn, ve = before[-1]
        n, e = local(la, lo)
        if not (math.isfinite(vn) and math.isfinite(ve)):
            earlier = [s for s in w.ins if s[0] < ti]
            if not earlier:  # one position: no velocity to carry it with
                out.append(math.nan)
                continue
            tp, lap, lop = earlier[-1][:3]
            n_p, e_p = local(lap, lop)
            vn, ve = (n - n_p) / (ti - tp), (e - e_p) / (ti - tp)
        fn, fe = local(lat, lon)
        out.append(math.hypot(n + vn * (t - ti) - fn, e + ve * (t - ti) - fe))
    return out


def ins_path_m(w: Written, t_a: float, t_b: float) -> float:
    """The INS path length (m) between two times, linear between positions."""
    pts = [(t, *local(la, lo)) for t, la, lo, _, _ in w.ins]

    def at(t: float) -> tuple[float, float, float]:
        k = max(i for i, p in enumerate(pts) if p[0] <= t)
        (t0, n0, e0), (t1, n1, e1) = pts[k], pts[min(k + 1, len(pts) - 1)]
        f = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
        return t, n0 + f * (n1 - n0), e0 + f * (e1 - e0)

    inside = [at(t_a)] + [p for p in pts if t_a < p[0] < t_b] + [at(t_b)]
    return sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in zip(inside, inside[1:]))


# ---------------------------------------------------------------- the path driven, and the INS's drift from it

V_NORTH, V_EAST = 0.5, 1.0                      # m/s, a straight line from the origin
HEADING = math.degrees(math.atan2(V_EAST, V_NORTH))


def truth(t: float) -> tuple[float, float]:
    """Where the vehicle is at mission second t (north, east m of the origin)."""
    return V_NORTH * t, V_EAST * t


def drifted(t: float, rate: tuple[float, float] = (0.03, -0.02)) -> tuple[float, float]:
    """Where its INS puts it: 20 cm off at the start, drifting by `rate` m/s north and east."""
    n, e = truth(t)
    return n + 0.2 + rate[0] * t, e + 0.1 + rate[1] * t


# ---------------------------------------------------------------- the CLI, as a user runs it

@dataclass
class Reviewed:
    """What the CLI gave for a trial: replay's metrics and both recordings read back."""

    metrics: dict
    results_rrd: Rrd
    trial_rrd: Rrd
    printed: str


def manifest(tmp: Path, vehicle: str, fmt: str, path: str, extra: str = "") -> Path:
    (tmp / "trial.toml").write_text(
        f'[trial]\nname = "shape"\ndate = "2016-10-12"\n[[vehicles]]\nname = "{vehicle}"\nrole = "follower"\n'
        f'[[vehicles.logs]]\nformat = "{fmt}"\npath = "{path}"\n{extra}\n')
    return tmp / "trial.toml"


def review(tmp: Path, toml: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch) -> Reviewed:
    """record, replay --json, view of the results and view of the trial: each exits 0."""
    for name in ("DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(name, raising=False)
    trial, results = tmp / "trial.mcap", tmp / "results.mcap"
    assert main(["record", str(toml), "-o", str(trial), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["replay", str(trial), "--json", "-o", str(results)]) == 0
    metrics = json.loads(capsys.readouterr().out)
    assert main(["view", str(results), "--save", str(tmp / "out.rrd")]) == 0
    assert main(["view", str(trial), "--save", str(tmp / "out2.rrd")]) == 0
    printed = capsys.readouterr().out
    for rrd in ("out.rrd", "out2.rrd"):
        assert f"saved {tmp / rrd}" in printed and f"rerun {tmp / rrd}" in printed
    assert "no display" in printed
    return Reviewed(metrics, Rrd(tmp / "out.rrd"), Rrd(tmp / "out2.rrd"), printed)


def tracks(rrd: Rrd, view: str = "map") -> dict[tuple[str, str], str]:
    """(vehicle, source) -> the entity of its whole track, `/<run>/<view>/<vehicle>/<source>/track`."""
    out = {}
    for entity in rrd.static:
        parts = entity.strip("/").split("/")
        if len(parts) == 5 and parts[1] == view and parts[4] == "track":
            out[(parts[2], parts[3])] = entity
    return out


def static_cell(rrd: Rrd, entity: str, column: str) -> list:
    """The one static value of a component of an entity."""
    (value,) = [b.column(column).to_pylist()[0] for b in rrd.static[entity] if column in b.schema.names]
    return value


def track_vertices(rrd: Rrd, entity: str) -> list[tuple[float, float]]:
    """The (lat, lon) vertices of a map track, over its strips (a track breaks where it is silent over 30 s)."""
    cell = static_cell(rrd, entity, "GeoLineStrings:line_strings")
    return [(a, b) for line in cell for a, b in line]


def near(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return abs(a[0] - b[0]) <= 1e-9 and abs(a[1] - b[1]) <= 1e-9


def check_tracks(r: Reviewed, want: set[tuple[str, str]], w: Written, sources: dict[str, list]) -> None:
    """Both recordings draw exactly `want` on the map and in local metres; GPS tracks are every fix written, the
    other sources' (one point a second) points written positions."""
    for rrd in (r.results_rrd, r.trial_rrd):
        assert set(tracks(rrd)) == want and set(tracks(rrd, "local")) == want
        for (_, source), entity in tracks(rrd).items():
            got = track_vertices(rrd, entity)
            if source == "gps":
                assert len(got) == len(w.fixes) and all(near(g, f[1:]) for g, f in zip(got, w.fixes))
            else:
                written = [(s[1], s[2]) for s in sources[source]]
                assert all(any(near(g, p) for p in written) for g in got)
                # one point a second: the samples of these logs come at whole fractions of a second
                span = sources[source][-1][0] - sources[source][0][0]
                assert len(got) == int(span) + 1 and near(got[0], written[0])


def check_ins_errors(r: Reviewed, vehicle: str, w: Written) -> list[float]:
    """The review's INS error at every fix (the Vehicles tab's series) and its scores agree with the reference."""
    ref = reference_ins_errors(w)
    t_fix = [f[0] for f in w.fixes]
    want = [(t, e) for t, e in zip(t_fix, ref) if math.isfinite(e)]
    assert want and max(e for _, e in want) < MAX_ERROR_M
    for rrd in (r.results_rrd, r.trial_rrd):
        (entity,) = [e for e in rrd.temporal if e.endswith(f"/vehicle/{vehicle}/error/ins")]
        got = [v[0] for v in rrd.cells(entity, "Scalars:scalars")]
        got_t = (rrd.times_ns(entity) - rrd.times_ns(entity)[0]) / NS + want[0][0]
        assert got_t == pytest.approx([t for t, _ in want], abs=1e-6)
        assert got == pytest.approx([e for _, e in want], abs=TOLERANCE_M)
    return ref


def scored(ref: list[float], rows: list[int]) -> dict[str, float]:
    """The figures the scoreboard gives for the INS over some fixes of the reference."""
    e = np.array([ref[i] for i in rows])
    return {"error_p50_m": float(np.percentile(e, 50)), "error_p90_m": float(np.percentile(e, 90)),
            "error_max_m": float(e.max())}


def check_skipped(metrics: dict, lacking: str, runs_dr: bool, detectors: str | None = None) -> None:
    """Every cooperative method skipped with the inputs it lacked (the detectors' `detectors` where they lack
    more: they need GPS too), the positioning methods for want of USBL; the DR unless the vehicle has a DVL."""
    want = ({m: lacking for m in COOPERATIVE} | {m: detectors or lacking for m in DETECTORS}
            | {m: NEEDS_USBL for m in POSITIONING})
    if not runs_dr:
        want["dead_reckoning"] = "needs DVL velocities on the vehicle"
    assert metrics["skipped"] == want


# ---------------------------------------------------------------- 1. a ROS 1 bag of a ground robot

def write_ugv_bag(path: Path) -> Written:
    """20 s of a ground robot: NavSatFix each second, Odometry (ENU on the origin) and Imu at 5 Hz, the
    odometry 15 cm before each second and drifting; its twist is 1.118 m/s forward along the heading."""
    ts = ros1_typestore()
    q = enu_quaternion(ts, HEADING)
    w, items = Written(), []
    for k in range(21):
        lat, lon = geodetic(*truth(k))
        items.append(navsatfix(ts, (T0 + k) * NS, lat, lon, 150.0))
        w.fixes.append((float(k), lat, lon))
    for k in range(100):
        t = k * 0.2 + 0.05
        n, e = drifted(t)
        t_ns = T0 * NS + k * 200_000_000 + 50_000_000
        items += [odometry(ts, t_ns, e, n, 0.0, q, math.hypot(V_NORTH, V_EAST)), imu(ts, t_ns + 10_000_000, q)]
        w.ins.append((t, *recorded(n, e), V_NORTH, V_EAST))    # Odometry: local metres on the origin
    write_ros1(path, ts, items)
    return w


def test_ros1_bag_of_a_ground_robot(tmp_path, capsys, monkeypatch):
    w = write_ugv_bag(tmp_path / "ugv.bag")
    r = review(tmp_path, manifest(tmp_path, "ugv", "rosbag", "ugv.bag", f"origin = [{LAT0}, {LON0}]"),
               capsys, monkeypatch)
    check_skipped(r.metrics, NEEDS_DVL_AND_RANGES, runs_dr=False)
    check_tracks(r, {("ugv", "gps"), ("ugv", "ins")}, w, {"ins": w.ins})
    ref = check_ins_errors(r, "ugv", w)
    nav = r.metrics["navigation"]["ugv"]
    assert list(nav["methods"]) == ["ins"] and nav["dives"] == []   # no DVL: no dead reckoning; no GPS gap
    ins = nav["methods"]["ins"]
    assert (ins["fixes"], ins["scored_at"], ins["worst_fix_s"]) == (20, "every fix", 20.0)
    for key, value in scored(ref, list(range(1, 21))).items():
        assert ins[key] == pytest.approx(value, abs=TOLERANCE_M), key


# ---------------------------------------------------------------- 2. a MOOS alog of a boat that dives

DIVE = (20.0, 60.0)  # no GPS between these: a 40 s dive


def write_boat_alog(path: Path) -> tuple[Written, list]:
    """80 s: GPS_LAT/GPS_LONG each second but in the dive; NAV_LAT/NAV_LONG/NAV_YAW/NAV_DEPTH (no NAV_SPEED) each
    second, 0.3 s before the fixes and drifting; the SBG's INS_NAV `TIME=..,LAT=..,LON=..` each second, drifting
    otherwise. Postings are grouped by time, as pLogger writes them; the SBG positions are returned too."""
    w, sbg, lines = Written(), [], []
    for k in range(81):
        if not DIVE[0] < k < DIVE[1]:
            lat, lon = geodetic(*truth(k))
            lines += [(k, f"{k:.3f} GPS_LAT iGPS {lat!r}"), (k, f"{k:.3f} GPS_LONG iGPS {lon!r}")]
            w.fixes.append((float(k), lat, lon))
    for k in range(80):
        t = k + 0.7
        lat, lon = geodetic(*drifted(t))
        depth = 5.0 if DIVE[0] < t < DIVE[1] else 0.0
        yaw = -math.radians(HEADING)  # MOOS: yaw = -heading, radians
        lines += [(t, f"{t:.3f} NAV_LAT pNav {lat!r}"), (t, f"{t:.3f} NAV_LONG pNav {lon!r}"),
                  (t, f"{t:.3f} NAV_YAW pNav {yaw!r}"), (t, f"{t:.3f} NAV_DEPTH pNav {depth}")]
        w.ins.append((t, lat, lon, math.nan, math.nan))
        t = k + 0.4
        lat, lon = geodetic(*drifted(t, (-0.01, 0.04)))
        lines.append((t, f"{t:.3f} INS_NAV iInsSBG TIME={T0 + t:.3f},LAT={lat!r},LON={lon!r},ALT=1.5"))
        sbg.append((t, lat, lon))
    lines.sort(key=lambda x: x[0])
    path.write_text(f"%% LOGSTART {T0}\n" + "\n".join(text for _, text in lines) + "\n")
    return w, sbg


def test_moos_alog_with_an_ins_and_a_dive(tmp_path, capsys, monkeypatch):
    w, sbg = write_boat_alog(tmp_path / "boat.alog")
    r = review(tmp_path, manifest(tmp_path, "boat", "alog", "boat.alog"), capsys, monkeypatch)
    check_skipped(r.metrics, NEEDS_DVL_AND_RANGES, runs_dr=False)
    check_tracks(r, {("boat", "gps"), ("boat", "ins"), ("boat", "ins_sbg")}, w, {"ins": w.ins, "ins_sbg": sbg})
    ref = check_ins_errors(r, "boat", w)
    nav = r.metrics["navigation"]["boat"]
    # the one dive ends at the first fix after it: scores are taken there
    end = [f[0] for f in w.fixes].index(DIVE[1])
    (dive,) = nav["dives"]
    assert (dive["start_s"], dive["end_s"], dive["duration_s"], dive["dr_error_m"]) == (*DIVE, 40.0, None)
    distance = ins_path_m(w, *DIVE)  # no DVL: the distance travelled is the INS's
    assert dive["distance_m"] == pytest.approx(distance, rel=0.0035)
    assert dive["ins_error_m"] == pytest.approx(ref[end], abs=TOLERANCE_M)
    assert dive["ins_pct"] == pytest.approx(100 * ref[end] / distance, rel=0.01)
    ins = nav["methods"]["ins"]
    assert (ins["fixes"], ins["scored_at"], ins["worst_fix_s"]) == (1, "dive ends", DIVE[1])
    assert ins["final_drift_pct"] == dive["ins_pct"]
    for key, value in scored(ref, [end]).items():
        assert ins[key] == pytest.approx(value, abs=TOLERANCE_M), key
    assert "1 dive(s) (GPS gaps longer than 30 s)" in nav["notes"]


# ---------------------------------------------------------------- 3. an ArduSub tlog

def write_sub_tlog(path: Path) -> Written:
    """30 s of an ArduSub: GPS_RAW_INT each second; GLOBAL_POSITION_INT at 4 Hz (0.15 s before each fix,
    drifting, its own vx/vy), each after an ATTITUDE; a downward DISTANCE_SENSOR each second."""
    m, w, packets = mavlink(), Written(), []
    us0 = T0 * 10**6
    vx, vy = round(V_NORTH * 100), round(V_EAST * 100)  # cm/s
    for k in range(31):
        lat, lon = (round(x * 1e7) for x in geodetic(*truth(k)))
        packets.append((us0 + k * 10**6, m.gps_raw_int_encode(us0 + k * 10**6, 3, lat, lon, 10000, 90, 200,
                                                              round(math.hypot(vx, vy)), round(HEADING * 100), 10)))
        w.fixes.append((float(k), lat * 1e-7, lon * 1e-7))
        packets.append((us0 + k * 10**6 + 500_000, m.distance_sensor_encode(1000 * k, 20, 5000, 850 + k, 0, 1, 25, 0)))
    for k in range(120):
        t = k * 0.25 + 0.1
        us = us0 + k * 250_000 + 100_000
        lat, lon = (round(x * 1e7) for x in geodetic(*drifted(t)))
        packets.append((us - 50_000, m.attitude_encode(k, 0.0, 0.0, math.radians(HEADING), 0, 0, 0)))
        packets.append((us, m.global_position_int_encode(k, lat, lon, 0, -3000, vx, vy, 0, round(HEADING * 100))))
        w.ins.append((t, lat * 1e-7, lon * 1e-7, vx / 100, vy / 100))
    path.write_bytes(tlog_bytes(m, sorted(packets, key=lambda p: p[0])))
    return w


def test_ardusub_tlog(tmp_path, capsys, monkeypatch):
    w = write_sub_tlog(tmp_path / "sub.tlog")
    r = review(tmp_path, manifest(tmp_path, "sub", "mavlink", "sub.tlog"), capsys, monkeypatch)
    check_skipped(r.metrics, NEEDS_RANGES, runs_dr=True)  # the rangefinder is a DVL without velocities
    check_tracks(r, {("sub", "gps"), ("sub", "ins")}, w, {"ins": w.ins})
    ref = check_ins_errors(r, "sub", w)
    nav = r.metrics["navigation"]["sub"]
    ins = nav["methods"]["ins"]
    assert (ins["fixes"], ins["scored_at"], ins["worst_fix_s"]) == (30, "every fix", 30.0)
    for key, value in scored(ref, list(range(1, 31))).items():
        assert ins[key] == pytest.approx(value, abs=TOLERANCE_M), key
    # DISTANCE_SENSOR: altitude only, never a velocity: no dead reckoning to score, no bottom lock to judge,
    # and its altitude is the vehicle's altitude series
    assert "dead_reckoning (DVL)" not in nav["methods"] and nav["bottom_lock"]["samples"] == 0
    assert any("altitude-only samples" in n for n in nav["notes"])
    altitude = [e for e in r.results_rrd.temporal if e.endswith("/vehicle/sub/depth/altitude")]
    assert altitude and r.results_rrd.cells(altitude[0], "Scalars:scalars")


# ---------------------------------------------------------------- 4. an ArduSub dataflash .BIN without GPS

START = "2024-05-01T10:00:00Z"
START_NS = 1_714_557_600 * NS


def test_ardusub_bin_without_gps(tmp_path, capsys, monkeypatch):
    write_nogps_bin(tmp_path / "dive.BIN", seconds=10)
    assert NOGPS_ORIGIN == (round(LAT0 * 1e7), round(LON0 * 1e7))  # so `geodetic` is about the EKF origin
    # XKF1 core 0 at boot + k + 1.001 s: 100 k m north and 50 k m east of the origin; the trial starts at k = 0
    w = Written(ins=[(float(k), *recorded(100.0 * k, 50.0 * k), 0.5, 0.25) for k in range(10)])   # XKF1: local
    toml = manifest(tmp_path, "rov", "mavlink", "dive.BIN", f'time_base = "boot"\nstart = "{START}"')
    r = review(tmp_path, toml, capsys, monkeypatch)
    check_skipped(r.metrics, NEEDS_RANGES, runs_dr=True,
                  detectors="needs modem ranges from a leader with a position and GPS fixes on the vehicle")
    check_tracks(r, {("rov", "ins")}, w, {"ins": w.ins})
    for rrd in (r.results_rrd, r.trial_rrd):  # on the UTC timeline of the manifest's start
        (position,) = [e for e in rrd.temporal if e.endswith("/map/rov/ins/position")]
        assert rrd.times_ns(position).tolist() == [START_NS + (k + 1) * NS + 1_000_000 for k in range(10)]
    nav = r.metrics["navigation"]["rov"]
    assert nav["methods"]["ins"]["fixes"] == 0 and nav["methods"]["ins"]["error_max_m"] is None
    assert "0 GPS fix(es): no error at a fix can be measured" in nav["notes"]


# ---------------------------------------------------------------- no position at all

def test_a_trial_without_any_position_is_refused(tmp_path, capsys):
    m = mavlink()
    us0 = T0 * 10**6
    packets = [(us0 + k * 250_000, m.attitude_encode(k, 0.01, -0.02, 0.5, 0, 0, 0)) for k in range(40)]
    (tmp_path / "att.tlog").write_bytes(tlog_bytes(m, packets))
    trial = tmp_path / "trial.mcap"
    assert main(["record", str(manifest(tmp_path, "sub", "mavlink", "att.tlog")), "-o", str(trial), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["replay", str(trial), "--json", "-o", str(tmp_path / "results.mcap")]) == 1
    err = capsys.readouterr().err
    assert "no position of any kind" in err and "Traceback" not in err
    assert not (tmp_path / "results.mcap").exists()
