"""The method table: a detector added from a module of its own, with one table entry, reaches every listing.

The toy detector lives in a temporary module written by the test; it registers
its entry on import (through ``$AUVREPLAY_PLUGINS``, as a user's plug-in
would). No file of the project is edited, yet the toy shows in `replay`'s
metrics.json, the review's why lines, the Detection lanes of the viewer's
recording and `evaluate`'s JSON.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from replay import cli
from replay.stack import methods
from replay.stack.config import ConfigError
from tests.test_views import Rrd

TOY = textwrap.dedent('''
    """A toy detector: flags an epoch whose innovation (f1) exceeds the training rows' largest normal one."""
    import numpy as np

    from replay.stack.detectors.base import Decision
    from replay.stack.methods import Method, register


    class ToyDetector:
        name = "toy"

        def __init__(self, config):
            self.threshold = float("inf")

        def train_on(self, ts):
            assert ts.feature_names == ("f1",)
            normal = ts.features[ts.labels == 0, 0]
            self.threshold = float(np.max(normal)) if normal.size else float("inf")

        def decide(self, features):
            score = float(features[0])
            return Decision(score > self.threshold, score, self.threshold)

        def scores(self, features):
            return np.asarray(features, dtype=float)[:, 0]

        def reset(self):
            pass


    def why(r, detector=None):
        return f"toy |innovation| {r.score:.2f} m vs {r.threshold:.2f} m"


    register(Method("toy", "detector", "detect", ("dvl", "ranges", "gps"), "ACKF + toy test", "toy",
                    (10, 200, 90), ToyDetector, ("f1",), why))
''')


def _cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def toy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """The toy module on the path and in $AUVREPLAY_PLUGINS; the table as it was afterwards."""
    (tmp_path / "toy_detector.py").write_text(TOY)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("AUVREPLAY_PLUGINS", "toy_detector")
    monkeypatch.setattr(methods, "_plugins_loaded", False)
    before = dict(methods.METHOD_TABLE)
    yield "toy"
    methods.METHOD_TABLE.clear()
    methods.METHOD_TABLE.update(before)
    sys.modules.pop("toy_detector", None)


def test_a_toy_detector_reaches_metrics_why_lines_lanes_and_evaluate(toy: str, tmp_path: Path) -> None:
    trial = tmp_path / "trial"
    assert _cli(["simulate", "--seed", "4", "--duration", "900", "-o", str(trial)])[0] == 0
    archive, results = tmp_path / "trial.mcap", tmp_path / "results.mcap"
    assert _cli(["record", str(trial / "trial.toml"), "-o", str(archive)])[0] == 0
    code, out, err = _cli(["replay", str(archive), "--set", "methods=ackf,chi_square,toy",
                           "--set", "training_window_s=400", "-o", str(results), "--json"])
    assert code == 0, err
    assert "toy" in methods.detecting_names() and methods.filter_kind(toy) == "detect"
    metrics = json.loads(out)
    row = metrics["methods"]["toy"]
    assert row["auc"] is not None and 0.0 <= row["auc"] <= 1.0      # judged like every detector
    assert json.loads((tmp_path / "results.metrics.json").read_text())["methods"]["toy"] == row

    rrd_path = tmp_path / "view.rrd"
    assert _cli(["view", str(results), "--save", str(rrd_path)])[0] == 0
    rrd = Rrd(rrd_path)       # the recording's entities, read back with Rerun's own reader
    assert [e for e in rrd.temporal if "/lanes/" in e and e.endswith("_toy")], "the toy detector has no lane"
    why_docs = [d[0] for e in rrd.temporal if "/why/" in e for d in rrd.cells(e, "TextDocument:text")]
    toy_lines = [ln for d in why_docs for ln in d.splitlines() if " toy: " in ln]
    assert toy_lines and all("toy |innovation| " in ln for ln in toy_lines)

    code, out, err = _cli(["evaluate", "--seeds", "5", "--train-seed", "4", "--duration", "700", "--workers", "1",
                           "--set", "training_window_s=400", "--set", "methods=ackf,toy", "--json"])
    assert code == 0, err
    figures = json.loads(out)["methods"]["toy"]
    assert figures["auc"] is not None and 0.0 <= figures["error_p50_m"] <= figures["error_p90_m"]


def test_a_clashing_or_incomplete_entry_is_refused() -> None:
    with pytest.raises(ConfigError, match="already in the method table"):
        methods.register(methods.Method("ackf", "filter", "ckf", ("dvl",), "x", "x", (1, 2, 3)))
    with pytest.raises(ConfigError, match="unknown inputs sonar"):
        methods.register(methods.Method("new", "filter", "ckf", ("sonar",), "x", "x", (1, 2, 3)))
    with pytest.raises(ConfigError, match="needs a factory"):
        methods.register(methods.Method("new", "detector", "detect", ("dvl",), "x", "x", (1, 2, 3)))
    assert "new" not in methods.METHOD_TABLE
