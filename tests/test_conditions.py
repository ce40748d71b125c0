"""The simulator's conditions (samples/conditions.py): off by default, each one's effect on the arrays and logs."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from samples.anomalies import KIND_CODES
from samples.conditions import realized
from samples.scenario import Conditions, Scenario, ScenarioError, load_scenario, scenario_from_dict, scenario_to_toml
from samples.simulator import SimulatedTrial, simulate_trial

SHORT = 500.0


def _trial(seed: int = 3, **conditions: object) -> SimulatedTrial:
    base = Scenario().with_options(duration_s=SHORT)
    return simulate_trial(replace(base, conditions=Conditions(**conditions)), seed)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def plain() -> SimulatedTrial:
    return _trial()


def _clean(trial: SimulatedTrial) -> np.ndarray:
    """Epochs with no injected anomaly."""
    return trial.ranges.injected == 0


def test_the_default_scenario_writes_no_conditions_and_reads_back_what_it_wrote(tmp_path: Path) -> None:
    text = scenario_to_toml(Scenario())
    assert "[conditions]" not in text and "follower_dive_s" not in text
    set_ = replace(Scenario(), conditions=Conditions(sound_speed_bias=0.005, multipath_per_hour=6.0,
                                                     anomalies_drawn=True))
    path = tmp_path / "s.toml"
    path.write_text(scenario_to_toml(set_))
    assert "[conditions]" in path.read_text() and "dvl_lock_loss_per_hour" not in path.read_text()
    assert load_scenario(path) == set_


@pytest.mark.parametrize("table", [{"range_noise_dof": 1.5}, {"sound_speed_bias": 0.5}, {"multipath_per_hour": -1.0},
                                   {"dvl_lock_loss_min_s": 90.0}])
def test_nonsense_conditions_are_refused(table: dict[str, float]) -> None:
    with pytest.raises(ScenarioError, match="conditions"):
        scenario_from_dict({"conditions": table})


def test_sound_speed_bias_scales_every_range(plain: SimulatedTrial) -> None:
    biased = _trial(sound_speed_bias=0.008)
    ok = _clean(plain) & _clean(biased)
    r0, r1 = plain.ranges, biased.ranges
    np.testing.assert_allclose(r1.range_m[ok] - r0.range_m[ok], 0.008 * r0.range_true_m[ok], rtol=1e-9)


def test_owtt_clock_offset_and_drift_add_a_line_in_time_per_link(plain: SimulatedTrial) -> None:
    clocked = _trial(owtt_clock_offset_s=1e-3, owtt_clock_drift_ppm=1.0)
    r0, r1 = plain.ranges, clocked.ranges
    slopes = []
    for leader in ("leader1", "leader2"):
        ok = _clean(plain) & _clean(clocked) & (r0.leader == leader)
        diff = r1.range_m[ok] - r0.range_m[ok]
        slope, offset = np.polyfit(r0.t_s[ok], diff, 1)
        np.testing.assert_allclose(diff, offset + slope * r0.t_s[ok], atol=1e-6)
        assert abs(offset) <= 1e-3 * 1450.0 and abs(slope) <= 1e-6 * 1450.0
        slopes.append(slope)
    assert slopes[0] != slopes[1]


def test_multipath_is_a_positive_bias_held_for_a_time_and_labelled_as_its_kind() -> None:
    trial = _trial(multipath_per_hour=12.0, multipath_min_m=15.0, multipath_max_m=20.0)
    segs = [iv for iv in trial.intervals if iv.kind == "multipath"]
    assert len(segs) == 2 * int(SHORT // 300.0) and all(iv.origin == "condition" for iv in segs)
    r = trial.ranges
    hit = r.injected == KIND_CODES["multipath"]
    assert hit.sum() > 10
    bias = r.range_m[hit] - r.range_true_m[hit]
    assert np.median(bias) > 14.0 and np.all(bias > 15.0 - 5 * 3.0)
    for iv in segs:
        inside = (r.t_s >= iv.start_s) & (r.t_s <= iv.end_s) & (r.leader == iv.leader) & (r.injected != 1)
        assert np.all(r.injected[inside] == KIND_CODES["multipath"])


def test_heavy_tailed_noise_grows_with_range(plain: SimulatedTrial) -> None:
    tailed = _trial(range_noise_dof=3.0, range_noise_per_km_m=4.0)
    ok = _clean(tailed)
    err = tailed.ranges.range_m[ok] - tailed.ranges.range_true_m[ok]
    base = plain.ranges.range_m[_clean(plain)] - plain.ranges.range_true_m[_clean(plain)]
    # a Student-t of 3 dof: far more beyond 4 sigma than a Gaussian's 6e-5
    sigma = 3.0 + 4.0 * tailed.ranges.range_true_m[ok] / 1000.0
    assert np.mean(np.abs(err) > 4.0 * sigma) > 0.005
    assert np.mean(np.abs(base) > 4.0 * 3.0) < 0.002
    # the noise (its MAD) is larger at long range
    far = tailed.ranges.range_true_m[ok] > np.median(tailed.ranges.range_true_m[ok])
    assert np.median(np.abs(err[far])) > np.median(np.abs(err[~far]))


def test_bottom_lock_loss_leaves_invalid_pings_that_the_recorder_archives_as_invalid(tmp_path: Path) -> None:
    from formats.mcap_reader import ArchiveReader
    from recorders.manifest import load_manifest
    from recorders.record import record
    from samples.writer import write_trial

    trial = _trial(dvl_lock_loss_per_hour=10.0, dvl_lock_loss_min_s=20.0, dvl_lock_loss_max_s=30.0)
    d = trial.vehicle("follower").dvl
    lost = ~d.valid
    assert 20 <= lost.sum() <= 31 and np.all(np.isnan(d.forward_mps[lost])) and np.all(np.isnan(d.beam_range_m[lost]))
    assert np.all(np.isfinite(d.forward_mps[d.valid]))
    write_trial(trial, tmp_path / "trial")
    out = tmp_path / "trial.mcap"
    record(load_manifest(tmp_path / "trial" / "trial.toml"), out)
    with ArchiveReader(out) as reader:
        topic = next(t for t in reader.summary().topics if t.endswith("follower/dvl"))
        msgs = [(m.log_time_ns, m.message) for m in reader.messages([topic])]
    assert len(msgs) == len(d.t_s)
    archived = np.array([not m.valid for _, m in msgs])
    np.testing.assert_array_equal(archived, lost)
    assert all(math.isnan(m.velocity_x_mps) for _, m in msgs if not m.valid)


def test_compass_deviation_follows_the_heading(plain: SimulatedTrial) -> None:
    deviated = _trial(compass_deviation_deg=3.0)
    f0, f1 = plain.vehicle("follower").ins, deviated.vehicle("follower").ins
    diff = (f1.heading_deg - f0.heading_deg + 180.0) % 360.0 - 180.0
    h = np.radians(np.interp(f0.t_s, plain.vehicle("follower").track.t_s, plain.vehicle("follower").track.heading_deg))
    # a one-cycle term of 3 deg and a two-cycle one of 1.5 deg: least squares on sin/cos of h and 2h
    basis = np.stack([np.sin(h), np.cos(h), np.sin(2 * h), np.cos(2 * h)], axis=1)
    coef, *_ = np.linalg.lstsq(basis, diff, rcond=None)
    np.testing.assert_allclose(basis @ coef, diff, atol=0.05)
    assert math.hypot(*coef[:2]) == pytest.approx(3.0, rel=0.02)
    assert math.hypot(*coef[2:]) == pytest.approx(1.5, rel=0.02)
    # the leaders' high-grade heading has none
    np.testing.assert_array_equal(deviated.vehicle("leader1").ins.heading_deg, plain.vehicle("leader1").ins.heading_deg)


def test_drawn_anomalies_and_sensor_parameters_differ_per_seed_and_are_written_back() -> None:
    base = replace(Scenario(), conditions=Conditions(anomalies_drawn=True, sensor_spread=0.4))
    a, b = realized(base, 1, ["leader1", "leader2"]), realized(base, 2, ["leader1", "leader2"])
    assert a != b and realized(base, 1, ["leader1", "leader2"]) == a
    assert not a.conditions.anomalies_drawn and a.conditions.sensor_spread == 0.0
    t_a = base.trial.training_window_s
    for old, new in zip(base.anomalies, a.anomalies):
        assert (new.kind, new.magnitude_m) == (old.kind, old.magnitude_m)
        assert new.end_s - new.start_s == pytest.approx(old.end_s - old.start_s, abs=0.11)
        assert (new.start_s < t_a) == (old.start_s < t_a) and new.end_s <= base.trial.duration_s
    starts = {ev.start_s for s in (a, b) for ev in s.anomalies}
    assert len(starts) == 2 * len(base.anomalies)
    specs = [(s.ins.follower_heading_bias_deg, s.ins.follower_heading_walk_deg_per_sqrt_s, s.dvl.sigma_mps,
              s.ranging.range_sigma_m) for s in (a, b)]
    assert specs[0] != specs[1] and all(v != d for v, d in zip(specs[0][1:], (0.03, base.dvl.sigma_mps, 3.0)))
    # the trial records its realized scenario: reading it back and simulating again gives the same ranges
    trial = simulate_trial(base.with_options(duration_s=SHORT), 5)
    again = simulate_trial(scenario_from_dict(__import__("tomllib").loads(scenario_to_toml(trial.scenario))), 5)
    np.testing.assert_array_equal(trial.ranges.range_m, again.ranges.range_m)


def test_drawn_sensor_parameters_never_make_the_recorder_refuse_a_follower_ins_record(tmp_path: Path) -> None:
    from recorders.manifest import load_manifest
    from recorders.record import record
    from samples.writer import write_trial

    base = replace(Scenario().with_options(duration_s=60.0), conditions=Conditions(sensor_spread=0.4))
    leaders = ["leader1", "leader2"]
    biases = {seed: realized(base, seed, leaders).ins.follower_heading_bias_deg for seed in range(40)}
    negative = [seed for seed, b in biases.items() if b < 0]
    assert 10 <= len(negative) <= 30  # the bias's sign is drawn: about half of the seeds
    for seed in range(12):
        ins = simulate_trial(base, seed).vehicle("follower").ins
        # the unit reports the size of its error: positive whatever the drawn bias's sign
        assert ins.heading_std_deg == pytest.approx(abs(biases[seed])) and ins.heading_std_deg > 0
    for seed in negative[:3]:
        trial = simulate_trial(base, seed)
        write_trial(trial, tmp_path / str(seed))
        summary = record(load_manifest(tmp_path / str(seed) / "trial.toml"), tmp_path / f"{seed}.mcap", workers=1)
        assert [(f.skipped, f.out_of_range) for f in summary.files] == [(0, 0)] * len(summary.files)
        assert sum(f.messages for f in summary.files if (f.vehicle, f.sensor) == ("follower", "ins")) == \
            len(trial.vehicle("follower").ins.t_s)
