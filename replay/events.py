"""What the replay engine hands to its listeners: every type a listener receives, and the Listener itself.

This module imports nothing of ours at run time (the KMCDF types in
`UsblEpoch` are named for the type checker only), so the stack, the engine,
the results writer and the review collector can all share it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

    from replay.stack.positioning.kmcdf import KmcdfFix, KmcdfParams
    from replay.stack.training import TrainingSet

NAN = float("nan")


@dataclass(frozen=True, slots=True)
class Fix:
    """A position sample: time (s since the trial start), latitude/longitude (rad), depth (m)."""

    t_s: float
    lat_rad: float
    lon_rad: float
    depth_m: float = 0.0


class ErrorSample(NamedTuple):
    """Horizontal error of one method's estimate against GPS: at a follower GPS fix, or at a USBL epoch."""

    # a NamedTuple, not a frozen dataclass: one per method at every GPS fix, built ~3x cheaper

    t_s: float
    method: str
    error_m: float


class EpochResult(NamedTuple):
    """One method's outcome at one range epoch, with its position estimate after the epoch.

    A NamedTuple: a run builds one per method and epoch, and a 21-field frozen
    dataclass costs four times as much to make.
    """

    time_s: float
    leader: str
    method: str
    flagged: bool
    score: float
    threshold: float
    f1: float                 # |innovation| (m)
    f2: float                 # squared Mahalanobis distance, unadapted P_zz
    f3: float                 # adapted measurement variance R* (m²)
    label: int                # 1 anomalous, 0 normal, -1 unknown
    isolated: bool
    capped: bool
    compensated: bool
    range_m: float            # horizontal range used (after slant conversion / compensation)
    predicted_range_m: float
    lat_rad: float
    lon_rad: float
    cov_nn_m2: float          # position covariance north-north, north-east, east-east (m²)
    cov_ne_m2: float
    cov_ee_m2: float
    truth_range_m: float = NAN   # horizontal range from the GPS fixes (NaN without truth)
    # filter-independent features (replay.stack.features), the same for every method of an epoch
    repeat_count: float = NAN         # consecutive identical slant ranges from this leader
    dr_residual_m: float = NAN        # range - dead-reckoned range, relative to its 60 s median
    leader_consistency_m: float = NAN  # dr_residual_m minus the other leaders' latest
    usbl_residual_m: float = NAN      # range - range from the USBL-anchored position (NaN without a fix)
    lag_residual_m: float = NAN       # range - range from the ackf estimate of 60 s ago + DR since
    drift_residual_m: float = NAN     # usbl_residual_m, else lag_residual_m, else dr_residual_m
    drift_cusum_m: float = NAN        # max(S+, S-) of the drift residual's CUSUM
    exclusion_residual_m: float = NAN  # range - range of the ACKF on DR and the other leaders' ranges only
    drift_z: float = NAN              # drift residual against all leaders' median / MAD-scale of 60-900 s ago
    exclusion_z: float = NAN          # exclusion residual against its median / MAD-scale of 60-300 s ago
    model_innovation_m: float = NAN   # range - the DR error model's current prediction (a stale run's error)


@dataclass(frozen=True)
class Track:
    """A method's estimates after every DR step and epoch: times, [L, λ] and north-east covariances."""

    t_s: np.ndarray
    lat_rad: np.ndarray
    lon_rad: np.ndarray
    cov_m2: np.ndarray        # (n, 2, 2), north-east


@dataclass(frozen=True)
class RunResults:
    """Everything a run produced, as arrays ready for DataFrames and for ``scoring``."""

    methods: tuple[str, ...]
    leaders: tuple[str, ...]
    start_time_s: float
    training_end_s: float
    epochs: dict[str, np.ndarray]
    tracks: dict[str, Track]
    open_loop: dict[str, dict[str, np.ndarray]]
    rejected: dict[str, int]
    capped: dict[str, int]
    clamped_ranges: int
    trained: bool
    training_errors: dict[str, str]
    position_fixes: int = 0       # position fixes (USBL) applied to the filters
    # what the detectors were trained on (replay.stack.training), for training other runs on it
    training_set: TrainingSet | None = None
    # method -> leader -> named thresholds ("3sigma", "fpr_target", "used", ...)
    thresholds: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    training_notes: dict[str, str] = field(default_factory=dict)   # what went into training, in words

    def epochs_frame(self) -> pd.DataFrame:
        """The epochs table as a pandas DataFrame (pandas imported on first use)."""
        import pandas as pd
        return pd.DataFrame(self.epochs)


@dataclass(frozen=True)
class UsblEpoch:
    """One target's epoch: emission time, node names and positions, delays, phases, and the KMCDF fix."""

    t_s: float
    target: str
    nodes: tuple[str, ...]
    node_en: np.ndarray           # (N, 2) east, north metres
    delays_s: np.ndarray
    phase_x: np.ndarray
    phase_y: np.ndarray
    fix: KmcdfFix
    params: KmcdfParams


class TrainedDetectors(Protocol):
    """What a listener may read of a follower's runner once its detectors are trained (at t_a)."""

    training_end_s: float

    def detectors(self, method: str) -> Mapping[str, Any]:
        """The trained detector per leader of a detecting method."""
        ...


@dataclass
class FollowerScores:
    """What scoring needs of one follower after t_a, kept compact: typed arrays, a few bytes per epoch or fix."""

    flagged: dict[str, Any] = field(default_factory=dict)     # method -> array("b")
    labels: dict[str, Any] = field(default_factory=dict)      # method -> array("b")
    errors: dict[str, Any] = field(default_factory=dict)      # method -> array("d") of metres
    epochs: int = 0
    anomalous: int = 0


@dataclass(frozen=True)
class RunScores:
    """What the engine hands to the metrics at the end of a run: scores per follower and positioning method."""

    methods: tuple[str, ...]
    training_end_s: float
    followers: dict[str, FollowerScores]
    positioning_errors: dict[str, Any]                        # method -> array("d") of metres
    usbl_epochs: int
    notes: list[str]
    counts: dict[str, int]
    skipped: dict[str, str] = field(default_factory=dict)      # method -> the input no vehicle held


class Listener:
    """Receives what the engine produces; the results writer and the review collector implement it."""

    def origin(self, lat_rad: float, lon_rad: float) -> None:
        """The local frame's origin (the trial's first GPS fix), said once before any east/north is used."""

    def epoch(self, follower: str, results: list[EpochResult], leader_fix: Fix | None) -> None:
        """One range epoch: a result per method, and the ranged leader's position at the epoch."""

    def estimates(self, follower: str, t_s: float, estimates: Mapping[str, tuple[float, ...]]) -> None:
        """Every method's estimate (lat, lon rad, nn, ne, ee m²) at t."""

    def errors(self, follower: str, samples: list[ErrorSample]) -> None:
        """Horizontal errors against GPS."""

    def usbl(self, epoch: UsblEpoch, positions: dict[str, tuple[float, float]]) -> None:
        """One USBL epoch with each positioning method's east/north fix."""

    def trained(self, follower: str, models: TrainedDetectors, t_s: float) -> None:
        """The detectors of a follower's runner were trained at t."""

    def finished(self, follower: str, results: RunResults) -> None:
        """A follower's runner finished."""

    def position(self, vehicle: str, source: str, fix: Fix) -> None:
        """A recorded position (source "gps" or "ins") of any vehicle."""

    def positions(self, vehicle: str, source: str, t_s: Any, lat_rad: Any, lon_rad: Any, depth_m: Any) -> None:
        """A block's recorded positions of one vehicle and source as columns (numpy arrays, time order); by
        default each one to `position`."""
        for t, lat, lon, depth in zip(t_s.tolist(), lat_rad.tolist(), lon_rad.tolist(), depth_m.tolist()):
            self.position(vehicle, source, Fix(t, lat, lon, depth))

    def event(self, t_s: float, level: str, text: str) -> None:
        """Something a reviewer should read: a rejected record, training finished, a note."""
