"""`auvreplay evaluate`: the JSON object's shape on short simulated trials, the train seed held out, the
figures against slow obvious counts, epoch kinds matched like a plain nearest search, the drift parameter."""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from replay import cli
from replay.errors import UserError
from replay.run import evaluate as ev
from replay.run.evaluate import (
    NO_KIND,
    TrialScores,
    TrialSpec,
    epoch_kinds,
    method_figures,
    split_seeds,
)
from replay.stack.methods import runnable_names
from samples.anomalies import KIND_CODES
from samples.scenario import ANOMALY_KINDS, Scenario, ScenarioError, scenario_to_toml
from samples.simulator import simulate_trial

# short trials: 700 s with t_a = 400 s keeps a scripted stale segment in training and natural anomalies after it
SHORT = ["--duration", "700", "--set", "training_window_s=400"]
FIGURES = {"auc", "fnr_at_fpr_1", "fnr_at_fpr_2", "fnr_at_fpr_5", "recall_by_kind", "error_p50_m", "error_p90_m"}


def _cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


@dataclass
class Spied:
    """What an `evaluate` run did: its JSON, the trials scored, the seeds trained on, each replay's training."""

    obj: dict[str, Any]
    scored: list[TrialSpec] = field(default_factory=list)
    trained_on: list[int] = field(default_factory=list)
    replays: list[tuple[int | None, str]] = field(default_factory=list)   # (rows given, training source note)


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory: pytest.TempPathFactory) -> Spied:
    """`evaluate --json` on seeds 1-2 (train seed 0) with one sweep rate, watched at every step.

    The scenario moves the sample trial's drift (70 s, 25 m) inside the short trial's scored part.
    """
    base = Scenario()
    events = tuple(replace(e, start_s=480.0, end_s=550.0) if e.kind == "drift" else e
                   for e in base.anomalies if e.end_s < 700.0 or e.kind == "drift")
    path = tmp_path_factory.mktemp("evaluate") / "scenario.toml"
    path.write_text(scenario_to_toml(replace(base, anomalies=events)))
    spied = Spied({})
    real_trial, real_set, real_replay = ev.evaluate_trial, ev.training_set_of, ev.replay_archive

    def trial(spec: TrialSpec, config: Any, given: Any = None, reuse: Any = None) -> TrialScores:
        spied.scored.append(spec)
        return real_trial(spec, config, given, reuse)

    def training(spec: TrialSpec, config: Any) -> Any:
        spied.trained_on.append(spec.seed)
        return real_set(spec, config)

    def replay(*args: Any, **kwargs: Any) -> Any:
        outcome = real_replay(*args, **kwargs)
        given = kwargs.get("training_set")
        spied.replays.append((None if given is None else len(given),
                              outcome.results["follower"].training_notes["source"]))
        return outcome

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ev, "evaluate_trial", trial)
        mp.setattr(ev, "training_set_of", training)
        mp.setattr(ev, "replay_archive", replay)
        code, out, _ = _cli(["evaluate", "--seeds", "1-2", "--train-seed", "0", "--drift-rate", "0.5",
                             "--scenario", str(path), "--workers", "1", "--json", *SHORT])
    assert code == 0
    spied.obj = json.loads(out)
    return spied


def test_json_has_the_documented_shape(evaluated: Spied) -> None:
    obj = evaluated.obj
    assert set(obj) == {"seeds", "train_seed", "methods", "drift_sweep"}
    assert obj["seeds"] == [1, 2] and obj["train_seed"] == 0
    # every method (evaluate judges the new detectors too), in its order, with every figure
    assert list(obj["methods"]) == list(runnable_names())
    for name, fig in obj["methods"].items():
        assert set(fig) == FIGURES, name
        assert set(fig["recall_by_kind"]) == set(ANOMALY_KINDS)
        assert fig["recall_by_kind"]["dropout"] is None          # a dropout leaves no epoch to flag
        assert 0 < fig["error_p50_m"] <= fig["error_p90_m"]
    detecting = [m for m, f in obj["methods"].items() if f["auc"] is not None]
    assert "chi_square" in detecting and "ackf" not in detecting
    for m in detecting:
        f = obj["methods"][m]
        assert 0.5 < f["auc"] <= 1.0
        # FNR can only fall as the allowed FPR grows
        assert 0 <= f["fnr_at_fpr_5"] <= f["fnr_at_fpr_2"] <= f["fnr_at_fpr_1"] <= 1
        assert f["recall_by_kind"]["outlier"] is not None      # outliers are drawn at 2 % of leader 1's epochs
        assert f["recall_by_kind"]["drift"] is not None
    sweep = obj["drift_sweep"]
    assert [r["method"] for r in sweep] == detecting
    for r in sweep:
        assert set(r) == {"rate_mps", "method", "recall", "epochs"}
        assert r["rate_mps"] == 0.5
        # 35 m over 70 s on leader 1 (pinged every 4.8 s) in two trials: most of its epochs past 9 m
        assert r["epochs"] == sweep[0]["epochs"] >= 10 and 0 <= r["recall"] <= 1


def test_trained_on_the_train_seed_and_scored_on_the_others(evaluated: Spied) -> None:
    assert 0 not in evaluated.obj["seeds"]
    assert evaluated.trained_on == [0]
    assert [(s.seed, s.drift_rate_mps) for s in evaluated.scored] == [(1, None), (2, None), (1, 0.5), (2, 0.5)]
    # the train seed's run trains on its own window; every scored run on exactly the set it handed over
    (first_given, first_note), *tests = evaluated.replays
    assert first_given is None and first_note.startswith("own window")
    rows = {given for given, _ in tests}
    assert len(tests) == 4 and len(rows) == 1 and rows != {None}
    assert all(note == f"given: {next(iter(rows))} rows" for _, note in tests)
    assert split_seeds([5, 6, 7], None) == (5, [6, 7])
    assert split_seeds([5, 6, 7], 6) == (6, [5, 7])
    with pytest.raises(UserError):
        split_seeds([4], 4)


def test_dask_gives_the_serial_figures() -> None:
    """A two-worker LocalCluster prints the figures the in-process loop gives, and its wall time."""
    args = ["evaluate", "--seeds", "3-4", "--train-seed", "9", "--drift-rate", "none", "--training", "own",
            "--set", "methods=ackf,chi_square", *SHORT]
    code1, serial, _ = _cli([*args, "--workers", "1", "--json"])
    code2, text, _ = _cli([*args, "--workers", "2"])
    assert code1 == code2 == 0
    obj = json.loads(serial)
    assert obj["drift_sweep"] == [] and list(obj["methods"]) == ["ackf", "chi_square"]
    chi = obj["methods"]["chi_square"]
    row = next(line.split() for line in text.splitlines() if line.startswith("chi_square"))
    assert row[1:5] == [f"{chi[k]:.3f}" for k in ("auc", "fnr_at_fpr_1", "fnr_at_fpr_2", "fnr_at_fpr_5")]
    assert row[-2:] == [f"{chi['error_p50_m']:.3f}", f"{chi['error_p90_m']:.3f}"]
    assert "train seed 9, never scored; test seeds 3,4" in text and "own window" in text
    assert " s wall (Dask, 2 workers; " in text


def test_bad_arguments_are_one_line_errors() -> None:
    for argv in (["--seeds", "x"], ["--seeds", "1", "--train-seed", "1"], ["--seeds", "1-2", "--drift-rate", "a"],
                 ["--seeds", "1-2", "--drift-rate", "-0.1"], ["--seeds", "1-2", "--duration", "0"],
                 ["--seeds", "1-2", "--scenario", "/nonexistent/scenario.toml"]):
        code, _, err = _cli(["evaluate", "--workers", "1", *argv])
        assert code == 1 and err.count("\n") == 1 and "Traceback" not in err, argv


def test_a_trial_whose_record_refused_records_is_not_scored() -> None:
    """A simulator bug that makes `record` refuse records (a negative heading std once took every follower INS
    record out) stops `evaluate` with one line naming the count, before any replay."""
    refused = {}

    def broken(scenario: Scenario, seed: int) -> Any:
        trial = simulate_trial(scenario, seed)
        vehicles = tuple(replace(v, ins=replace(v.ins, heading_std_deg=-1.0)) if v.role == "follower" else v
                         for v in trial.vehicles)
        refused[seed] = sum(len(v.ins.t_s) for v in vehicles if v.role == "follower")
        return replace(trial, vehicles=vehicles)

    def replay(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("a trial with refused records was replayed")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ev, "simulate_trial", broken)
        mp.setattr(ev, "replay_archive", replay)
        code, out, err = _cli(["evaluate", "--seeds", "1-2", "--train-seed", "0", "--workers", "1",
                               "--duration", "60", "--set", "training_window_s=30"])
    assert code == 1 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert f"seed 0: record refused {refused[0]} simulated records" in err and refused[0] > 50
    assert "not scored" in err


def _slow_recall(flagged: np.ndarray, labels: np.ndarray, kinds: np.ndarray, kind: str) -> float | None:
    """Recall of one kind by walking the epochs one at a time."""
    if kind == "dropout":
        return None
    hit = total = 0
    for f, lab, k in zip(flagged, labels, kinds):
        if lab == 1 and k == KIND_CODES[kind]:
            total += 1
            hit += bool(f)
    return hit / total if total else None


def _trial(flagged: np.ndarray, labels: np.ndarray, kinds: np.ndarray, scores: np.ndarray) -> TrialScores:
    m = "det"
    return TrialScores(TrialSpec(0), (m, "plain"), (m,), {m: flagged, "plain": np.zeros_like(flagged)},
                       {m: labels, "plain": labels}, {m: kinds, "plain": kinds}, {m: labels}, {m: scores},
                       {m: np.abs(scores), "plain": np.arange(3.0)})


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.sampled_from([0, 1]), st.sampled_from([NO_KIND, 0, 1, 2, 3]),
                          st.floats(-5, 5)), min_size=1, max_size=60), st.integers(1, 3))
def test_recall_by_kind_is_the_obvious_count(rows: list[tuple[bool, int, int, float]], parts: int) -> None:
    flagged = np.array([r[0] for r in rows], bool)
    labels = np.array([r[1] for r in rows], np.int8)
    kinds = np.array([r[2] for r in rows], np.int16)
    scores = np.array([r[3] for r in rows], float)
    # the same epochs split over several trials pool to the same figures
    cuts = np.array_split(np.arange(len(rows)), parts)
    trials = [_trial(flagged[c], labels[c], kinds[c], scores[c]) for c in cuts]
    fig = method_figures(trials, "det")
    for kind in ANOMALY_KINDS:
        assert fig["recall_by_kind"][kind] == _slow_recall(flagged, labels, kinds, kind)
    plain = method_figures(trials, "plain")
    assert plain["auc"] is None and set(plain["recall_by_kind"].values()) == {None}
    assert plain["error_p50_m"] == 1.0    # pooled 0, 1, 2 from each trial


def test_auc_and_fnr_on_separable_and_tied_scores() -> None:
    labels = np.array([0] * 100 + [1] * 10, np.int8)
    kinds = np.zeros(110, np.int16)
    flagged = np.zeros(110, bool)
    separable = method_figures([_trial(flagged, labels, kinds, np.r_[np.zeros(100), np.ones(10)])], "det")
    assert separable["auc"] == 1.0 and separable["fnr_at_fpr_1"] == 0.0
    # 3 negatives score above every positive: FPR 3 % before any positive is caught
    s = np.r_[np.zeros(97), np.full(3, 2.0), np.ones(10)]
    fig = method_figures([_trial(flagged, labels, kinds, s)], "det")
    assert fig["fnr_at_fpr_1"] == fig["fnr_at_fpr_2"] == 1.0 and fig["fnr_at_fpr_5"] == 0.0
    assert fig["auc"] == pytest.approx(0.97)


def _slow_kinds(sf: np.ndarray, sl: np.ndarray, stt: np.ndarray, sk: np.ndarray, f: np.ndarray, ld: np.ndarray,
                t: np.ndarray, tol: float) -> list[int]:
    out = []
    for fi, li, ti in zip(f, ld, t):
        best, code = np.inf, NO_KIND
        for a, b, c, k in zip(sf, sl, stt, sk):
            # the first of equally near epochs, like the fast path's left neighbour
            if a == fi and b == li and abs(c - ti) < best - 1e-12:
                best, code = abs(c - ti), k
        out.append(int(code) if best <= tol else NO_KIND)
    return out


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["f1", "f2"]), st.sampled_from(["l1", "l2"]),
                          st.integers(0, 400).map(lambda x: x * 0.25), st.sampled_from([0, 1, 2, 3])),
                min_size=0, max_size=30, unique_by=lambda r: (r[0], r[1], r[2])),
       st.lists(st.tuples(st.sampled_from(["f1", "f2"]), st.sampled_from(["l1", "l2", "l3"]),
                          st.floats(-2, 102)), min_size=0, max_size=30))
def test_epoch_kinds_is_the_nearest_epoch_of_the_link(sim: list[tuple[str, str, float, int]],
                                                       replayed: list[tuple[str, str, float]]) -> None:
    sf, sl, stt, sk = (np.array([r[i] for r in sim], dtype=object if i < 2 else float) for i in range(4))
    sk = sk.astype(np.int8)
    f, ld, t = (np.array([r[i] for r in replayed], dtype=object if i < 2 else float) for i in range(3))
    fast = epoch_kinds(sf, sl, stt, sk, f, ld, t, tolerance_s=0.5)
    assert fast.tolist() == _slow_kinds(sf, sl, stt, sk, f, ld, t, 0.5)


def test_drift_rate_is_the_simulated_slope() -> None:
    base = Scenario()
    assert [e.magnitude_m for e in base.anomalies if e.kind == "drift"] == [25.0]      # the default is unchanged
    assert base.anomalies[1].drift_rate_mps == pytest.approx(25.0 / 70.0)
    short = replace(base, trial=replace(base.trial, duration_s=1200.0))
    slow, fast = (simulate_trial(short.with_drift_rate(rate), 7).ranges for rate in (0.2, 0.6))
    drift = slow.injected == KIND_CODES["drift"]
    assert drift.sum() >= 10
    ev_ = next(e for e in base.anomalies if e.kind == "drift")
    # the same noise draws: drift epochs differ by the extra slope times the time into the drift, the rest
    # not at all (but a stale segment may repeat a drifted range)
    np.testing.assert_allclose(fast.range_m[drift] - slow.range_m[drift], 0.4 * (slow.t_s[drift] - ev_.start_s),
                               atol=1e-9)
    other = ~drift & (slow.injected != KIND_CODES["stale"])
    np.testing.assert_array_equal(fast.range_m[other], slow.range_m[other])
    with pytest.raises(ScenarioError):
        base.with_drift_rate(-0.1)
