"""Acoustic measurements: follower-leader modem ranging and the LBL/USBL buoy network.

Ranging: each follower pings its leaders in turn (round-trip pings, one every
`ping_interval_s`). A range is the slant distance at the ping instant plus
Gaussian noise (seed A: R = 3^2 m^2); the vehicles' motion during the ~1 s
round trip is ignored, as the stack's measurement model ignores it.

USBL (seed K section 2 and 4): every node hears the follower's beacon; delay
t_i = r_i / c + N(0, sigma_t); phase differences psi_i = kappa d0 (x - x_i)/r_i
and phi_i = kappa d0 (y - y_i)/r_i plus N(0, sigma_psi), unwrapped; an
abnormal delay is uniform on (0, Rmax/c), an abnormal phase uniform on (-pi, pi).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from formats.geodesy import LocalFrame

from . import anomalies as an
from . import conditions as cond
from .scenario import AnomalyEvent, Scenario
from .sensors import GpsSeries, InsSeries, grid
from .trajectories import Track, interp_track, stream


@dataclass(frozen=True)
class RangeEpochs:
    """Every answered ping, in time order: geometry, measurement, GPS truth and labels."""

    t_s: np.ndarray
    follower: np.ndarray
    leader: np.ndarray
    leader_index: np.ndarray
    range_true_m: np.ndarray
    range_m: np.ndarray
    travel_time_s: np.ndarray
    follower_depth_m: np.ndarray
    leader_depth_m: np.ndarray
    follower_lat_deg: np.ndarray
    follower_lon_deg: np.ndarray
    leader_lat_deg: np.ndarray
    leader_lon_deg: np.ndarray
    leader_ins_lat_deg: np.ndarray
    leader_ins_lon_deg: np.ndarray
    follower_gps_lat_deg: np.ndarray
    follower_gps_lon_deg: np.ndarray
    leader_gps_lat_deg: np.ndarray
    leader_gps_lon_deg: np.ndarray
    z_gps_m: np.ndarray
    z_m: np.ndarray
    label: np.ndarray
    injected: np.ndarray


@dataclass(frozen=True)
class Pings:
    """Every ping sent, answered or not (a dropout is a ping with no reply)."""

    t_s: np.ndarray
    follower: np.ndarray
    leader: np.ndarray
    replied: np.ndarray


def ping_schedule(scenario: Scenario, followers: list[str],
                  leaders: list[str]) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Per follower: ping times and the leader index pinged (leaders in turn)."""
    r = scenario.ranging
    out = []
    for k, name in enumerate(followers):
        # several followers share the cycle, offset so their pings interleave
        first = r.first_ping_s + k * r.ping_interval_s / len(followers)
        t = grid(scenario.trial.duration_s, 1.0 / r.ping_interval_s, first)
        out.append((name, t, np.arange(len(t)) % len(leaders)))
    return out


def _interp_fix(gps: GpsSeries, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.interp(t, gps.t_s, gps.lat_deg), np.interp(t, gps.t_s, gps.lon_deg)


def _link(scenario: Scenario, follower: Track, leader: Track, t: np.ndarray, seed: int,
          events: list[AnomalyEvent]) -> dict[str, np.ndarray]:
    f, ld = interp_track(follower, t), interp_track(leader, t)
    true = np.sqrt((f["east_m"] - ld["east_m"]) ** 2 + (f["north_m"] - ld["north_m"]) ** 2
                   + (f["depth_m"] - ld["depth_m"]) ** 2)
    rng = stream(seed, "range", follower.name, leader.name)
    noisy = cond.range_errors(scenario.conditions, scenario.ranging.range_sigma_m, true, t,
                              scenario.ranging.sound_speed_mps, rng.standard_normal(len(t)), seed,
                              follower.name, leader.name)
    measured, replied, kinds = an.apply_events(t, noisy, events)
    return {"true": true, "measured": measured, "replied": replied, "kinds": kinds,
            "f_depth": f["depth_m"], "l_depth": ld["depth_m"]}


def simulate_ranging(scenario: Scenario, tracks: dict[str, Track], ins: dict[str, InsSeries],
                     gps: dict[str, GpsSeries], frame: LocalFrame, seed: int
                     ) -> tuple[RangeEpochs, Pings, list[an.Interval]]:
    """All follower-leader ranges with anomalies applied and labelled; the intervals injected."""
    leaders = sorted(n for n in tracks if n.startswith("leader"))
    followers = [n for n in tracks if n.startswith("follower")]
    nat = {n.leader: n for n in scenario.natural}
    cols: dict[str, list[np.ndarray]] = {}
    pings: dict[str, list[np.ndarray]] = {"t": [], "f": [], "l": [], "r": []}
    intervals: list[an.Interval] = []
    for fname, t_all, lidx in ping_schedule(scenario, followers, leaders):
        for j, lname in enumerate(leaders):
            t = t_all[lidx == j]
            fixed = [e for e in scenario.anomalies if e.leader == lname and e.follower == fname]
            drawn = (an.natural_events(nat[lname], fname, t, scenario.trial.duration_s, seed, fixed)
                     if lname in nat else [])
            bounced = cond.multipath_events(scenario.conditions, fname, lname, scenario.trial.duration_s, seed)
            intervals += (an.intervals_for(fixed, "scenario") + an.intervals_for(drawn, "natural")
                          + an.intervals_for(bounced, "condition"))
            link = _link(scenario, tracks[fname], tracks[lname], t, seed, fixed + drawn + bounced)
            pings["t"].append(t)
            pings["f"].append(np.full(len(t), fname))
            pings["l"].append(np.full(len(t), lname))
            pings["r"].append(link["replied"])
            keep = link["replied"]
            te = t[keep]
            part = {
                "t_s": te, "follower": np.full(len(te), fname), "leader": np.full(len(te), lname),
                "leader_index": np.full(len(te), j + 1), "range_true_m": link["true"][keep],
                "range_m": link["measured"][keep], "follower_depth_m": link["f_depth"][keep],
                "leader_depth_m": link["l_depth"][keep], "injected": link["kinds"][keep],
            }
            part.update(_positions(tracks[fname], tracks[lname], ins[lname], gps[fname], gps[lname], te, frame))
            for k, v in part.items():
                cols.setdefault(k, []).append(v)
    return _finish(scenario, cols), _pings(pings), intervals


def _positions(follower: Track, leader: Track, l_ins: InsSeries, f_gps: GpsSeries, l_gps: GpsSeries, t: np.ndarray,
               frame: LocalFrame) -> dict[str, np.ndarray]:
    fi, li = interp_track(follower, t), interp_track(leader, t)
    flat, flon = frame.to_geodetic(fi["east_m"], fi["north_m"])
    llat, llon = frame.to_geodetic(li["east_m"], li["north_m"])
    fg, lg = _interp_fix(f_gps, t), _interp_fix(l_gps, t)
    return {
        "follower_lat_deg": flat, "follower_lon_deg": flon, "leader_lat_deg": llat, "leader_lon_deg": llon,
        "leader_ins_lat_deg": np.interp(t, l_ins.t_s, l_ins.lat_deg),
        "leader_ins_lon_deg": np.interp(t, l_ins.t_s, l_ins.lon_deg),
        "follower_gps_lat_deg": fg[0], "follower_gps_lon_deg": fg[1],
        "leader_gps_lat_deg": lg[0], "leader_gps_lon_deg": lg[1],
    }


def _finish(scenario: Scenario, cols: dict[str, list[np.ndarray]]) -> RangeEpochs:
    data = {k: np.concatenate(v) for k, v in cols.items()}
    # stable sort: equal times keep follower/leader order, so output is deterministic
    order = np.argsort(data["t_s"], kind="stable")
    data = {k: v[order] for k, v in data.items()}
    data["travel_time_s"] = data["range_m"] / scenario.ranging.sound_speed_mps
    data["z_m"] = an.horizontal_range(data["range_m"], data["follower_depth_m"], data["leader_depth_m"])
    data["z_gps_m"] = an.gps_range(data["follower_gps_lat_deg"], data["follower_gps_lon_deg"],
                                   data["leader_gps_lat_deg"], data["leader_gps_lon_deg"],
                                   data["follower_depth_m"], data["leader_depth_m"])
    data["label"] = an.label(data["z_gps_m"], data["z_m"])
    return RangeEpochs(**data)


def _pings(p: dict[str, list[np.ndarray]]) -> Pings:
    t = np.concatenate(p["t"])
    order = np.argsort(t, kind="stable")
    return Pings(t[order], np.concatenate(p["f"])[order], np.concatenate(p["l"])[order],
                 np.concatenate(p["r"])[order])


@dataclass(frozen=True)
class UsblEpochs:
    """One row per beacon epoch, one column per node."""

    t_s: np.ndarray
    target: str
    nodes: tuple[str, ...]
    node_east_m: np.ndarray
    node_north_m: np.ndarray
    node_depth_m: np.ndarray
    node_lat_deg: np.ndarray
    node_lon_deg: np.ndarray
    target_east_m: np.ndarray
    target_north_m: np.ndarray
    target_depth_m: np.ndarray
    delay_true_s: np.ndarray
    delay_s: np.ndarray
    phase_x_true_rad: np.ndarray
    phase_y_true_rad: np.ndarray
    phase_x_rad: np.ndarray
    phase_y_rad: np.ndarray
    abnormal_delay: np.ndarray
    abnormal_phase: np.ndarray
    kappa_d0_rad: float
    sound_speed_mps: float


def buoy_layout(scenario: Scenario) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """Node names and local positions on a circle around the trial area (seed K section 4)."""
    u = scenario.usbl
    ang = math.pi / 4 + 2 * math.pi * np.arange(u.buoys) / u.buoys
    names = tuple(f"buoy{i + 1}" for i in range(u.buoys))
    return names, u.layout_radius_m * np.sin(ang), u.layout_radius_m * np.cos(ang)


def _fault_masks(scenario: Scenario, nodes: tuple[str, ...], t: np.ndarray, rng: np.random.Generator
                 ) -> tuple[np.ndarray, np.ndarray]:
    u = scenario.usbl
    shape = (len(t), len(nodes))
    bad_delay = rng.random(shape) < u.abnormal_delay_prob
    bad_phase = rng.random(shape) < u.abnormal_phase_prob
    for nf in scenario.node_faults:
        if nf.node in nodes:
            rows = (t >= nf.start_s) & (t <= nf.end_s)
            col = nodes.index(nf.node)
            if nf.kind in ("delay", "both"):
                bad_delay[rows, col] = True
            if nf.kind in ("phase", "both"):
                bad_phase[rows, col] = True
    return bad_delay, bad_phase


def simulate_usbl(scenario: Scenario, target: Track, frame: LocalFrame, seed: int) -> UsblEpochs:
    """Delays and phase differences of every node for every beacon of the target."""
    u = scenario.usbl
    c = scenario.ranging.sound_speed_mps
    t = grid(scenario.trial.duration_s, 1.0 / u.interval_s, u.first_s)
    nodes, ne, nn = buoy_layout(scenario)
    nd = np.full(len(nodes), u.node_depth_m)
    p = interp_track(target, t)
    de = p["east_m"][:, None] - ne[None, :]
    dn = p["north_m"][:, None] - nn[None, :]
    du = nd[None, :] - p["depth_m"][:, None]
    r = np.sqrt(de**2 + dn**2 + du**2)
    kd = 2 * math.pi * u.frequency_hz / c * u.element_spacing_m
    rng = stream(seed, "usbl", target.name)
    shape = r.shape
    delay = r / c + rng.standard_normal(shape) * u.delay_sigma_s
    px = kd * de / r + rng.standard_normal(shape) * u.phase_sigma_rad
    py = kd * dn / r + rng.standard_normal(shape) * u.phase_sigma_rad
    bad_delay, bad_phase = _fault_masks(scenario, nodes, t, rng)
    delay = np.where(bad_delay, rng.uniform(0.0, u.max_range_m / c, shape), delay)
    px = np.where(bad_phase, rng.uniform(-math.pi, math.pi, shape), px)
    py = np.where(bad_phase, rng.uniform(-math.pi, math.pi, shape), py)
    lat, lon = frame.to_geodetic(ne, nn)
    return UsblEpochs(t, target.name, nodes, ne, nn, nd, lat, lon, p["east_m"], p["north_m"], p["depth_m"],
                      r / c, delay, kd * de / r, kd * dn / r, px, py, bad_delay, bad_phase, kd, c)


def usbl_intervals(scenario: Scenario, target: str) -> list[an.Interval]:
    """The scripted node faults as labelled intervals (random single-epoch faults are in the arrays)."""
    return [an.Interval(nf.node, target, f"usbl_{nf.kind}", nf.start_s, nf.end_s, "scenario")
            for nf in scenario.node_faults]
