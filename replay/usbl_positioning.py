"""Positioning methods applied to one archived USBL epoch: KMCDF and the delay-only baselines.

In an archive the states of the parameters are unknown, so the engine runs
the general KMCDF (judging delays and phases, the paper's second experiment)
and reports it as `kmcdf2`; `kmcdf1` names the paper's delays-only
experiment and appears only in `reproduce kmcdf`.
"""

from __future__ import annotations

import math
import numpy as np

from .stack.kmcdf_montecarlo import delay_baseline
from .usbl_epochs import UsblEpoch

BASELINES = ("gar", "ear", "lms", "lhc")
# LHC's majorization creeps along flat Huber valleys for hundreds of steps; per epoch
# in a replay we stop at 1 cm or 100 steps (the Monte Carlo figure runs it to 1e-6 m)
LHC_MAX_ITERATIONS = 100
LHC_TOLERANCE_M = 0.01


def positions_for_epoch(epoch: UsblEpoch) -> dict[str, tuple[float, float]]:
    """East/north fix (m) of each positioning method; NaN where a method reached no decision."""
    out = {"kmcdf2": (float(epoch.fix.position_xy[0]), float(epoch.fix.position_xy[1]))}
    finite = np.isfinite(epoch.delays_s)
    if finite.sum() < 3:
        return out
    nodes, delays = epoch.node_en[finite], epoch.delays_s[finite][None, :]
    centre = tuple(float(v) for v in nodes.mean(axis=0))
    half = float(epoch.params.max_range_m)
    for name in BASELINES:
        try:
            result = delay_baseline(name, nodes, delays, epoch.params, field_centre_xy=centre,
                                    field_half_width_m=half, lhc_tolerance_m=LHC_TOLERANCE_M,
                                    lhc_max_iterations=LHC_MAX_ITERATIONS)
            xy = result.position[0]
            ok = bool(result.resolved[0]) and all(math.isfinite(v) for v in xy)
            out[name] = (float(xy[0]), float(xy[1])) if ok else (math.nan, math.nan)
        except (ValueError, np.linalg.LinAlgError):
            out[name] = (math.nan, math.nan)
    return out
