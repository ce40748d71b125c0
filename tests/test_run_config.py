"""Replay configuration: defaults, TOML, overrides, run ids; position tracks."""

from __future__ import annotations

import functools
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from replay.engine.tracks import Fix, Track
from replay.errors import UserError
from replay.run.config import load_config, run_id
from replay.stack.config import CHOICES


def test_defaults_are_stack_md():
    c = load_config()
    assert c.stack.r_m == 3.0 and c.stack.t1_m == 9.0 and c.stack.training_window_s == 600.0
    assert c.stack.anfis.mfs_per_input == 2 and c.stack.anfis.epochs == 100
    assert c.engine.window_s is None and c.engine.rate == 0.0


def test_toml_then_overrides(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text('r_m = 2.0\nmethods = ["ckf", "anfis"]\n[anfis]\nepochs = 40\n[engine]\nlag_s = 2.0\n')
    c = load_config(path, ["anfis.epochs=10", "window_s=600,1700"], rate=4.0)
    assert c.stack.r_m == 2.0 and c.stack.methods == ("ckf", "anfis")
    assert c.stack.anfis.epochs == 10 and c.engine.lag_s == 2.0
    assert c.engine.window_s == (600.0, 1700.0) and c.engine.rate == 4.0


@pytest.mark.parametrize("window, rate, words", [
    ((5.0, 1.0), None, "expected two finite times T0 < T1"), ((0.0, float("inf")), None, "T0 < T1"),
    (None, -1.0, "rate -1.0: expected >= 0"), (None, float("nan"), "expected >= 0"),
])
def test_bad_window_or_rate(window, rate, words):
    with pytest.raises(UserError, match=words):
        load_config(None, [], window, rate)


@pytest.mark.parametrize("item, words", [
    ("nokey=1", "unknown key 'stack.nokey'"), ("anfis.epochs=x", "not a valid int"),
    ("r_m", "expected key=value"), ("methods=ckf,bogus", "unknown bogus"),
    ("usbl_update=kmcdf9", "engine.usbl_update: unknown 'kmcdf9'"),
    ("usbl_update_sigma_m=0", "must be > 0"),
])
def test_bad_overrides(item, words):
    extra = ["usbl_update=kmcdf2"] if item.startswith("usbl_update_sigma") else []
    with pytest.raises(UserError, match=words):
        load_config(None, extra + [item])


def test_run_id_changes_with_any_parameter_input_or_version():
    base = run_id(load_config(), "sha", "1")
    assert base == run_id(load_config(), "sha", "1")
    assert base != run_id(load_config(None, ["r_m=3.1"]), "sha", "1")
    assert base != run_id(load_config(), "sha2", "1")
    assert base != run_id(load_config(), "sha", "2")


def test_track_interpolates_inside_gaps_only():
    tr = Track(keep_s=10)
    for t in range(5):
        tr.add(Fix(float(t), 0.1 * t, 0.2 * t, float(t)))
    f = tr.at(2.5, max_gap_s=2)
    assert math.isclose(f.lat_rad, 0.25) and math.isclose(f.lon_rad, 0.5) and f.depth_m == 2.5
    assert tr.at(4.9, 2).t_s == 4.0 and tr.at(5.5, 2) is None
    tr.add(Fix(20.0, 2.0, 4.0))
    assert tr.at(10.0, 3) is None          # the gap 4 -> 20 is too long
    assert tr.at(1.0, 3) is None           # older than keep_s: pruned


@given(st.lists(st.floats(0, 1e5, allow_nan=False), min_size=1, max_size=30), st.floats(-1e3, 2e5))
def test_track_interpolation_stays_between_neighbours(times, t):
    tr = Track(keep_s=1e9)
    for x in sorted(set(times)):
        tr.add(Fix(x, x * 1e-6, -x * 1e-6))
    f = tr.at(t, max_gap_s=1e9)
    if f is not None:
        assert min(times) * 1e-6 - 1e-9 <= f.lat_rad <= max(times) * 1e-6 + 1e-9


@pytest.mark.parametrize("key", sorted(CHOICES))
def test_a_parameter_with_fixed_values_refuses_another(key):
    """Every default is one of its key's values; a misspelt one is a one-line UserError naming the values."""
    allowed = CHOICES[key]
    assert functools.reduce(getattr, key.split("."), load_config()) in allowed
    for value in allowed:
        assert functools.reduce(getattr, key.split("."), load_config(overrides=[f"{key}={value}"])) == value
    with pytest.raises(UserError, match=f"{key}: unknown 'modle' \\(known: {', '.join(allowed)}\\)"):
        load_config(overrides=[f"{key}=modle"])
