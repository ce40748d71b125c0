"""The stack driven straight from the simulator's arrays (no logs, no archive): the reference a replay
through the archive is checked against.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from replay.stack.config import StackConfig
from replay.stack.runner import CooperativeRunner, RunResults, Start
from replay.stack.scoring import score_run


def run_on_arrays(trial: Any, config: StackConfig) -> tuple[RunResults, dict[str, dict[str, Any]]]:
    """Push the follower's DVL/INS samples and every range epoch through the runner; score after t_a.

    Leader positions are their INS at the ranging instant and the truth range
    comes from the GPS fixes, as the engine takes them from an archive.
    """
    fol = next(v for v in trial.vehicles if v.role == "follower")
    d = fol.dvl
    heading = np.radians(d.heading_deg)
    depth = np.interp(d.t_s, fol.ins.t_s, fol.ins.depth_m)
    samples = list(zip(d.t_s.tolist(), d.forward_mps.tolist(), d.starboard_mps.tolist(), heading.tolist(),
                       depth.tolist()))
    r = trial.ranges
    epochs = list(zip(r.t_s.tolist(), [str(x) for x in r.leader], np.radians(r.leader_ins_lat_deg).tolist(),
                      np.radians(r.leader_ins_lon_deg).tolist(), r.leader_depth_m.tolist(), r.range_m.tolist(),
                      r.z_gps_m.tolist()))
    leaders = sorted({e[1] for e in epochs})
    runner = CooperativeRunner(config, fol.name, leaders, Start(0.0, math.radians(fol.gps.lat_deg[0]),
                                                                math.radians(fol.gps.lon_deg[0]), samples[0][4]))
    k = 0
    for row in samples:
        while k < len(epochs) and epochs[k][0] <= row[0]:
            runner.range_epoch(*epochs[k])
            k += 1
        runner.dead_reckon(*row)
    for e in epochs[k:]:
        runner.range_epoch(*e)
    results = runner.finish()
    scores = score_run(results, fol.gps.t_s, np.radians(fol.gps.lat_deg), np.radians(fol.gps.lon_deg))
    return results, scores
