"""replay.stack.forked: jobs in forked children give what they give here, and whatever fails there runs here."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from replay.stack import forked
from replay.stack.detectors.dual_threshold import train_bp


@given(st.lists(st.floats(0.0, 10.0), max_size=12), st.integers(1, 5))
def test_balance_splits_every_job_once_into_even_groups(costs: list[float], groups: int) -> None:
    """Every index in exactly one group, no empty group, and no group heavier than the lightest by more than
    the costliest job (what greedy largest-first guarantees)."""
    split = forked.balance(costs, groups)
    assert sorted(i for g in split for i in g) == list(range(len(costs)))
    assert all(g == sorted(g) and g for g in split)
    assert len(split) <= max(1, groups)
    if costs:
        loads = [sum(costs[i] for i in g) for g in split]
        assert max(loads) - min(loads) <= max(costs) + 1e-9


def test_balance_of_the_sample_jobs_puts_one_heavy_job_in_each_group() -> None:
    """Two leaders' jobs (chi_square, dual_threshold, anfis, anfis_aqpso, anfis_compensation): the same split
    per leader."""
    costs = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 4.0, 4.0, 1.0, 1.0]
    assert forked.balance(costs, 2) == [[0, 2, 4, 6, 8], [1, 3, 5, 7, 9]]


@pytest.mark.skipif(not forked.can_fork(), reason="no fork here")
def test_children_give_the_bits_a_training_gives_here() -> None:
    """Adam-trained networks from forked children equal, bit for bit, those trained in this process."""
    rng = np.random.default_rng(4)
    data = [(rng.gamma(2.0, 1.0, (60 + k, 3)), rng.normal(0.0, 1.0, 60 + k)) for k in range(3)]

    def job(i: int) -> tuple[np.ndarray, np.ndarray, int]:
        net = train_bp(data[i][0], data[i][1], hidden=4, seed=i)
        return net.w1, net.w2, os.getpid()

    out = forked.run_groups(job, [[0], [1], [2]])
    assert out[0][2] == os.getpid() and out[1][2] != os.getpid() and out[2][2] not in (os.getpid(), out[1][2])
    for i in range(3):
        here = job(i)
        np.testing.assert_array_equal(out[i][0], here[0])
        np.testing.assert_array_equal(out[i][1], here[1])


@pytest.mark.skipif(not forked.can_fork(), reason="no fork here")
def test_a_result_that_does_not_pickle_or_a_failing_job_runs_here() -> None:
    """A lock does not pickle: that job runs again in this process; a job raising in its child raises here."""
    def job(i: int) -> object:
        if i == 1:
            return (os.getpid(), threading.Lock())
        if i == 2 and os.getpid() != parent:
            raise RuntimeError("only in the child")
        return os.getpid()

    parent = os.getpid()
    out = forked.run_groups(job, [[0], [1, 2, 3]])
    assert out[0] == parent and out[2] == parent         # 2 failed in its child: trained here
    assert out[1][0] == parent                           # type: ignore[index]
    assert out[3] != parent                              # 3 came back from the child


def test_without_fork_every_group_runs_here(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where there is no fork, the jobs run in this process, each once."""
    monkeypatch.setattr(forked, "can_fork", lambda: False)
    calls: list[int] = []
    out = forked.run_groups(lambda i: calls.append(i) or i * i, [[2], [0, 1]])
    assert out == {0: 0, 1: 1, 2: 4} and sorted(calls) == [0, 1, 2]
