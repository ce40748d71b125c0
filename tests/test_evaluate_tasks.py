"""`evaluate`'s trial tasks: prepared then scored, the given training reused, on Dask as in-process: same scores.

A trial is simulated and recorded by `prepare_trial` (no training set needed) and replayed by
`score_prepared`; `evaluate_trial` does both in one scratch directory. Detectors trained on a given set
are trained once per process (`training_window.reuse_training`). None of that may change a figure: every
path is judged against the plain one, array for array.
"""

from __future__ import annotations

import contextlib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from replay.engine.config import RunConfig
from replay.run import evaluate as ev
from replay.run.batch import dask_client
from replay.run.config import load_config
from replay.run.evaluate import TrialGroup, TrialScores, TrialSpec, run_trials
from replay.stack.training_window import TrainedCache
from samples.scenario import Scenario
from samples.simulator import simulate_trial
from samples.writer import render, write_trial

DURATION_S = 500.0
# the trained detectors of the paper and the new ones (their training is what is reused), and the plain ACKF
METHODS = "ackf,chi_square,dual_threshold,anfis,drift_reference"


def _config(source: str = "given") -> RunConfig:
    config = load_config(None, ["training_window_s=300", f"methods={METHODS}"])
    return replace(config, stack=replace(config.stack, training_source=source))


def _same(a: TrialScores, b: TrialScores) -> None:
    """Every array of two trials' scores equal, method by method."""
    assert a.spec == b.spec and a.methods == b.methods and a.detecting == b.detecting
    assert a.unmatched == b.unmatched
    for name in ("flagged", "labels", "kinds", "open_labels", "open_scores", "errors"):
        x, y = getattr(a, name), getattr(b, name)
        assert list(x) == list(y), name
        for m in x:
            assert np.array_equal(x[m], y[m]), (name, m)


@pytest.fixture(scope="module")
def given() -> object:
    """The train seed's set (seed 0, a 500 s trial, 300 s window)."""
    return ev.training_set_of(TrialSpec(0, None, DURATION_S), _config("own"))


def test_prepared_then_scored_is_the_trial_in_one_go(given: object) -> None:
    config = _config()
    spec = TrialSpec(1, 0.5, DURATION_S)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ev, "_TRAINED_HERE", TrainedCache())        # nothing trained before: every detector anew
        whole = ev.evaluate_trial(spec, config, given)
    prepared = ev.prepare_trial(spec)
    assert prepared.archive[:8] == b"\x89MCAP0\r\n" and prepared.cpu_s > 0
    assert len(prepared.epochs[0]) == len(simulate_trial(spec.scenario(), spec.seed).ranges.t_s)
    _same(ev.score_prepared(prepared, config, given), whole)
    assert any(len(whole.flagged[m]) for m in whole.methods)    # something was scored


def test_detectors_trained_on_a_given_set_are_trained_once_and_score_the_same(given: object) -> None:
    config = _config()
    spec = TrialSpec(2, None, DURATION_S)
    cache = TrainedCache()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ev, "_TRAINED_HERE", cache)
        first = ev.evaluate_trial(spec, config, given)
        trained, hits = len(cache), cache.hits
        assert trained > 0
        again = ev.evaluate_trial(spec, config, given)
    assert len(cache) == trained and cache.hits - hits == trained + hits    # this time nothing is trained anew
    _same(first, again)
    # and without any reuse at all (the runner trains every detector itself)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ev, "reuse_training", lambda cache: contextlib.nullcontext())
        _same(ev.evaluate_trial(spec, config, given), first)


def test_the_cache_hands_out_copies_and_keeps_its_bound() -> None:
    cache = TrainedCache(max_entries=2)
    marker = {"memory": [1.0]}
    cache.put(("a", "cfg", "d1"), (marker, ""))  # type: ignore[arg-type]
    marker["memory"].append(2.0)                  # the run changes its own detector: the kept one is untouched
    got = cache.get(("a", "cfg", "d1"))
    assert got == ({"memory": [1.0]}, "") and got[0] is not cache.get(("a", "cfg", "d1"))[0]  # type: ignore[index]
    cache.put(("b", "cfg", "d1"), (None, "no labelled epochs"))
    cache.put(("c", "cfg", "d1"), (None, ""))
    assert len(cache) == 2 and cache.get(("a", "cfg", "d1")) is None    # the least recently used went first
    assert cache.get(("b", "cfg", "d1")) == (None, "no labelled epochs")


def test_dask_tasks_give_the_in_process_scores(given: object) -> None:
    """Two groups (trained on the train seed) on a 2-worker LocalCluster: the in-process loop's scores."""
    config = _config()
    groups = [TrialGroup(config, TrialSpec(0, None, DURATION_S), (TrialSpec(1, None, DURATION_S),
                                                                    TrialSpec(2, 0.3, DURATION_S))),
              TrialGroup(config, TrialSpec(3, None, DURATION_S), (TrialSpec(1, 0.5, DURATION_S),))]
    serial = run_trials(groups)
    seen: list[tuple[int, int]] = []
    with dask_client(None, 2) as client:
        on_dask = run_trials(groups, client, lambda done, total: seen.append((done, total)))
    assert [len(g) for g in on_dask] == [2, 1]
    for a, b in zip(serial, on_dask):
        for x, y in zip(a, b):
            _same(x, y)
    assert seen == [(k, 5) for k in range(1, 6)]


def test_logs_only_writes_what_record_reads(tmp_path: Path) -> None:
    trial = simulate_trial(Scenario().with_options(120.0, None), 4)
    written = write_trial(trial, tmp_path, logs_only=True)
    full = render(trial)
    names = {p.relative_to(tmp_path).as_posix() for p in written}
    assert names == {"trial.toml"} | {n for n in full if "/" in n}
    for p in written:
        assert p.read_bytes() == full[p.relative_to(tmp_path).as_posix()]
