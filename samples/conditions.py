"""The per-trial draws of a condition set (`scenario.Conditions`) and the errors they add.

`realized` applies the draws that change the scenario's own values (sensor
parameters around their specification, scripted anomalies moved) and returns
a scenario whose draws are written back as plain values, so the trial's
scenario.toml replays it exactly. The other conditions draw from their own
streams of the seed where they act (ranges, DVL pings, compass): with every
condition off no stream is touched and the default trial is what it was.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from .scenario import AnomalyEvent, Conditions, Scenario
from .trajectories import stream


def realized(scenario: Scenario, seed: int, leaders: list[str]) -> Scenario:
    """The scenario of this seed's trial: sensor parameters and scripted anomalies drawn when the conditions ask."""
    c = scenario.conditions
    out = scenario
    if c.sensor_spread > 0:
        rng = stream(seed, "sensor-spread")
        f = np.exp(rng.standard_normal(5) * c.sensor_spread)
        sign = 1.0 if rng.random() < 0.5 else -1.0
        ins, dvl, rng_cfg = out.ins, out.dvl, out.ranging
        out = replace(out, ins=replace(ins, follower_heading_bias_deg=sign * ins.follower_heading_bias_deg * f[0],
                                       follower_heading_walk_deg_per_sqrt_s=ins.follower_heading_walk_deg_per_sqrt_s
                                       * f[1],
                                       follower_velocity_error_mps=ins.follower_velocity_error_mps * f[2]),
                      dvl=replace(dvl, sigma_mps=dvl.sigma_mps * f[3]),
                      ranging=replace(rng_cfg, range_sigma_m=rng_cfg.range_sigma_m * f[4]))
    if c.anomalies_drawn and leaders:
        rng = stream(seed, "scripted-anomalies")
        t_a, dur = out.trial.training_window_s, out.trial.duration_s

        def moved(ev: AnomalyEvent) -> AnomalyEvent:
            span = ev.end_s - ev.start_s
            lo, hi = (0.0, t_a - span) if ev.start_s < t_a else (t_a, dur - span)
            start = round(float(rng.uniform(lo, max(lo, hi))), 1)
            return replace(ev, start_s=start, end_s=round(start + span, 1),
                           leader=leaders[int(rng.integers(len(leaders)))])
        out = replace(out, anomalies=tuple(moved(ev) for ev in out.anomalies))
    return replace(out, conditions=replace(c, sensor_spread=0.0, anomalies_drawn=False))


def range_errors(c: Conditions, sigma_m: float, true_m: np.ndarray, t_s: np.ndarray, sound_speed_mps: float,
                 noise: np.ndarray, seed: int, follower: str, leader: str) -> np.ndarray:
    """The ranges of one link before anomalies: true + noise scaled by the conditions + biases.

    ``noise`` is the link's unit Gaussian draw (the default trial's);
    heavy tails and range-dependent sigma rescale it, the sound-speed bias
    and the clock offset and drift of the pair add to it.
    """
    sigma = sigma_m + c.range_noise_per_km_m * true_m / 1000.0 if c.range_noise_per_km_m > 0 else sigma_m
    unit = noise
    if c.range_noise_dof > 0:
        # Student-t with dof degrees of freedom, rescaled to unit variance (dof > 2)
        tail = stream(seed, "range-tail", follower, leader)
        dof = c.range_noise_dof
        unit = noise * np.sqrt(dof / tail.chisquare(dof, len(noise))) * math.sqrt((dof - 2.0) / dof)
    out = true_m + unit * sigma
    if c.sound_speed_bias != 0:
        out = out + true_m * c.sound_speed_bias
    if c.owtt_clock_offset_s > 0 or c.owtt_clock_drift_ppm > 0:
        clock = stream(seed, "owtt-clock", follower, leader)
        offset = clock.uniform(-c.owtt_clock_offset_s, c.owtt_clock_offset_s)
        drift = clock.uniform(-c.owtt_clock_drift_ppm, c.owtt_clock_drift_ppm) * 1e-6
        out = out + sound_speed_mps * (offset + drift * t_s)
    return out


def multipath_events(c: Conditions, follower: str, leader: str, duration_s: float,
                     seed: int) -> list[AnomalyEvent]:
    """The multipath segments of one link (at least one): jittered starts, bias and length drawn per segment."""
    if c.multipath_per_hour <= 0:
        return []
    rng = stream(seed, "multipath", follower, leader)
    period = 3600.0 / c.multipath_per_hour
    count = max(int(duration_s // period), 1)
    starts = (np.arange(count) + rng.random(count)) * min(period, duration_s)
    lengths = rng.uniform(c.multipath_min_s, c.multipath_max_s, count)
    sizes = rng.uniform(c.multipath_min_m, c.multipath_max_m, count)
    return [AnomalyEvent(leader, "multipath", round(float(s), 1), round(float(min(s + n, duration_s)), 1),
                         round(float(m), 2), follower) for s, n, m in zip(starts, lengths, sizes)]


def bottom_lock(c: Conditions, t_s: np.ndarray, vehicle: str, duration_s: float, seed: int) -> np.ndarray:
    """True where the vehicle's DVL has bottom lock: stretches of loss (at least one), jittered like stale ones."""
    valid = np.ones(len(t_s), dtype=bool)
    if c.dvl_lock_loss_per_hour <= 0:
        return valid
    rng = stream(seed, "dvl-lock", vehicle)
    period = 3600.0 / c.dvl_lock_loss_per_hour
    count = max(int(duration_s // period), 1)
    starts = (np.arange(count) + rng.random(count)) * min(period, duration_s)
    lengths = rng.uniform(c.dvl_lock_loss_min_s, c.dvl_lock_loss_max_s, count)
    for s, n in zip(starts, lengths):
        valid &= ~((t_s >= s) & (t_s < s + n))
    return valid


def compass_deviation(c: Conditions, heading_deg: np.ndarray, vehicle: str, seed: int) -> np.ndarray:
    """Heading error (deg) that depends on the heading: one-cycle and two-cycle terms, phases drawn per seed."""
    if c.compass_deviation_deg <= 0:
        return np.zeros(len(heading_deg))
    rng = stream(seed, "compass", vehicle)
    p1, p2 = rng.uniform(0.0, 2.0 * math.pi, 2)
    h = np.radians(heading_deg)
    return c.compass_deviation_deg * (np.sin(h + p1) + 0.5 * np.sin(2.0 * h + p2))
