"""The one table of allowed ranges for every numeric configuration parameter, and the check of a RunConfig.

A value outside its range is refused with one line naming the key, the value and the range, wherever a
configuration is loaded (`replay.run.config.load_config` for files and `--set`, `config_from_parameters`
for a results archive's stored parameters), so that no run path starts the engine on NaN, a negative
sigma or a training set no machine holds. The ranges are physical (a ranging sigma is a positive length
no larger than an acoustic modem's reach, a probability lies in (0, 1)) or computational (the grid ANFIS
has mfs_per_input^3 rules per model); each says why. They hold every default and every value the tests,
samples/, bench/ and docs/ use (tests/test_config_ranges.py checks the defaults and the table's coverage).

`evaluate`'s own numbers (how many seeds, how long a trial, how many workers) are bounded here too.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from typing import Any, NamedTuple

from replay.engine.config import RunConfig
from replay.errors import UserError


class Range(NamedTuple):
    """Allowed values lo..hi; `bounds` says which ends are allowed ("[]", "(]", "[)", "()"); why the range."""

    lo: float
    hi: float
    bounds: str
    why: str

    def holds(self, value: float) -> bool:
        """Whether `value` lies in the range (NaN never does; an infinite value only at an allowed end)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
            return False
        above = value >= self.lo if self.bounds[0] == "[" else value > self.lo
        below = value <= self.hi if self.bounds[1] == "]" else value < self.hi
        return above and below

    def text(self) -> str:
        """The range in words: "positive and at most 20000", "in [0, 1]"."""
        if self.lo == 0 and self.hi != math.inf:
            low = "positive" if self.bounds[0] == "(" else "at least 0"
        elif self.lo == 0:
            return "positive" if self.bounds[0] == "(" else "at least 0"
        else:
            return f"in {self.bounds[0]}{_num(self.lo)}, {_num(self.hi)}{self.bounds[1]}"
        return f"{low} and {'at most' if self.bounds[1] == ']' else 'below'} {_num(self.hi)}"


def _num(x: float) -> str:
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


SEED_MAX = 2**32 - 1           # numpy's SeedSequence and the simulator take seeds in [0, 2^32)
DAY_S = 86_400.0
WEEK_S = 7 * DAY_S
RANGE_MAX_M = 20_000.0         # beyond any acoustic modem's reach (long-baseline systems: about 10 km)

# key (dotted, as --set and CHOICES name it) -> Range; a tuple parameter: every element
RANGES: dict[str, Range] = {
    # the stack (docs/design.md sections 7-9)
    "stack.p0_m": Range(0, 1e5, "(]", "an initial position sigma (m): positive, within 100 km"),
    "stack.q_m_per_s": Range(0, 1e3, "(]", "a DR process sigma per second (m): positive, below 1 km/s"),
    "stack.r_m": Range(0, RANGE_MAX_M, "(]", "a ranging sigma (m): positive, below a modem's reach"),
    "stack.t1_m": Range(0, RANGE_MAX_M, "(]", "a label threshold on a range error (m): positive"),
    "stack.training_window_s": Range(0, WEEK_S, "[]", "t_a (s from the trial start): at most a week"),
    "stack.chi_square_alpha": Range(0, 1, "()", "a false-alarm probability of the chi-square test"),
    "stack.isolation_cap": Range(0, 1e6, "[]", "a count of consecutive isolations"),
    "stack.dual_threshold_cusum_h_m": Range(0, 1e5, "(]", "a CUSUM alarm level (m): positive"),
    "stack.dual_threshold_cusum_k_m": Range(0, 1e5, "[]", "a CUSUM allowance (m): not negative"),
    "stack.dual_threshold_hidden": Range(1, 1000, "[]", "hidden units of the BP network"),
    "stack.seed": Range(0, SEED_MAX, "[]", "a random seed (numpy: [0, 2^32))"),
    "stack.detection_fpr_target": Range(0, 1, "()", "a false-alarm rate on training: a probability"),
    "stack.drift_reference_z": Range(0, 1e3, "(]", "a threshold in sigmas: positive"),
    "stack.running_threshold_gain": Range(0, 1, "[]", "a log step per epoch: 0 (off) to 1 (g moves e-fold)"),
    "stack.running_threshold_share": Range(0, 1, "()", "the share of marginal exceedances held: a probability"),
    "stack.running_threshold_band": Range(1, 1e3, "(]", "a marginal exceedance's ceiling, a multiple above 1"),
    "stack.running_threshold_floor": Range(0, 1, "(]", "the lowest multiple of the starting threshold"),
    # ANFIS (sections 10 and 12)
    "stack.anfis.mfs_per_input": Range(1, 10, "[]", "membership functions per input: the grid has n^3 rules"),
    "stack.anfis.epochs": Range(0, 100_000, "[]", "training epochs"),
    "stack.anfis.initial_step": Range(0, 10, "(]", "the hybrid learning rule's first step size: positive"),
    "stack.anfis.step_increase": Range(1, 10, "[]", "a step-size factor after decreases: at least 1"),
    "stack.anfis.step_decrease": Range(0, 1, "(]", "a step-size factor after oscillations: in (0, 1]"),
    "stack.anfis.ridge": Range(0, 1e6, "[]", "a least-squares ridge: not negative"),
    "stack.anfis.compensation_threshold_m": Range(0, RANGE_MAX_M, "(]", "a range-error threshold (m): positive"),
    "stack.anfis.particles": Range(1, 10_000, "[]", "AQPSO-GA swarm size"),
    "stack.anfis.iterations": Range(0, 100_000, "[]", "AQPSO-GA iterations"),
    "stack.anfis.seed": Range(0, SEED_MAX, "[]", "a random seed (numpy: [0, 2^32))"),
    # features and the drift CUSUM (replay.stack.features)
    "stack.features.median_window_s": Range(0, WEEK_S, "(]", "a window (s): positive, at most a week"),
    "stack.features.lag_s": Range(0, WEEK_S, "[]", "an age (s): not negative, at most a week"),
    "stack.features.reference_gate_m": Range(0, math.inf, "(]", "a gate on a residual (m): positive (inf: none)"),
    "stack.features.reference_cap": Range(0, 1e6, "[]", "a count of consecutive epochs"),
    "stack.features.usbl_max_age_s": Range(0, WEEK_S, "(]", "an age (s): positive, at most a week"),
    "stack.features.usbl_blend": Range(0, 1, "[]", "a weight: in [0, 1]"),
    "stack.features.scale_window_s": Range(0, WEEK_S, "(]", "a window (s): positive, at most a week"),
    "stack.features.scale_min_samples": Range(1, 1e6, "[]", "a sample count: at least 1"),
    "stack.features.scale_floor_m": Range(0, RANGE_MAX_M, "(]", "a scale floor (m): positive (it divides)"),
    "stack.features.scale_pooled_window_s": Range(0, WEEK_S, "(]", "a window (s): positive, at most a week"),
    "stack.features.cusum_k_sigma": Range(0, 1e3, "[]", "a CUSUM allowance (sigmas): not negative"),
    "stack.features.cusum_h_sigma": Range(0, 1e3, "(]", "a CUSUM alarm level (sigmas): positive"),
    "stack.features.cusum_k_m": Range(0, 1e5, "[]", "a CUSUM allowance (m): not negative"),
    "stack.features.model_q_m2_per_s": Range(0, 1e6, "(]", "a random-walk intensity (m^2/s): positive"),
    "stack.features.model_heading_walk_deg_per_sqrt_s": Range(0, 10, "[]", "a heading walk (deg/sqrt(s))"),
    "stack.features.model_scale_walk_per_sqrt_s": Range(0, 1, "[]", "a scale-factor walk (1/sqrt(s))"),
    "stack.features.model_heading_sigma_deg": Range(0, 180, "[]", "a heading sigma (deg): at most 180"),
    "stack.features.model_scale_sigma": Range(0, 1, "[]", "a DVL scale-factor sigma: a fraction"),
    "stack.features.model_gate_sigma": Range(0, math.inf, "(]", "a gate (sigmas): positive (inf: none)"),
    "stack.features.model_gate_cap": Range(0, 1e6, "[]", "a count of consecutive gated ranges"),
    "stack.features.model_hold_q_m2_per_s3": Range(0, 1e6, "[]", "a held-velocity walk (m^2/s^3): not negative"),
    "stack.features.model_hold_grace_s": Range(0, 86400, "[]", "a grace (s): 0 to a day"),
    "stack.features.model_deviation_sigma_deg": Range(0, 180, "[]", "a deviation sigma (deg): 0 (none) to 180"),
    "stack.features.model_deviation_link_gate": Range(0, math.inf, "[]", "a link gate (sigmas): 0 (none) or more"),
    "stack.features.model_turn_deg_per_sqrt_rad": Range(0, 180, "[]", "a heading walk per turn (deg/sqrt(rad))"),
    "stack.features.model_range_scale_sigma": Range(0, 0.1, "[]", "a range-scale sigma: a fraction, 0 (none) to 0.1"),
    "stack.features.stiff_q_m2_per_s": Range(0, 1e6, "(]", "a random-walk intensity (m^2/s): positive"),
    "stack.features.stiff_cap": Range(0, 1e6, "[]", "a count of consecutive ranges"),
    "stack.features.exclusion_gate_m": Range(0, math.inf, "(]", "a gate on a residual (m): positive (inf: none)"),
    "stack.features.exclusion_cap": Range(0, 1e6, "[]", "a count of consecutive ranges"),
    "stack.features.cusum_h_m": Range(0, 1e5, "(]", "a CUSUM alarm level (m): positive"),
    # the hybrid training database (replay.stack.injection)
    "stack.injection.copies": Range(0, 100, "[]", "copies of the training window (each a full replay of it)"),
    "stack.injection.outlier_share": Range(0, 1, "[]", "a share of range epochs: a fraction"),
    "stack.injection.stale_share": Range(0, 1, "[]", "a share of range epochs: a fraction"),
    "stack.injection.drift_share": Range(0, 1, "[]", "a share of range epochs: a fraction"),
    "stack.injection.dropout_share": Range(0, 1, "[]", "a share of range epochs: a fraction"),
    "stack.injection.outlier_min_m": Range(0, RANGE_MAX_M, "[]", "an outlier size (m): below a modem's reach"),
    "stack.injection.outlier_max_m": Range(0, RANGE_MAX_M, "[]", "an outlier size (m): below a modem's reach"),
    "stack.injection.stale_min_s": Range(0, DAY_S, "[]", "a stale segment (s): at most a day"),
    "stack.injection.stale_max_s": Range(0, DAY_S, "[]", "a stale segment (s): at most a day"),
    "stack.injection.drift_rate_mps": Range(0, 100, "[]", "a drift rate (m/s): not negative, below 100 m/s"),
    "stack.injection.drift_s": Range(0, DAY_S, "[]", "a drift duration (s): at most a day"),
    "stack.injection.seed": Range(0, SEED_MAX, "[]", "a random seed (numpy: [0, 2^32))"),
    # the engine (replay.engine.config); window_s is checked where it is read (two times, T0 < T1)
    "engine.rate": Range(0, 1e6, "[]", "a pace, times real time: 0 = as fast as possible"),
    "engine.lag_s": Range(0, DAY_S, "[]", "a look-ahead (s): the engine holds this much data"),
    "engine.max_gap_s": Range(0, WEEK_S, "[]", "a gap (s) interpolated across"),
    "engine.node_max_gap_s": Range(0, WEEK_S, "[]", "a gap (s) interpolated across"),
    "engine.usbl_group_s": Range(0, DAY_S, "(]", "a grouping interval (s): positive"),
    "engine.kmcdf_rho_m": Range(0, RANGE_MAX_M, "(]", "KMCDF's range scale (m): positive, below a modem's reach"),
    "engine.kmcdf_phase_noise_rad": Range(0, 2 * math.pi, "[]", "a phase noise (rad): within a turn"),
    "engine.usbl_update_sigma_m": Range(0, RANGE_MAX_M, "(]", "a fix sigma (m): positive"),
}

# pairs whose first must not exceed the second
ORDERED: tuple[tuple[str, str], ...] = (
    ("stack.injection.outlier_min_m", "stack.injection.outlier_max_m"),
    ("stack.injection.stale_min_s", "stack.injection.stale_max_s"),
)

# evaluate's command-line numbers
EVALUATE_MAX_SEEDS = 10_000                 # a trial each, minutes of CPU apiece: far beyond any study
EVALUATE_MAX_DURATION_S = DAY_S             # a simulated trial of at most a day (the sample trial: 1700 s)


def evaluate_max_workers() -> int:
    """The most LocalCluster workers `evaluate` starts: four per core (each one process of a whole replay)."""
    return 4 * (os.cpu_count() or 1)


def value_of(cfg: RunConfig, key: str) -> Any:
    """The value of a dotted key ("stack.anfis.epochs") of a configuration."""
    return functools.reduce(getattr, key.split("."), cfg)


def check_ranges(cfg: RunConfig) -> RunConfig:
    """`cfg` when every numeric parameter lies in its range (RANGES, ORDERED); else a one-line UserError."""
    for key, rng in RANGES.items():
        value = value_of(cfg, key)
        for v in value if isinstance(value, tuple) else (value,):
            if not rng.holds(v):
                raise UserError(f"configuration: {key} must be {rng.text()}, not {v!r} ({rng.why})")
    for lo_key, hi_key in ORDERED:
        lo, hi = value_of(cfg, lo_key), value_of(cfg, hi_key)
        if lo > hi:
            raise UserError(f"configuration {lo_key} = {lo!r} exceeds {hi_key} = {hi!r}")
    for key in ("stack.injection.drift_rate_mps", "stack.injection.drift_s"):
        pair = value_of(cfg, key)
        if len(pair) != 2 or pair[0] > pair[1]:
            raise UserError(f"configuration {key}: {list(pair)}: expected [low, high] with low <= high")
    return cfg


def numeric_keys(obj: Any = None, prefix: str = "") -> list[str]:
    """Every numeric parameter of a RunConfig (ints, floats and tuples of them), dotted: what RANGES must cover."""
    obj = RunConfig() if obj is None else obj
    keys: list[str] = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        name = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(value):
            keys += numeric_keys(value, f"{name}.")
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            keys.append(name)
        elif isinstance(value, tuple) and value and all(isinstance(v, (int, float)) for v in value):
            keys.append(name)
    return keys


__all__ = ["EVALUATE_MAX_DURATION_S", "EVALUATE_MAX_SEEDS", "RANGES", "Range", "SEED_MAX", "check_ranges",
           "evaluate_max_workers", "numeric_keys"]
