"""Every configuration value range-checked against one table: one line for a bad value, never a traceback or a hang."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay.cli import main
from replay.engine.config import RunConfig
from replay.errors import UserError
from replay.run.batch import parse_seeds
from replay.run.config import config_from_parameters, load_config, to_dict
from replay.run.config_ranges import RANGES, SEED_MAX, Range, check_ranges, numeric_keys, value_of


def _one_line(err: str, *words: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def test_the_table_covers_every_numeric_parameter_and_holds_every_default():
    keys = numeric_keys()
    assert len(keys) > 60
    assert sorted(set(keys) - set(RANGES)) == []
    assert sorted(set(RANGES) - set(keys)) == []
    cfg = RunConfig()
    assert check_ranges(cfg) is cfg
    for key, rng in RANGES.items():
        value = value_of(cfg, key)
        assert all(rng.holds(v) for v in (value if isinstance(value, tuple) else (value,))), key
        assert rng.bounds in ("[]", "(]", "[)", "()") and rng.lo < rng.hi and rng.why


def test_range_ends():
    r = Range(0, 1, "()", "p")
    assert [r.holds(v) for v in (0, 1e-12, 0.5, 1 - 1e-12, 1, math.nan, -math.inf)] == [
        False, True, True, True, False, False, False]
    gate = Range(0, math.inf, "(]", "gate")
    assert gate.holds(math.inf) and not gate.holds(0) and not gate.holds(math.nan)
    assert not Range(0, 10, "[]", "n").holds(True)  # a bool is not a number here


# the cases of issue 29, and the ones around them
@pytest.mark.parametrize("setting, key", [
    ("r_m=NaN", "stack.r_m"), ("r_m=0", "stack.r_m"), ("r_m=-3", "stack.r_m"), ("r_m=Infinity", "stack.r_m"),
    ("chi_square_alpha=2", "stack.chi_square_alpha"), ("chi_square_alpha=0", "stack.chi_square_alpha"),
    ("anfis.mfs_per_input=1000", "stack.anfis.mfs_per_input"), ("anfis.mfs_per_input=0", "stack.anfis.mfs_per_input"),
    ("training_window_s=NaN", "stack.training_window_s"), ("training_window_s=-1", "stack.training_window_s"),
    ("kmcdf_rho_m=-30", "engine.kmcdf_rho_m"), ("kmcdf_rho_m=0", "engine.kmcdf_rho_m"),
    ("seed=-1", "stack.seed"), ("anfis.seed=4294967296", "stack.anfis.seed"), ("injection.seed=-5", "stack.injection.seed"),
    ("p0_m=1,-1", "stack.p0_m"), ("q_m_per_s=0,1", "stack.q_m_per_s"), ("t1_m=0", "stack.t1_m"),
    ("detection_fpr_target=1", "stack.detection_fpr_target"), ("anfis.particles=0", "stack.anfis.particles"),
    ("anfis.iterations=10000000", "stack.anfis.iterations"), ("anfis.epochs=-1", "stack.anfis.epochs"),
    ("anfis.step_decrease=2", "stack.anfis.step_decrease"), ("anfis.initial_step=0", "stack.anfis.initial_step"),
    ("features.usbl_blend=1.5", "stack.features.usbl_blend"), ("features.scale_floor_m=0", "stack.features.scale_floor_m"),
    ("features.median_window_s=NaN", "stack.features.median_window_s"),
    ("features.exclusion_gate_m=0", "stack.features.exclusion_gate_m"),
    ("injection.copies=1000", "stack.injection.copies"), ("injection.outlier_share=1.2", "stack.injection.outlier_share"),
    ("injection.drift_rate_mps=0.1,NaN", "stack.injection.drift_rate_mps"),
    ("dual_threshold_hidden=0", "stack.dual_threshold_hidden"), ("lag_s=-1", "engine.lag_s"),
    ("usbl_group_s=0", "engine.usbl_group_s"), ("max_gap_s=NaN", "engine.max_gap_s"),
])
def test_replay_set_out_of_range_is_one_line(tmp_path, capsys, setting, key):
    out = tmp_path / "r.mcap"
    assert main(["replay", str(tmp_path / "no-archive.mcap"), "--set", setting, "-o", str(out)]) == 1
    line = _one_line(capsys.readouterr().err, "auvreplay replay: error: configuration", key)
    assert ("must be" in line or "not a valid" in line) and not out.exists()


@pytest.mark.parametrize("setting, words", [
    ("injection.outlier_min_m=50", "exceeds stack.injection.outlier_max_m"),
    ("injection.drift_s=90,40", "low <= high"),
])
def test_ordered_pairs(setting, words):
    with pytest.raises(UserError, match=words):
        load_config(None, [setting])


def test_a_toml_file_is_checked_too(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("r_m = 2.5\n[stack.anfis]\nmfs_per_input = 1000\n")
    with pytest.raises(UserError, match="stack.anfis.mfs_per_input must be in"):
        load_config(path)
    path.write_text("r_m = 2.5\nkmcdf_rho_m = 25.0\n[stack.anfis]\nmfs_per_input = 3\n")
    cfg = load_config(path)
    assert (cfg.stack.r_m, cfg.engine.kmcdf_rho_m, cfg.stack.anfis.mfs_per_input) == (2.5, 25.0, 3)


def test_stored_parameters_are_checked():
    params = to_dict(RunConfig())
    assert config_from_parameters(params) == RunConfig()
    params["stack"]["r_m"] = -1
    with pytest.raises(UserError, match="stack.r_m must be positive"):
        config_from_parameters(params)
    with pytest.raises(UserError, match="expected a table"):
        config_from_parameters([])  # type: ignore[arg-type]


def test_the_values_the_docs_tests_and_samples_use_are_accepted():
    cfg = load_config(None, ["r_m=2.5", "anfis.epochs=10", "window_s=600,1700", "training_window_s=12",
                             "anfis.epochs=4", "usbl_update=kmcdf2", "anfis.model=shared", "features.exclusion_gate_m=Infinity",
                             "features.lag_s=0", "injection.copies=0", "anfis.mfs_per_input=1", "seed=4294967295"])
    assert cfg.stack.r_m == 2.5 and cfg.stack.seed == SEED_MAX and math.isinf(cfg.stack.features.exclusion_gate_m)


def _scalar_keys() -> list[str]:
    return [k for k in RANGES if not isinstance(value_of(RunConfig(), k), tuple)]


@settings(max_examples=300, deadline=None)
@given(key=st.sampled_from(_scalar_keys()),
       value=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-2**70, 2**70),
                       st.sampled_from(["NaN", "-Infinity", "1e400", "x", "", "[1]", "true"])))
def test_any_value_is_accepted_in_range_or_refused_in_one_line(key, value):
    text = value if isinstance(value, str) else repr(value) if isinstance(value, int) else (
        "NaN" if math.isnan(value) else "Infinity" if value == math.inf else "-Infinity" if value == -math.inf
        else repr(value))
    try:
        cfg = load_config(None, [f"{key}={text}"])
    except UserError as exc:
        assert "\n" not in str(exc) and key.split(".")[-1] in str(exc)
        return
    got = value_of(cfg, key)
    assert RANGES[key].holds(got)
    default = value_of(RunConfig(), key)
    assert type(got) is type(default)


def test_numeric_keys_follow_the_dataclasses():
    fields = {f.name for f in dataclasses.fields(RunConfig().stack.anfis)}
    assert {k.rsplit(".", 1)[1] for k in numeric_keys() if k.startswith("stack.anfis.")} == fields - {
        "rule_structure", "model", "threshold_rule"}


@pytest.mark.parametrize("argv, words", [
    (["--seeds", "0-99999999"], "more than 10000 seeds"),
    (["--seeds", "0-3", "--train-seed=-1"], "--train-seed -1"),
    (["--seeds", "0-3", "--train-seed", "4294967296"], "--train-seed 4294967296"),
    (["--seeds", "0-3", "--duration", "1e12"], "--duration 1e+12"),
    (["--seeds", "0-3", "--duration", "nan"], "--duration nan"),
    (["--seeds", "0-3", "--duration", "0"], "--duration 0"),
    (["--seeds", "0-3", "--workers", "100000"], "--workers 100000"),
    (["--seeds", "0-3", "--workers", "0"], "--workers 0"),
    (["--seeds", "0-3", "--set", "training_window_s=NaN"], "stack.training_window_s"),
    (["--seeds", "0-3", "--set", "kmcdf_rho_m=-30"], "engine.kmcdf_rho_m"),
    (["--seeds", "4294967296"], "beyond 4294967295"),
    (["--seeds", "x"], "--seeds 'x'"),
])
def test_evaluate_numbers_are_one_line(capsys, argv, words):
    assert main(["evaluate", *argv]) == 1
    _one_line(capsys.readouterr().err, "auvreplay evaluate: error:", words)


def test_seed_count_is_checked_before_the_list_is_built():
    with pytest.raises(UserError, match="more than 10000"):
        parse_seeds("0-4294967295")  # would be 32 GiB as a list
    assert parse_seeds("0-3,10", max_count=5) == [0, 1, 2, 3, 10]
    with pytest.raises(UserError, match="more than 4 seeds"):
        parse_seeds("0-3,10", max_count=4)
