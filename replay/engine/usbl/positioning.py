"""Positioning methods applied to archived USBL epochs: KMCDF and the delay-only baselines.

In an archive the states of the parameters are unknown, so the engine runs
the general KMCDF (judging delays and phases, the paper's second experiment)
and reports it as `kmcdf2`; `kmcdf1` names the paper's delays-only
experiment and appears only in `reproduce kmcdf`.

Epochs are positioned in batches: the baselines run once per group of
epochs with the same count of finite delays and the same KMCDF parameters,
with each epoch's own buoy positions (T, N, 2); every baseline treats the
trials of a batch independently, so a batch gives what each epoch alone gives.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from replay.events import UsblEpoch
from replay.stack.positioning.kmcdf import KmcdfParams
from replay.stack.positioning.kmcdf_montecarlo import delay_baseline
from replay.stack.positioning.toa_baselines import BaselineResult

BASELINES = ("gar", "ear", "lms", "lhc")
# LHC's majorization creeps along flat Huber valleys for hundreds of steps; per epoch
# in a replay we stop at 1 cm or 100 steps (the Monte Carlo figure runs it to 1e-6 m)
LHC_MAX_ITERATIONS = 100
LHC_TOLERANCE_M = 0.01

Positions = dict[str, tuple[float, float]]


def positions_for_epoch(epoch: UsblEpoch) -> Positions:
    """East/north fix (m) of each positioning method; NaN where a method reached no decision."""
    return positions_for_epochs([epoch])[0]


def positions_for_epochs(epochs: Sequence[UsblEpoch]) -> list[Positions]:
    """`positions_for_epoch` of each epoch, with one vectorized call per baseline and group of epochs."""
    out: list[Positions] = [
        {"kmcdf2": (float(e.fix.position_xy[0]), float(e.fix.position_xy[1]))} for e in epochs]
    groups: dict[tuple[int, KmcdfParams], list[int]] = {}
    for i, e in enumerate(epochs):
        count = int(np.sum(np.isfinite(e.delays_s)))
        if count >= 3:
            groups.setdefault((count, e.params), []).append(i)
    for (_, params), members in groups.items():
        finite = [np.isfinite(epochs[i].delays_s) for i in members]
        nodes = np.stack([epochs[i].node_en[f] for i, f in zip(members, finite)])
        delays = np.stack([epochs[i].delays_s[f] for i, f in zip(members, finite)])
        for name in BASELINES:
            _baseline_into(out, members, name, nodes, delays, params)
    return out


def _baseline_into(out: list[Positions], members: list[int], name: str, nodes: np.ndarray,
                   delays: np.ndarray, params: KmcdfParams) -> None:
    """Run one baseline on a group (T, N, 2) and store each epoch's fix; epoch by epoch if the batch fails."""
    try:
        result = _baseline(name, nodes, delays, params)
    except (ValueError, np.linalg.LinAlgError):
        if len(members) == 1:
            out[members[0]][name] = (math.nan, math.nan)
            return
        # a failure is one epoch's: rerun alone so the others keep their fixes
        for k, i in enumerate(members):
            _baseline_into(out, [i], name, nodes[k:k + 1], delays[k:k + 1], params)
        return
    xy, ok = result.position.tolist(), result.resolved.tolist()
    for k, i in enumerate(members):
        good = ok[k] and math.isfinite(xy[k][0]) and math.isfinite(xy[k][1])
        out[i][name] = (float(xy[k][0]), float(xy[k][1])) if good else (math.nan, math.nan)


def _baseline(name: str, nodes: np.ndarray, delays: np.ndarray, params: KmcdfParams) -> BaselineResult:
    """One baseline on T epochs, EAR's field centred on each epoch's own nodes."""
    return delay_baseline(name, nodes, delays, params, field_centre_xy=nodes.mean(axis=-2),
                          field_half_width_m=float(params.max_range_m), lhc_tolerance_m=LHC_TOLERANCE_M,
                          lhc_max_iterations=LHC_MAX_ITERATIONS)
