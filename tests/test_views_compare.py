"""Issue 27, items 5 and 6: one ANFIS view per ANFIS model that ran, named by method and leader, with
its MF axes in the input's own units; comparisons where A is the first argument everywhere (`compare A B`,
`view A B`, `replay --compare A`), and the viewer's table of differing epochs equal to `compare`'s list."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from recorders.manifest import load_manifest
from recorders.record import record
from replay.cli import main
from replay.review.differing import differing_epochs, who_was_right
from replay.run.compare import compare_runs
from replay.run.config import load_config
from replay.run.pipeline import replay_archive
from replay.stack.methods import anfis_models
from replay.views import recording as views
from replay.views.anfis import MF_TICKS, axis_labels, model_parts, tick
from tests.test_views import Rrd

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
QUICK = ["anfis.epochs=3", "anfis.iterations=3", "anfis.particles=4"]
ANFIS_RUN = ["methods=dead_reckoning,ckf,ackf,anfis,anfis_aqpso,anfis_hybrid", *QUICK]   # no anfis_compensation
FAST = ["methods=dead_reckoning,ckf,ackf,chi_square,anfis", *QUICK]


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("lake") / "lake.mcap"
    record(load_manifest(SAMPLE / "trial.toml"), out)
    return out


@pytest.fixture(scope="module")
def anfis_rrd(archive, tmp_path_factory):
    """The sample replayed with three of the four ANFIS methods, and its recording read back."""
    review = replay_archive(archive, load_config(None, ANFIS_RUN), write_output=False, review=True).review
    path = views.save_rrd([review], tmp_path_factory.mktemp("anfis") / "a.rrd")
    return review, Rrd(path)


def test_anfis_family_is_the_method_tables():
    assert set(anfis_models()) == {"anfis", "anfis_aqpso", "anfis_compensation", "anfis_hybrid"}


def test_one_anfis_view_per_model_that_ran(anfis_rrd):
    review, rrd = anfis_rrd
    rid = review.run_id
    ran = {"anfis", "anfis_aqpso", "anfis_hybrid"}
    leaders = sorted(set(review.detections.leader))
    models = set(review.anfis_epochs.model)
    assert models == {f"{m}/{ld}" for m in ran for ld in leaders}
    assert set(review.anfis_explain.model) == models
    roots = {"/".join(e.split("/")[3:5]) for e in [*rrd.static, *rrd.temporal] if e.startswith(f"/{rid}/anfis/")}
    assert roots == models                                                 # nothing for anfis_compensation
    for model in sorted(models):
        method, leader = model_parts(model)
        base = f"/{rid}/anfis/{method}/{leader}"
        note = rrd.static[f"{base}/note"][0].column("TextDocument:text").to_pylist()[0][0]
        assert note.startswith(f"**{method}** on **{leader}**") and "bell MFs each" in note
        assert ("AQPSO-GA" in note) == (method == "anfis_aqpso")
        rows = review.anfis_epochs[review.anfis_epochs.model == model]
        params = rows.params.iloc[-1]
        assert params["method"] == method and params["leader"] == leader
        n_inputs = len(params["inputs"])
        assert n_inputs == (3 if method != "anfis_hybrid" else len(params["input_min"]))
        for d in range(1, n_inputs + 1):
            assert len(rrd.cells(f"{base}/training/mf/in{d}", "LineStrips2D:strips")) == len(rows) + 1
            # the MF axis carries the input's real values, from the model's own range
            labels = rrd.static[f"{base}/training/mf/in{d}/axis/values"][0].column("Points2D:labels").to_pylist()[0]
            assert labels[:MF_TICKS.size] == axis_labels(params["input_min"][d - 1], params["input_max"][d - 1])
        explained = review.anfis_explain[review.anfis_explain.model == model]
        verdicts = [t[0] for t in rrd.cells(f"{base}/explain/verdict", "TextDocument:text")]
        assert len(verdicts) == len(explained) and all("Inputs: " in v for v in verdicts)
        # one label on the rule plot per epoch (the strongest rule), never one per bar
        tops = rrd.cells(f"{base}/explain/firing/top", "Points2D:labels")
        assert len(tops) == len(explained) and all(len(t) == 1 for t in tops)
        firing = np.stack(explained.firing.to_numpy())
        np.testing.assert_allclose([float(t[0]) for t in tops], firing.max(axis=1), atol=0.006)
        assert f"{method} {leader}" in rrd.view_names                  # the model's note, titled with both


def test_anfis_notes_are_titled_with_method_and_leader(anfis_rrd):
    review, rrd = anfis_rrd
    titles = [n for n in rrd.view_names if re.fullmatch(r"anfis\w* leader\d", n)]
    assert sorted(titles) == sorted(m.replace("/", " ") for m in set(review.anfis_epochs.model))


@given(st.floats(-1e6, 1e6, allow_nan=False), st.floats(1e-6, 1e6))
def test_tick_labels_are_short_numbers(lo, span):
    labels = axis_labels(lo, lo + span)
    assert len(labels) == MF_TICKS.size and all(len(s) <= 8 for s in labels)
    for s, v in zip(labels, lo + MF_TICKS * span, strict=True):
        assert s == "0" or abs(float(s) - v) <= 0.06 * max(abs(v), 1e-300) + 1e-9
    assert tick(0.0, 5.0) == "0" and tick(1234.4, 5000.0) == "1234" and tick(0.0123, 1.0) == "0.0123"


@pytest.fixture(scope="module")
def pair(archive, tmp_path_factory):
    """Results of run A (chi_square_alpha=0.01), and `replay --compare A` making run B (alpha 0.2) and a recording."""
    d = tmp_path_factory.mktemp("pair")
    a = replay_archive(archive, load_config(None, [*FAST, "chi_square_alpha=0.01"]), d / "a.mcap")
    argv = ["replay", str(archive), "-o", str(d / "b.mcap"), "--rrd", str(d / "ab.rrd"), "--compare", str(a.output)]
    for s in [*FAST, "chi_square_alpha=0.2"]:
        argv += ["--set", s]
    assert main(argv) == 0
    return a.output, d / "b.mcap", d / "ab.rrd"


def _changes(rrd: Rrd) -> str:
    found = [k for k in rrd.static if k.endswith("/changes")]
    assert len(found) == 1
    return rrd.static[found[0]][0].column("TextDocument:text").to_pylist()[0][0]


def test_a_is_the_first_argument_everywhere(pair, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)           # view: save the recording, open no window
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    a, b, ab = pair
    capsys.readouterr()
    assert main(["compare", str(a), str(b), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    a_id, b_id = result["a"]["run_id"], result["b"]["run_id"]
    assert result["a"]["label"] == "chi_square_alpha=0.01" and result["b"]["label"] == "chi_square_alpha=0.2"
    head = f"**A = chi_square_alpha=0.01** (run {a_id}) against **B = chi_square_alpha=0.2** (run {b_id})"
    # replay --compare A: the earlier run is A, the new one B, as `compare A B` says
    assert _changes(Rrd(ab)).startswith(head)
    # view A B: the same A
    assert main(["view", str(a), str(b), "--save", str(tmp_path / "v.rrd")]) == 0
    view = Rrd(tmp_path / "v.rrd")
    assert _changes(view).startswith(head)
    assert "Events; chi_square_alpha: A 0.01, B 0.2" in view.view_names
    assert view.static[f"/{b_id}/differing"] and f"/{a_id}/events" in view.temporal
    lines = [t[0] for t in view.cells(f"/{a_id}/events", "TextLog:text")]
    assert lines and all(t.startswith("[A] ") and "chi_square_alpha" not in t for t in lines)


def test_differing_table_rows_are_compares_list(pair):
    a, b, ab = pair
    result = compare_runs(a, b)
    listed = sorted((f"{r['mission_s']:.1f}", f"{r['follower']} <- {r['leader']}", m,
                     "-" if r["a"] is None else ("flagged" if r["a"] else "passed"),
                     "-" if r["b"] is None else ("flagged" if r["b"] else "passed"),
                     {1: "anomalous", 0: "normal"}.get(r["label"], "unlabelled"), who_was_right(r))
                    for m, rows in result["differing_epochs"].items() for r in rows)
    assert listed and {x[2] for x in listed} == {"chi_square"}
    rrd = Rrd(ab)
    doc = next(rrd.static[k] for k in rrd.static if k.endswith("/differing"))[0].column(
        "TextDocument:text").to_pylist()[0][0]
    table = sorted(tuple(c.strip() for c in line.strip("|").split("|"))
                   for line in doc.splitlines() if re.match(r"^\| \d", line))
    assert table == listed
    total = sum(t["epochs"] for t in result["right"].values())
    assert f"**Epochs that differ: {total}**" in doc


def test_differing_rule_credits_the_run_that_matches_the_truth():
    key = (1_000_000_000, "f", "l", "m")
    rows, tally = differing_epochs({key: (True, 1), (2, "f", "l", "m"): (True, 0)},
                                   {key: (False, 1), (2, "f", "l", "m"): (True, 0), (3, "f", "l", "m"): (False, 0)})
    assert [r["mission_s"] for r in rows["m"]] == pytest.approx([3e-9, 1.0])
    assert tally["m"] == {"a": 1, "b": 1, "epochs": 2}
    assert [who_was_right(r) for r in rows["m"]] == ["B", "A"]
