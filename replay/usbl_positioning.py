"""Positioning methods applied to one archived USBL epoch: KMCDF and the delay-only baselines.

In an archive the states of the parameters are unknown, so the engine runs
the general KMCDF (judging delays and phases, the paper's second experiment)
and reports it as `kmcdf2`; `kmcdf1` names the paper's delays-only
experiment and appears only in `reproduce kmcdf`.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from .stack.kmcdf_montecarlo import run_baseline
from .usbl_epochs import UsblEpoch

BASELINES = ("gar", "ear", "lms", "lhc")


def positions_for_epoch(epoch: UsblEpoch) -> dict[str, tuple[float, float]]:
    """East/north fix (m) of each positioning method; NaN where a method reached no decision."""
    out = {"kmcdf2": (float(epoch.fix.position_xy[0]), float(epoch.fix.position_xy[1]))}
    finite = np.isfinite(epoch.delays_s)
    if finite.sum() < 3:
        return out
    batch = SimpleNamespace(node_xy=epoch.node_en[finite], delays_s=epoch.delays_s[finite][None, :])
    for name in BASELINES:
        try:
            result = run_baseline(name, batch, epoch.params)
            xy = result.position[0]
            ok = bool(result.resolved[0]) and all(math.isfinite(v) for v in xy)
            out[name] = (float(xy[0]), float(xy[1])) if ok else (math.nan, math.nan)
        except (ValueError, np.linalg.LinAlgError):
            out[name] = (math.nan, math.nan)
    return out
