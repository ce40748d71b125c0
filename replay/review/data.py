"""Everything a reviewer sees of one replay run, as plain DataFrames: what the views draw.

The engine fills it from an archive; the Rerun views (`replay.views.recording`) read it.
Times are float seconds since the trial start (`t_s`) plus the absolute
`trial_start_ns` to put them on a UTC timeline. Angles in degrees, distances
in metres; local east/north metres are relative to `origin_lat_deg`,
`origin_lon_deg`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import pandas as pd


def empty(columns: list[str]) -> pd.DataFrame:
    """An empty DataFrame with the given columns."""
    return pd.DataFrame({c: [] for c in columns})


TRACK_COLUMNS = ["t_s", "vehicle", "source", "lat_deg", "lon_deg", "east_m", "north_m", "std_east_m", "std_north_m"]
RANGE_COLUMNS = ["t_s", "follower", "leader", "measured_m", "true_m", "residual_m", "leader_east_m", "leader_north_m",
                 "horizontal_m"]
DETECTION_COLUMNS = ["t_s", "follower", "leader", "method", "flagged", "score", "threshold", "f1_innovation_m",
                     "f2_mahalanobis2", "f3_r_adapted_m2", "label", "isolated", "capped",
                     # the filter-independent features (replay.stack.features.EXTRA_FEATURES), NaN where a run
                     # did not compute them, and why the detector did (not) flag ('' before t_a)
                     "repeat_count", "dr_residual_m", "leader_consistency_m", "usbl_residual_m", "lag_residual_m",
                     "drift_residual_m", "drift_cusum_m", "exclusion_residual_m", "drift_z", "exclusion_z",
                     "model_innovation_m", "why"]
ERROR_COLUMNS = ["t_s", "follower", "method", "error_m"]
ANFIS_EPOCH_COLUMNS = ["model", "epoch", "rmse", "params"]          # params: dict (see AnfisSnapshot)
ANFIS_EXPLAIN_COLUMNS = ["t_s", "model", "inputs", "memberships", "firing", "output", "threshold", "flagged"]
KMCDF_COLUMNS = ["t_s", "target", "method", "east_m", "north_m", "fixes_east_m", "fixes_north_m", "fixes_cluster",
                 "nodes_east_m", "nodes_north_m", "delay_normal", "phase_normal", "nodes"]
EVENT_COLUMNS = ["t_s", "level", "text"]


if TYPE_CHECKING:
    from replay.navigation.review import NavigationReview


@dataclass
class ReviewData:
    """One run of one trial, ready to draw.

    - tracks: every position track; `source` is "gps" (truth), "ins", or a method name
      (dead_reckoning, ckf, ackf, chi_square, dual_threshold, anfis, anfis_aqpso,
      anfis_compensation, kmcdf1, kmcdf2, gar, ear, lms, lhc).
    - ranges: every ranging epoch with measured and GPS-true slant range.
    - detections: one row per (epoch, detecting method): outcome, score and threshold, every feature,
      and `why`, one line saying what the detector compared (`replay.review.why`).
    - errors: horizontal error of each method's follower estimate against GPS.
    - anfis_epochs: every ANFIS model (each method of the method table's `anfis_models` that ran, per
      leader; `model` "<method>/<leader>", "<method>/<follower>/<leader>" with several followers) after
      every training epoch (params as a dict: a, b, c [input][mf], consequents, input_min, input_max,
      and what the model is: method, leader, trainer, inputs, compensation, training_samples).
    - anfis_explain: per ranging epoch after training and per ANFIS model, the inputs (normalized),
      memberships per input/MF, rule firing strengths, output and threshold.
    - kmcdf: per USBL epoch and positioning method, the final fix, the preliminary fixes with
      their cluster (only methods that make them: kmcdf2), and the nodes by vehicle name (`nodes`).
      Every positioning method also has a track (vehicle = target) and error rows.
    - events: text log on mission seconds: training, notes, anomaly interval start and end, and one
      line per epoch where a detector flagged or the truth is anomalous (WARN on a false alarm or a miss).
    - parameters: the run's configuration as a dict (what `run_labels` names comparisons by).
    """

    run_id: str
    trial: str
    trial_start_ns: int
    origin_lat_deg: float
    origin_lon_deg: float
    vehicles: dict[str, str] = field(default_factory=dict)      # name -> role
    methods: list[str] = field(default_factory=list)
    tracks: pd.DataFrame = field(default_factory=lambda: empty(TRACK_COLUMNS))
    ranges: pd.DataFrame = field(default_factory=lambda: empty(RANGE_COLUMNS))
    detections: pd.DataFrame = field(default_factory=lambda: empty(DETECTION_COLUMNS))
    errors: pd.DataFrame = field(default_factory=lambda: empty(ERROR_COLUMNS))
    anfis_epochs: pd.DataFrame = field(default_factory=lambda: empty(ANFIS_EPOCH_COLUMNS))
    anfis_explain: pd.DataFrame = field(default_factory=lambda: empty(ANFIS_EXPLAIN_COLUMNS))
    kmcdf: pd.DataFrame = field(default_factory=lambda: empty(KMCDF_COLUMNS))
    events: pd.DataFrame = field(default_factory=lambda: empty(EVENT_COLUMNS))
    metrics: dict[str, Any] = field(default_factory=dict)       # the replay --json object
    parameters: dict[str, Any] = field(default_factory=dict)    # the run's configuration (to_dict)
    # what reading the input archive skipped, "<path>: <warning>", when a results archive's run was re-run
    input_warning: str | None = None
    # per vehicle with a DVL or an INS: its navigation review (replay.navigation: DR, drift at fixes, lock, series)
    navigation: dict[str, NavigationReview] = field(default_factory=dict)
