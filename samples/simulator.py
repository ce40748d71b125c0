"""The lake trial in memory: `simulate_trial(scenario, seed)` returns every truth and measurement array.

Vehicles: leader1 and leader2 (high-grade INS + GPS), one or more followers
(low-grade INS, DVL, GPS as reference), and a ring of USBL buoys (docs/design.md
sections 7, 13 and 15). Times are seconds from the trial start; `start_ns` is
the UTC start in ns. Deterministic per (scenario, seed). With `[tracks] archive`
set the vehicles move along a recorded trial's GPS tracks instead of the
scripted racetracks (samples/recorded.py); everything else is simulated alike.
"""

from __future__ import annotations

import calendar
from dataclasses import dataclass
from datetime import date, time

import numpy as np

from formats.geodesy import LocalFrame
from formats.units import NS

from . import acoustics as ac
from .anomalies import Interval
from .conditions import realized
from .recorded import recorded_motion
from .scenario import Scenario, validate
from .sensors import DvlSeries, GpsSeries, InsSeries, heading_error, simulate_dvl, simulate_gps, simulate_ins
from .trajectories import Track, default_plans, make_track


@dataclass(frozen=True)
class VehicleSim:
    """One boat: role, modem address, truth track and its sensors' series."""

    name: str
    role: str
    modem_address: int
    track: Track
    gps: GpsSeries
    ins: InsSeries
    dvl: DvlSeries


@dataclass(frozen=True)
class BuoySim:
    """One moored USBL node: address, position and its (sparse) GPS log."""

    name: str
    modem_address: int
    east_m: float
    north_m: float
    depth_m: float
    lat_deg: float
    lon_deg: float
    gps: GpsSeries


@dataclass(frozen=True)
class SimulatedTrial:
    """Everything one simulated trial holds."""

    scenario: Scenario
    seed: int
    start_ns: int
    frame: LocalFrame
    vehicles: tuple[VehicleSim, ...]
    buoys: tuple[BuoySim, ...]
    ranges: ac.RangeEpochs
    pings: ac.Pings
    usbl: ac.UsblEpochs
    intervals: tuple[Interval, ...]
    notes: tuple[str, ...] = ()         # what the simulation of recorded tracks chose (who is who, a cut span)

    def vehicle(self, name: str) -> VehicleSim:
        """The vehicle called `name`."""
        for v in self.vehicles:
            if v.name == name:
                return v
        raise KeyError(name)

    def t_ns(self, t_s: np.ndarray | float) -> np.ndarray:
        """UTC ns for seconds from the start, rounded to the microsecond like the logs."""
        return self.start_ns + np.round(np.asarray(t_s, dtype=float) * 1e6).astype(np.int64) * 1000


def start_ns(scenario: Scenario) -> int:
    """The trial's UTC start in ns from its date and start time."""
    d = date.fromisoformat(scenario.trial.date)
    tm = time.fromisoformat(scenario.trial.start_time_utc)
    return (calendar.timegm(d.timetuple()) + tm.hour * 3600 + tm.minute * 60 + tm.second) * NS


def _track_times(scenario: Scenario) -> np.ndarray:
    step = 1.0 / scenario.trial.truth_rate_hz
    n = int(round(scenario.trial.duration_s / step)) + 1
    return np.arange(n) * step


def _vehicle(name: str, track: Track, scenario: Scenario, frame: LocalFrame, seed: int, address: int) -> VehicleSim:
    leader = name.startswith("leader")
    dur = scenario.trial.duration_s
    gps = simulate_gps(track, scenario.gps, frame, dur, seed)
    cond = scenario.conditions
    ins = simulate_ins(track, scenario.ins, frame, dur, leader, seed, cond)
    # a PD0 ensemble carries the heading of the vehicle's own compass/INS
    head = np.mod(track.heading_deg + heading_error(track, scenario.ins, leader, seed, cond), 360.0)
    rate = scenario.dvl.leader_rate_hz if leader else scenario.dvl.rate_hz
    dvl = simulate_dvl(track, scenario.dvl, dur, rate, seed, head, cond)
    return VehicleSim(name, "leader" if leader else "follower", address, track, gps, ins, dvl)


def _motion(scenario: Scenario, seed: int) -> tuple[Scenario, dict[str, Track], tuple[str, ...]]:
    """The truth tracks: the recorded ones when the scenario names an archive (its trial dated and placed on
    them), else the scripted racetracks."""
    if scenario.tracks.archive:
        m = recorded_motion(scenario, seed)
        return m.scenario, m.tracks, m.notes
    frame = LocalFrame(scenario.trial.origin_lat_deg, scenario.trial.origin_lon_deg)
    t = _track_times(scenario)
    plans = default_plans(scenario.trial.followers)
    return scenario, {name: make_track(name, plan, t, frame, seed) for name, plan in plans.items()}, ()


def simulate_trial(scenario: Scenario, seed: int) -> SimulatedTrial:
    """Simulate the whole trial: tracks, sensors, ranging with anomalies and labels, USBL.

    The trial's scenario is the one given with its conditions' per-seed draws
    applied (`conditions.realized`), which is what the trial records.
    """
    validate(scenario)
    scenario, tracks, notes = _motion(scenario, seed)
    scenario = realized(scenario, seed, sorted(n for n in tracks if n.startswith("leader")))
    frame = LocalFrame(scenario.trial.origin_lat_deg, scenario.trial.origin_lon_deg)
    vehicles = tuple(_vehicle(n, tr, scenario, frame, seed, i + 1) for i, (n, tr) in enumerate(tracks.items()))
    gps = {v.name: v.gps for v in vehicles}
    ins = {v.name: v.ins for v in vehicles}
    ranges, pings, intervals = ac.simulate_ranging(scenario, tracks, ins, gps, frame, seed)
    target = next(n for n in tracks if n.startswith("follower"))
    usbl = ac.simulate_usbl(scenario, tracks[target], frame, seed)
    buoys = _buoys(scenario, usbl, frame, seed)
    intervals += ac.usbl_intervals(scenario, target)
    intervals.sort(key=lambda iv: (iv.start_s, iv.vehicle, iv.leader, iv.kind, iv.end_s))
    return SimulatedTrial(scenario, seed, start_ns(scenario), frame, vehicles, buoys, ranges, pings, usbl,
                          tuple(intervals), notes)


def _buoys(scenario: Scenario, usbl: ac.UsblEpochs, frame: LocalFrame, seed: int) -> tuple[BuoySim, ...]:
    out = []
    t = np.array([0.0, scenario.trial.duration_s])
    for i, name in enumerate(usbl.nodes):
        e, n, d = float(usbl.node_east_m[i]), float(usbl.node_north_m[i]), float(usbl.node_depth_m[i])
        still = Track(name, t, np.full(2, e), np.full(2, n), *frame.to_geodetic(np.full(2, e), np.full(2, n)),
                      np.full(2, d), np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2),
                      np.zeros(2), np.zeros(2), np.zeros(2))
        gps = simulate_gps(still, scenario.gps, frame, scenario.trial.duration_s, seed, scenario.gps.buoy_rate_hz)
        out.append(BuoySim(name, 11 + i, e, n, d, float(usbl.node_lat_deg[i]), float(usbl.node_lon_deg[i]), gps))
    return tuple(out)
