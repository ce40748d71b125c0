"""Navigation logs of the simulated trial: GPS (NMEA, NovAtel), INS (PHINS, NovAtel SPAN), DVL (PD0).

Which vehicle writes which format is decided in `writer._plans`. All are
raw instrument output (no host prefixes: every record carries its own time).
"""

from __future__ import annotations

import math

import numpy as np

from formats import phins
from formats.nmea import sentences as nmea
from formats.novatel import logs as novatel
from formats.pd0 import ensembles as pd0
from formats.pd0 import frames

from .sensors import GEOID_SEPARATION_M, GpsSeries
from .simulator import SimulatedTrial

MPS_TO_KNOTS = 3600.0 / 1852.0
LAKE_TEMPERATURE_C = 12.0


def _gps(trial: SimulatedTrial, name: str) -> GpsSeries:
    for b in trial.buoys:
        if b.name == name:
            return b.gps
    return trial.vehicle(name).gps


def surfaced(trial: SimulatedTrial, name: str, t_s: np.ndarray) -> np.ndarray:
    """Where a vehicle's GPS receiver has sky: always, but for a follower during its dives (scenario `gps`)."""
    cfg = trial.scenario.gps
    role = next((v.role for v in trial.vehicles if v.name == name), "buoy")
    if cfg.follower_dive_s <= 0 or role != "follower":
        return np.ones(np.shape(t_s), dtype=bool)
    phase = (np.asarray(t_s) - cfg.follower_first_dive_s) % (cfg.follower_dive_s + cfg.follower_surface_s)
    return (np.asarray(t_s) < cfg.follower_first_dive_s) | (phase >= cfg.follower_dive_s)


def nmea_gps(trial: SimulatedTrial, name: str) -> bytes:
    """GGA, GST and RMC every fix (buoys: GGA and RMC), straight from the receiver; none while submerged."""
    g = _gps(trial, name)
    buoy = name.startswith("buoy")
    t_ns = trial.t_ns(g.t_s)
    sky = surfaced(trial, name, g.t_s)
    out = []
    for i in np.flatnonzero(sky):
        t = int(t_ns[i])
        lines = [nmea.encode_gga(t, float(g.lat_deg[i]), float(g.lon_deg[i]), satellites=int(g.satellites[i]),
                                 hdop=float(g.hdop[i]), altitude_msl_m=float(g.altitude_m[i]),
                                 geoid_separation_m=GEOID_SEPARATION_M, decimals=6)]
        if not buoy:
            lines.append(nmea.encode_gst(t, lat_std_m=g.sigma_m, lon_std_m=g.sigma_m,
                                         alt_std_m=trial.scenario.gps.vertical_sigma_m,
                                         rms_m=trial.scenario.gps.horizontal_rms_m))
        lines.append(nmea.encode_rmc(t, float(g.lat_deg[i]), float(g.lon_deg[i]),
                                     speed_knots=float(g.speed_mps[i] * MPS_TO_KNOTS),
                                     course_deg=float(g.course_deg[i]), decimals=6))
        out += lines
    return "".join(out).encode("ascii")


def novatel_gps(trial: SimulatedTrial, name: str) -> bytes:
    """NovAtel OEMV #BESTPOSA at every fix (single point, 1-sigma errors from the model)."""
    g = _gps(trial, name)
    sigma_v = trial.scenario.gps.vertical_sigma_m
    t_ns = trial.t_ns(g.t_s)
    out = [
        novatel.encode_bestposa(
            int(t_ns[i]), float(g.lat_deg[i]), float(g.lon_deg[i]), float(g.altitude_m[i]),
            lat_std_m=g.sigma_m, lon_std_m=g.sigma_m, height_std_m=sigma_v, undulation_m=GEOID_SEPARATION_M,
            satellites_tracked=int(g.satellites[i]) + 2, satellites_used=int(g.satellites[i]), sequence=0)
        for i in np.flatnonzero(surfaced(trial, name, g.t_s))
    ]
    return "".join(out).encode("ascii")


def _phins_burst(t_ns: int, lat: float, lon: float, depth: float, heading: float, roll: float, pitch: float,
                 vn: float, ve: float, vd: float, std_h: float, std_att: float, std_pos: float) -> str:
    """The PHINS sentences the leaders were configured to output, in PHINS burst order."""
    return "".join((
        phins.encode_hehdt(heading),
        phins.encode_atitud(roll, -pitch + 0.0),  # PHINS pitch is positive bow down
        phins.encode_positi(lat, lon, -depth + 0.0),
        phins.encode_speed(ve, vn, -vd + 0.0),
        phins.encode_time(t_ns),
        phins.encode_stdhrp(std_h, std_att, std_att),
        phins.encode_stdpos(std_pos, std_pos, 0.1),
        phins.encode_status("ALGSTS", 0x00000045, 0),
    ))


def phins_ins(trial: SimulatedTrial, name: str) -> bytes:
    """A leader's PHINS standard bursts, one per INS epoch (altitude relative to the lake surface)."""
    s = trial.vehicle(name).ins
    att = trial.scenario.ins.attitude_sigma_deg
    t_ns = trial.t_ns(s.t_s)
    cols = np.column_stack([s.lat_deg, s.lon_deg, s.depth_m, s.heading_deg, s.roll_deg, s.pitch_deg,
                            s.vel_north_mps, s.vel_east_mps, s.vel_down_mps, s.position_std_m])
    out = [_phins_burst(int(t_ns[i]), lat, lon, depth, heading, roll, pitch, vn, ve, vd, s.heading_std_deg, att,
                        std_pos)
           for i, (lat, lon, depth, heading, roll, pitch, vn, ve, vd, std_pos) in enumerate(cols.tolist())]
    return "".join(out).encode("ascii")


def novatel_ins(trial: SimulatedTrial, name: str) -> bytes:
    """A follower's low-grade SPAN solution as #INSPVAXA.

    Heights are relative to the lake surface as vertical datum (as the INS
    units of a lake trial are set up to report depth), so that
    -(height - undulation) is the transducer depth.
    """
    s = trial.vehicle(name).ins
    cfg = trial.scenario.ins
    t_ns = trial.t_ns(s.t_s)
    height = GEOID_SEPARATION_M - s.depth_m
    out = [
        novatel.encode_inspvaxa(
            int(t_ns[i]), float(s.lat_deg[i]), float(s.lon_deg[i]), float(height[i]),
            float(s.vel_north_mps[i]), float(s.vel_east_mps[i]), float(-s.vel_down_mps[i]), float(s.roll_deg[i]),
            float(s.pitch_deg[i]), float(s.heading_deg[i]), lat_std_m=float(s.position_std_m[i]),
            lon_std_m=float(s.position_std_m[i]), height_std_m=0.5, velocity_std_mps=cfg.follower_velocity_error_mps,
            roll_std_deg=cfg.attitude_sigma_deg, pitch_std_deg=cfg.attitude_sigma_deg,
            azimuth_std_deg=s.heading_std_deg, undulation_m=GEOID_SEPARATION_M)
        for i in range(len(s.t_s))
    ]
    return "".join(out).encode("ascii")


def pd0_dvl(trial: SimulatedTrial, name: str) -> bytes:
    """Bottom-track PD0 ensembles in ship coordinates with the vehicle's heading and attitude."""
    v = trial.vehicle(name)
    d = v.dvl
    cos_beam = math.cos(math.radians(trial.scenario.dvl.beam_angle_deg))
    vertical = d.beam_range_m * cos_beam
    t_ns = trial.t_ns(d.t_s)
    depth = np.interp(d.t_s, v.track.t_s, v.track.depth_m)
    out = []
    for i in range(len(d.t_s)):
        bottom = frames.bottom_velocity_from_frd(float(d.forward_mps[i]), float(d.starboard_mps[i]),
                                              float(d.down_mps[i]), float(d.error_mps[i]))
        out.append(pd0.encode_ensemble(
            int(t_ns[i]), i + 1, bottom, [float(x) for x in vertical[i]], coordinates="ship",
            beam_angle_deg=int(trial.scenario.dvl.beam_angle_deg),
            sound_speed_mps=trial.scenario.ranging.sound_speed_mps, depth_m=float(depth[i]),
            heading_deg=float(d.heading_deg[i]), pitch_deg=float(d.pitch_deg[i]), roll_deg=float(d.roll_deg[i]),
            temperature_c=LAKE_TEMPERATURE_C, serial_number=1000 + v.modem_address))
    return b"".join(out)
