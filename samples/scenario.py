"""The sample lake trial's scenario: every number the simulator uses, with TOML in and out.

Defaults follow the source lake trial (docs/design.md section 15; seed A section 4,
table 1): three boats, 1700 s, GPS 1.8 m RMS, DVL 0.2 kn, ranging sigma 3 m,
two leaders pinged alternately, leader 1 stale 100-150 s and drifting
1100-1170 s. Choices the sources leave open are made here once, before any
detector is scored, and documented next to the value.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import MISSING, Field, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

ANOMALY_KINDS = ("stale", "drift", "outlier", "dropout", "multipath")
NODE_FAULT_KINDS = ("delay", "phase", "both")
OPTIONAL = {"optional": True}
"""Field metadata of a key added after the sample trial: written to TOML only when it differs from its default,
so the sample's scenario.toml stays as it was."""


def optional(default: Any) -> Any:
    """A scenario field with this default, written to TOML only when set to something else."""
    return field(default=default, metadata=OPTIONAL)


@dataclass(frozen=True)
class TrialConfig:
    """Where and when: the lake, the UTC start, the length and the training window."""

    name: str = "lake-trial"
    date: str = "2016-10-12"
    start_time_utc: str = "02:00:00"
    duration_s: float = 1700.0
    origin_lat_deg: float = 45.70
    origin_lon_deg: float = 126.60
    training_window_s: float = 600.0
    followers: int = 1
    truth_rate_hz: float = 10.0


@dataclass(frozen=True)
class GpsConfig:
    """Single-point GPS (OEMV-2RT-2, 1.8 m RMS horizontal; seed A table 1)."""

    rate_hz: float = 1.0
    horizontal_rms_m: float = 1.8
    vertical_sigma_m: float = 3.0
    # single-point errors wander over tens of seconds; first-order Gauss-Markov
    correlation_time_s: float = 30.0
    buoy_rate_hz: float = 0.2
    # an AUV's receiver has no sky while it is submerged: followers dive for follower_dive_s (0: never), from
    # follower_first_dive_s on, surfacing for follower_surface_s between dives (typical survey AUVs: dives of
    # 5-30 min, a minute or two at the surface for a fix); their GPS logs hold no fix while submerged
    follower_dive_s: float = optional(0.0)
    follower_surface_s: float = optional(60.0)
    follower_first_dive_s: float = optional(60.0)


@dataclass(frozen=True)
class InsConfig:
    """High-grade INS on leaders, low-grade on followers (heading bias + random walk)."""

    rate_hz: float = 1.0
    leader_heading_sigma_deg: float = 0.05
    leader_position_sigma_m: float = 0.7
    leader_position_correlation_s: float = 60.0
    follower_heading_bias_deg: float = 1.5
    follower_heading_walk_deg_per_sqrt_s: float = 0.03
    follower_velocity_error_mps: float = 0.05
    follower_velocity_correlation_s: float = 300.0
    attitude_sigma_deg: float = 0.05


@dataclass(frozen=True)
class DvlConfig:
    """Bottom-track DVL (DS-99, 0.2 kn accuracy; seed A table 1)."""

    rate_hz: float = 1.0
    leader_rate_hz: float = 0.5
    sigma_mps: float = 0.2 * 1852.0 / 3600.0
    beam_angle_deg: float = 30.0
    lake_depth_m: float = 12.0
    lake_depth_variation_m: float = 3.0


@dataclass(frozen=True)
class RangingConfig:
    """Modem ranging: alternating leaders, round-trip pings from each follower.

    The sources say 0.2 Hz per leader; their counts (345 and 348 ranges per
    leader in 1700 s, 462 epochs in 600-1700 s) need one ping every ~2.4 s,
    so the cycle is 4.8 s and dropouts bring the totals back to the source's.
    """

    ping_interval_s: float = 2.4
    first_ping_s: float = 1.0
    sound_speed_mps: float = 1450.0
    range_sigma_m: float = 3.0
    turnaround_s: float = 0.0


@dataclass(frozen=True)
class UsblConfig:
    """LBL/USBL buoy network hearing the follower (seed K section 4 parameters)."""

    buoys: int = 4
    layout_radius_m: float = 800.0 * math.sqrt(2.0)
    interval_s: float = 5.0
    first_s: float = 2.2
    node_depth_m: float = 5.0
    delay_sigma_s: float = 0.5e-3
    phase_sigma_rad: float = 0.1
    frequency_hz: float = 75_000.0
    element_spacing_m: float = 0.18
    max_range_m: float = 2830.0
    abnormal_delay_prob: float = 0.02
    abnormal_phase_prob: float = 0.01


@dataclass(frozen=True)
class NodeFault:
    """A buoy whose delays and/or phases are abnormal (uniform, seed K) in [start, end]."""

    node: str
    kind: str
    start_s: float
    end_s: float


@dataclass(frozen=True)
class AnomalyEvent:
    """One injected ranging anomaly on a follower-leader pair over [start, end] seconds.

    stale: the modem repeats its last range; drift: the error ramps linearly
    from 0 to `magnitude_m`, so its rate is `drift_rate_mps` (the default
    leader 1 drift: 25 m over 70 s, 0.36 m/s; `Scenario.with_drift_rate`
    sets it); outlier: every epoch inside gets `magnitude_m`; dropout: no
    reply at all.
    """

    leader: str
    kind: str
    start_s: float
    end_s: float
    magnitude_m: float = 0.0
    follower: str = "follower"

    @property
    def drift_rate_mps(self) -> float:
        """How fast a drift's error grows (m/s, signed): magnitude over duration; 0 for other kinds."""
        span = self.end_s - self.start_s
        return self.magnitude_m / span if self.kind == "drift" and span > 0 else 0.0


@dataclass(frozen=True)
class NaturalAnomalies:
    """Random anomalies of one leader's link, drawn from the seed (P: outliers, dropouts)."""

    leader: str
    stale_per_hour: float = 0.0
    stale_min_s: float = 10.0
    stale_max_s: float = 30.0
    outlier_prob: float = 0.0
    outlier_min_m: float = 12.0
    outlier_max_m: float = 40.0
    dropout_prob: float = 0.0


@dataclass(frozen=True)
class Conditions:
    """What real trials add to the default scenario (issue 26): every one off at its default.

    Each key has its physical meaning and a realistic range next to it. The
    draws (which ones, when, how strong) come from the trial's seed, so a
    condition set gives different trials per seed; `realized` applies the
    per-trial draws and writes them back as plain values.
    """

    # sound-speed scale bias (fraction): the modems convert travel time with an assumed sound speed that is
    # off the water's by 0.1-1 % (temperature, salinity, a default of 1500 m/s in a 1450 m/s lake), so every
    # range is (1 + bias) times the true one: 1-10 m at 1 km, a slow drift on every link as ranges change.
    # Negative: the water is faster than assumed; 0: none
    sound_speed_bias: float = optional(0.0)
    # one-way travel-time clocks: each follower-leader pair's clocks differ by an offset drawn uniform in
    # +-owtt_clock_offset_s (0.1-2 ms after a GPS sync, i.e. 0.15-3 m) that grows at a rate drawn uniform in
    # +-owtt_clock_drift_ppm (a TCXO 0.1-1 ppm, 0.15-1.5 mm/s of range; a chip-scale atomic clock 1e-4)
    owtt_clock_offset_s: float = optional(0.0)
    owtt_clock_drift_ppm: float = optional(0.0)
    # multipath: a surface or bottom bounce heard instead of the direct path adds a persistent positive bias
    # of multipath_min_m-multipath_max_m (5-30 m at a few hundred metres in shallow water) for
    # multipath_min_s-multipath_max_s (30-300 s, while the geometry lasts), multipath_per_hour times per link
    multipath_per_hour: float = optional(0.0)
    multipath_min_m: float = optional(8.0)
    multipath_max_m: float = optional(25.0)
    multipath_min_s: float = optional(30.0)
    multipath_max_s: float = optional(180.0)
    # heavy-tailed, range-dependent ranging noise: sigma = range_sigma_m + range_noise_per_km_m per km of
    # range (1-5 m/km: weaker, later detections at long range), Student-t with range_noise_dof degrees of
    # freedom scaled to that sigma (2.5-5 for real modems' arrival-picking errors; 0: Gaussian)
    range_noise_per_km_m: float = optional(0.0)
    range_noise_dof: float = optional(0.0)
    # DVL bottom-lock loss: stretches of dvl_lock_loss_min_s-dvl_lock_loss_max_s (10-60 s over soft mud,
    # weed, steep slopes or beyond the altitude limit), dvl_lock_loss_per_hour per vehicle (1-20), where the
    # DVL's pings have no bottom track (archived as invalid)
    dvl_lock_loss_per_hour: float = optional(0.0)
    dvl_lock_loss_min_s: float = optional(10.0)
    dvl_lock_loss_max_s: float = optional(60.0)
    # compass deviation with heading on the followers' low-grade heading: a one-cycle term of amplitude
    # compass_deviation_deg (hard iron) and a two-cycle one of half of it (soft iron), phases drawn per
    # seed; 0.5-2 deg after a swing calibration, up to 5 deg without
    compass_deviation_deg: float = optional(0.0)
    # the scripted anomalies move: each keeps its kind, length and size but gets a start drawn per seed
    # (inside the training window if it was there, after it otherwise) and a leader drawn among the leaders
    anomalies_drawn: bool = optional(False)
    # the vehicles' sensor parameters drawn per trial around their specification: the followers' heading
    # bias (its sign too), heading walk and velocity error, the DVL's noise and the ranging sigma, each times
    # exp(N(0, sensor_spread)) (0.3-0.5: units of one model differ by tens of percent), so no model that
    # uses the specification is told the truth; 0: the specification itself
    sensor_spread: float = optional(0.0)


@dataclass(frozen=True)
class TracksConfig:
    """Motion from a recorded trial's GPS tracks (`simulate --tracks`, samples/recorded.py); off while `archive` is "".

    The vehicles move as the archive's GPS fixes say (linear between fixes at
    `truth_rate_hz`); only the acoustics and the DR sensors are simulated.
    """

    # the archive whose foxglove.LocationFix tracks give the motion ("": the scripted racetracks)
    archive: str = optional("")
    # the vehicle whose track is the follower's; "": the one named `follower`, else the archive's first vehicle
    # of role follower, else the first vehicle with a track
    follower: str = optional("")
    # one vehicle with a track: its track replayed for `leaders` leaders, leader k the same track
    # k * leader_offset_s seconds ahead (300 s: 300-600 m along a survey at 1-2 m/s, usually another leg,
    # so the ranges come from other directions than straight ahead)
    leaders: int = optional(2)
    leader_offset_s: float = optional(300.0)
    # a gap between fixes up to max_gap_s (a dropped fix, a short dive) is bridged by linear interpolation;
    # a longer one (a dive without GPS) cuts the trial to the longest span every track covers
    max_gap_s: float = optional(30.0)
    # heading and speed come from the positions smoothed by a Gaussian of this sigma (s) and differenced:
    # 1 Hz single-point fixes have metre noise, whose raw differences would give tens of degrees of heading noise
    smoothing_s: float = optional(5.0)


def _default_events() -> tuple[AnomalyEvent, ...]:
    return (
        AnomalyEvent("leader1", "stale", 100.0, 150.0),
        AnomalyEvent("leader1", "drift", 1100.0, 1170.0, 25.0),
        # leader 2's stale segment has no time in the seed: one inside the
        # training window (so a per-leader model sees one) and one after it
        AnomalyEvent("leader2", "stale", 330.0, 370.0),
        AnomalyEvent("leader2", "stale", 1460.0, 1490.0),
    )


def _default_natural() -> tuple[NaturalAnomalies, ...]:
    # leader 1's modem was the flaky one in the source (51 of its 237 test
    # epochs anomalous against 6 of 225 for leader 2, seed A section 4.2)
    return (
        NaturalAnomalies("leader1", stale_per_hour=30.0, stale_min_s=15.0, stale_max_s=45.0,
                         outlier_prob=0.02, dropout_prob=0.02),
        NaturalAnomalies("leader2", stale_per_hour=2.0, stale_min_s=10.0, stale_max_s=15.0,
                         outlier_prob=0.002, dropout_prob=0.02),
    )


def _default_faults() -> tuple[NodeFault, ...]:
    return (
        NodeFault("buoy2", "delay", 400.0, 700.0),
        NodeFault("buoy4", "both", 1200.0, 1350.0),
    )


@dataclass(frozen=True)
class Scenario:
    """Everything `simulate_trial` needs besides the seed."""

    trial: TrialConfig = field(default_factory=TrialConfig)
    gps: GpsConfig = field(default_factory=GpsConfig)
    ins: InsConfig = field(default_factory=InsConfig)
    dvl: DvlConfig = field(default_factory=DvlConfig)
    ranging: RangingConfig = field(default_factory=RangingConfig)
    usbl: UsblConfig = field(default_factory=UsblConfig)
    anomalies: tuple[AnomalyEvent, ...] = field(default_factory=_default_events)
    natural: tuple[NaturalAnomalies, ...] = field(default_factory=_default_natural)
    node_faults: tuple[NodeFault, ...] = field(default_factory=_default_faults)
    conditions: Conditions = field(default_factory=Conditions)
    tracks: TracksConfig = field(default_factory=TracksConfig)

    def with_options(self, duration_s: float | None = None, followers: int | None = None) -> Scenario:
        """A copy with the command-line overrides applied."""
        trial = self.trial
        if duration_s is not None:
            trial = replace(trial, duration_s=float(duration_s))
        if followers is not None:
            trial = replace(trial, followers=int(followers))
        return replace(self, trial=trial)

    def with_drift_rate(self, rate_mps: float) -> Scenario:
        """A copy whose scripted drifts grow at `rate_mps` (m/s) over their own spans, each keeping its sign.

        The drift rate is the simulator's drift parameter (`auvreplay evaluate
        --drift-rate` sweeps it); the default scenario is left as it is.
        ScenarioError for a negative or non-finite rate.
        """
        if not (math.isfinite(rate_mps) and rate_mps >= 0):
            raise ScenarioError(f"drift rate must be a finite number >= 0 m/s, not {rate_mps!r}")

        def rescaled(ev: AnomalyEvent) -> AnomalyEvent:
            if ev.kind != "drift":
                return ev
            sign = -1.0 if ev.magnitude_m < 0 else 1.0
            return replace(ev, magnitude_m=sign * float(rate_mps) * (ev.end_s - ev.start_s))
        return replace(self, anomalies=tuple(rescaled(ev) for ev in self.anomalies))


_LISTS: dict[str, type] = {"anomalies": AnomalyEvent, "natural": NaturalAnomalies, "node_faults": NodeFault}
_TABLES: dict[str, type] = {
    "trial": TrialConfig, "gps": GpsConfig, "ins": InsConfig, "dvl": DvlConfig,
    "ranging": RangingConfig, "usbl": UsblConfig, "conditions": Conditions, "tracks": TracksConfig,
}
# tables written only when one of their keys is set (every key optional): the sample's scenario.toml stays as it was
_OPTIONAL_TABLES = ("conditions", "tracks")


class ScenarioError(ValueError):
    """A scenario file that does not describe a valid scenario."""


def _build(cls: type, table: dict[str, Any], where: str) -> Any:
    names = {f.name: f for f in fields(cls)}
    unknown = sorted(set(table) - set(names))
    if unknown:
        raise ScenarioError(f"{where}: unknown key(s) {', '.join(unknown)}")
    # TOML writes 100 for 100.0; float fields take either
    values = {
        k: float(v) if names[k].type == "float" and isinstance(v, int) and not isinstance(v, bool) else v
        for k, v in table.items()
    }
    try:
        return cls(**values)
    except TypeError as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def scenario_from_dict(data: dict[str, Any]) -> Scenario:
    """A Scenario from parsed TOML; missing tables keep their defaults, lists replace them."""
    unknown = sorted(set(data) - set(_TABLES) - set(_LISTS))
    if unknown:
        raise ScenarioError(f"unknown table(s) {', '.join(unknown)}")
    kwargs: dict[str, Any] = {}
    for key, cls in _TABLES.items():
        if key in data:
            kwargs[key] = _build(cls, data[key], f"[{key}]")
    for key, cls in _LISTS.items():
        if key in data:
            kwargs[key] = tuple(_build(cls, t, f"[[{key}]] #{i + 1}") for i, t in enumerate(data[key]))
    scenario = Scenario(**kwargs)
    validate(scenario)
    return scenario


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario TOML file."""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: {exc}") from None
    return scenario_from_dict(data)


def validate(scenario: Scenario) -> None:
    """Raise ScenarioError when a value makes no sense."""
    t = scenario.trial
    if t.duration_s <= 0 or t.followers < 1 or t.truth_rate_hz <= 0:
        raise ScenarioError("[trial]: duration_s > 0, followers >= 1 and truth_rate_hz > 0 are required")
    if scenario.ranging.ping_interval_s <= 0 or scenario.usbl.interval_s <= 0:
        raise ScenarioError("ping and USBL intervals must be > 0")
    if not 3 <= scenario.usbl.buoys <= 12:
        raise ScenarioError("[usbl]: buoys must be between 3 and 12")
    for ev in scenario.anomalies:
        if ev.kind not in ANOMALY_KINDS or ev.end_s < ev.start_s:
            raise ScenarioError(f"[[anomalies]]: bad event {ev}")
    for nf in scenario.node_faults:
        if nf.kind not in NODE_FAULT_KINDS or nf.end_s < nf.start_s:
            raise ScenarioError(f"[[node_faults]]: bad fault {nf}")
    c = scenario.conditions
    rates = (c.owtt_clock_offset_s, c.owtt_clock_drift_ppm, c.multipath_per_hour, c.range_noise_per_km_m,
             c.dvl_lock_loss_per_hour, c.compass_deviation_deg, c.sensor_spread)
    if not all(math.isfinite(v) and v >= 0 for v in rates):
        raise ScenarioError("[conditions]: clock, multipath, noise, lock-loss, deviation and spread keys must be >= 0")
    if not (math.isfinite(c.sound_speed_bias) and abs(c.sound_speed_bias) < 0.1):
        raise ScenarioError("[conditions]: sound_speed_bias is a fraction (0.001-0.01), |bias| < 0.1")
    if c.range_noise_dof != 0 and not c.range_noise_dof > 2:
        raise ScenarioError("[conditions]: range_noise_dof must be 0 (Gaussian) or > 2 (finite variance)")
    if not (0 <= c.multipath_min_m <= c.multipath_max_m and 0 < c.multipath_min_s <= c.multipath_max_s
            and 0 < c.dvl_lock_loss_min_s <= c.dvl_lock_loss_max_s):
        raise ScenarioError("[conditions]: each min must be > 0 (metres >= 0) and at most its max")
    tr = scenario.tracks
    if not (tr.leaders >= 1 and math.isfinite(tr.leader_offset_s) and tr.leader_offset_s > 0
            and math.isfinite(tr.max_gap_s) and tr.max_gap_s >= 0
            and math.isfinite(tr.smoothing_s) and tr.smoothing_s >= 0):
        raise ScenarioError("[tracks]: leaders >= 1, leader_offset_s > 0, max_gap_s >= 0 and smoothing_s >= 0")


def _fmt(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    raise TypeError(f"cannot write {value!r} to TOML")


def _written(f: Field[Any], value: Any) -> bool:
    """Every key but an optional one at its default (which would change the sample trial's file)."""
    return not f.metadata.get("optional") or f.default is MISSING or value != f.default


def _table_lines(obj: Any) -> list[str]:
    return [f"{f.name} = {_fmt(getattr(obj, f.name))}" for f in fields(obj) if _written(f, getattr(obj, f.name))]


def scenario_to_toml(scenario: Scenario) -> str:
    """The scenario as TOML text; deterministic (field order, repr of floats)."""
    out = ["# auvreplay lake-trial scenario (samples/scenario.py documents every key)"]
    for key in _TABLES:
        lines = _table_lines(getattr(scenario, key))
        if lines or key not in _OPTIONAL_TABLES:
            out += ["", f"[{key}]", *lines]
    for key in _LISTS:
        for item in getattr(scenario, key):
            assert is_dataclass(item)
            out += ["", f"[[{key}]]", *_table_lines(item)]
    return "\n".join(out) + "\n"
