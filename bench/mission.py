"""A synthetic long mission written straight into an archive (bench helper, not product code).

The simulator's arrays at the bench's rates (INS 50 Hz, DVL 5 Hz, GPS 1 Hz,
ranging every 2.4 s) become archive messages directly: generating vendor logs
for 24 h only to record them again would time the recorder, not the replay.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from formats import schemas as S
from formats.mcap_writer import ArchiveWriter
from samples.scenario import Scenario
from samples.simulator import simulate_trial


def mission_scenario(duration_s: float, ins_hz: float = 50.0, dvl_hz: float = 5.0) -> Scenario:
    """The lake scenario stretched to `duration_s` with fast INS and DVL, anomalies as configured."""
    s = Scenario().with_options(duration_s=duration_s)
    return dataclasses.replace(
        s, ins=dataclasses.replace(s.ins, rate_hz=ins_hz),
        dvl=dataclasses.replace(s.dvl, rate_hz=dvl_hz, leader_rate_hz=dvl_hz))


def write_mission(path: Path, duration_s: float, seed: int = 0) -> int:
    """Simulate and write the mission archive; returns the number of messages."""
    trial = simulate_trial(mission_scenario(duration_s), seed)
    n = 0
    with ArchiveWriter(path) as w:
        for v in trial.vehicles:
            g, ins, dvl = v.gps, v.ins, v.dvl
            for t, lat, lon, alt in zip(trial.t_ns(g.t_s).tolist(), g.lat_deg.tolist(), g.lon_deg.tolist(),
                                        g.altitude_m.tolist()):
                w.write(f"/{v.name}/gps", S.location_fix(t, v.name, lat, lon, alt), t)
                n += 1
            cols = zip(trial.t_ns(ins.t_s).tolist(), ins.lat_deg.tolist(), ins.lon_deg.tolist(),
                       ins.depth_m.tolist(), ins.heading_deg.tolist())
            for t, lat, lon, depth, hdg in cols:
                w.write(f"/{v.name}/ins", S.InsState(timestamp=S.timestamp(t), frame_id=v.name, latitude=lat,
                                                     longitude=lon, depth_m=depth, heading_deg=hdg), t)
                n += 1
            if v.role != "follower":
                continue
            for t, fwd, stbd in zip(trial.t_ns(dvl.t_s).tolist(), dvl.forward_mps.tolist(),
                                    dvl.starboard_mps.tolist()):
                w.write(f"/{v.name}/dvl", S.DvlVelocity(timestamp=S.timestamp(t), frame_id=v.name,
                                                        frame=S.DvlVelocity.BODY_FRD, velocity_x_mps=fwd,
                                                        velocity_y_mps=stbd, velocity_z_mps=0.0, valid=True), t)
                n += 1
        r = trial.ranges
        for t, f, ld, rng, tt in zip(trial.t_ns(r.t_s).tolist(), r.follower.tolist(), r.leader.tolist(),
                                     r.range_m.tolist(), r.travel_time_s.tolist()):
            w.write(f"/{f}/modem/range", S.AcousticRange(timestamp=S.timestamp(t), source=ld, destination=f,
                                                         travel_time_s=tt, range_m=rng, kind="ping"), t)
            n += 1
        roles = [{"name": v.name, "role": v.role} for v in trial.vehicles]
        w.add_metadata("trial", {"name": f"mission-{duration_s:.0f}s", "vehicles": roles})
    return n
