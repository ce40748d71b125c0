"""The feature tracker a runner (or a hybrid-database copy) is handed, wired from the stack's configuration.

The filter-independent features (`replay.stack.features`) are an input of
the new methods only (a method-table entry reading more than (f1, f2, f3)):
without one of them the runner builds no tracker, and an epoch's
EXTRA_FEATURES are NaN (the tracker costs ~5 % of a replay).
"""

from __future__ import annotations

from collections.abc import Sequence

from replay.stack.config import StackConfig
from replay.stack.detectors.chi_square import chi_square_threshold
from replay.stack.exclusion import ExclusionParams, LeaderExclusion
from replay.stack.features import FeatureTracker
from replay.stack.methods import method
from replay.stack.runner_options import Start


def needs_features(config: StackConfig) -> bool:
    """True when a configured method decides on the filter-independent features (and trains on the hybrid database)."""
    return any(method(n).wide for n in dict.fromkeys(config.methods))


def leader_exclusion(config: StackConfig, leaders: Sequence[str], start: Start) -> LeaderExclusion | None:
    """Fresh leader-exclusion filters at the start position when a new method uses them, else None.

    Used when the drift residual is the exclusion residual or anfis_hybrid
    takes it; otherwise the features stay NaN and the two extra filters
    cost nothing (held out, seeds 100-109 trained on 0, they did not help).
    """
    c = config
    wanted = c.features.drift_source == "exclusion" or bool(
        {"exclusion_residual_m", "exclusion_z"} & set(c.hybrid_inputs))
    if not (needs_features(c) and wanted):
        return None
    return LeaderExclusion(tuple(leaders), (float(start.lat_rad), float(start.lon_rad), float(start.depth_m)),
                           ExclusionParams(c.p0_m, c.q_m_per_s, c.r_m, chi_square_threshold(c.chi_square_alpha),
                                           c.features.exclusion_cap, c.features.exclusion_gate_m))


def feature_tracker(config: StackConfig, leaders: Sequence[str], start: Start) -> FeatureTracker:
    """A feature tracker at the start position, with the leader-exclusion filters when a method uses them."""
    return FeatureTracker(config.features, tuple(leaders), (float(start.lat_rad), float(start.lon_rad)),
                          leader_exclusion(config, leaders, start), config.r_m, config.p0_m)


def runner_tracker(config: StackConfig, leaders: Sequence[str], start: Start) -> FeatureTracker | None:
    """The runner's feature tracker: one when a configured method reads the features, else None."""
    return feature_tracker(config, leaders, start) if needs_features(config) else None
