"""`auvreplay evaluate --conditions`: the JSON shape of issue 26 on tiny trials, and its figures against counts."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from replay import cli
from replay.errors import UserError
from replay.run.evaluate import TrialScores, TrialSpec
from replay.run.matrix import (
    BUILTIN_CONDITIONS,
    closed_loop_fnr,
    conditions,
    drift_recall_by_rate,
    label_noise_floor,
)
from samples.anomalies import KIND_CODES
from samples.scenario import ANOMALY_KINDS

METHOD_KEYS = {"auc", "fnr_at_fpr_1", "fnr_at_fpr_2", "fnr_at_fpr_5", "fpr_closed", "fnr_closed", "recall_by_kind",
               "drift_recall_by_rate", "error_p50_m", "error_p90_m"}
METHODS = ("ackf", "chi_square", "drift_reference")


def _cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def matrix(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], str]:
    """A one-condition FILE (multipath, often) on 700 s trials: seed 1 scored, seed 0 trained on.

    The condition moves the scripted drift inside the short trial's scored part (a list replaces the list).
    """
    path = tmp_path_factory.mktemp("matrix") / "conditions.toml"
    path.write_text("[multipath.conditions]\nmultipath_per_hour = 12.0\nmultipath_min_m = 15.0\n"
                    "[[multipath.anomalies]]\nleader = \"leader1\"\nkind = \"drift\"\nstart_s = 480.0\n"
                    "end_s = 550.0\nmagnitude_m = 25.0\n")
    code, out, err = _cli(["evaluate", "--conditions", str(path), "--seeds", "1", "--train-seed", "0",
                           "--duration", "700", "--set", "training_window_s=400", "--set",
                           f"methods={','.join(METHODS)}", "--drift-rate", "0.5", "--workers", "1", "--json"])
    assert code == 0
    return json.loads(out), err


def test_the_json_has_the_issues_shape(matrix: tuple[dict[str, Any], str]) -> None:
    obj, err = matrix
    assert set(obj) == {"seeds", "train_seed", "operating_point", "conditions"}
    assert obj["seeds"] == [1] and obj["train_seed"] == 0 and "test trials' own ROC" in obj["operating_point"]
    assert set(obj["conditions"]) == {"multipath", "multipath_usbl"}
    for cond in obj["conditions"].values():
        assert set(cond) == {"label_noise_floor", "methods"}
        assert 0.0 <= cond["label_noise_floor"] < 0.5
        assert set(cond["methods"]) == set(METHODS)
        for name, fig in cond["methods"].items():
            assert set(fig) == METHOD_KEYS
            assert set(fig["recall_by_kind"]) == set(ANOMALY_KINDS)
            assert set(fig["drift_recall_by_rate"]) == {"0.5"}
            assert 0.0 < fig["error_p50_m"] <= fig["error_p90_m"]
            if name == "ackf":
                assert fig["auc"] is None and fig["fpr_closed"] is None and fig["drift_recall_by_rate"]["0.5"] is None
            else:
                assert 0.0 < fig["auc"] <= 1.0
                assert fig["fnr_at_fpr_1"] >= fig["fnr_at_fpr_2"] >= fig["fnr_at_fpr_5"]
                assert 0.0 <= fig["fpr_closed"] < 0.5 and 0.0 <= fig["fnr_closed"] <= 1.0
                assert fig["recall_by_kind"]["multipath"] is not None
                assert 0.0 <= fig["drift_recall_by_rate"]["0.5"] <= 1.0
    assert "2 conditions" in err and "s wall" in err
    assert "multipath_usbl: median over trials of fpr_closed: chi_square " in err


def test_usbl_fixes_feed_the_filters_in_the_usbl_condition(matrix: tuple[dict[str, Any], str]) -> None:
    """With KMCDF's fixes the ACKF's error is a few metres and the detectors separate; without, tens of metres."""
    conds = matrix[0]["conditions"]
    for m in ("chi_square", "drift_reference"):
        assert conds["multipath_usbl"]["methods"][m]["auc"] > 0.9
    # the fixes keep the ACKF off a held bias: chi-square's innovation sees it
    with_fixes, without = (conds[c]["methods"]["chi_square"]["recall_by_kind"]["multipath"]
                           for c in ("multipath_usbl", "multipath"))
    assert with_fixes > without
    assert conds["multipath_usbl"]["methods"]["ackf"]["error_p90_m"] < 8.0
    assert conds["multipath"]["methods"]["ackf"]["error_p90_m"] > 2 * conds["multipath_usbl"]["methods"]["ackf"][
        "error_p90_m"]


def test_all_is_every_condition_with_and_without_usbl() -> None:
    names = [c.name for c in conditions("all")]
    assert names == [n + s for n in BUILTIN_CONDITIONS for s in ("", "_usbl")]
    by = {c.name: c for c in conditions("all")}
    assert by["sound_speed"].scenario == by["sound_speed_usbl"].scenario and by["sound_speed_usbl"].usbl
    assert by["sound_speed"].scenario.conditions.sound_speed_bias == 0.005
    assert by["default"].scenario.conditions == by["default_usbl"].scenario.conditions
    assert by["combined"].scenario.conditions.anomalies_drawn


def test_a_bad_conditions_file_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[x.conditions]\nrange_noise_dof = 1.0\n")
    with pytest.raises(UserError, match="condition 'x'"):
        conditions(str(bad))
    with pytest.raises(UserError, match="cannot read"):
        conditions(str(tmp_path / "missing.toml"))


def _scores(rate: float, flagged: list[bool], labels: list[int], kinds: list[int]) -> TrialScores:
    f, lab, k = np.array(flagged), np.array(labels, np.int8), np.array(kinds, np.int16)
    return TrialScores(TrialSpec(1, rate), ("m",), ("m",), {"m": f}, {"m": lab}, {"m": k}, {}, {}, {})


def test_closed_loop_fnr_floor_and_drift_recall_by_rate_against_counts() -> None:
    d, s, n = KIND_CODES["drift"], KIND_CODES["stale"], KIND_CODES[""]
    a = _scores(0.3, [True, False, True, False, True], [1, 1, 1, 0, 1], [d, d, n, n, s])
    b = _scores(0.5, [True, True, False], [1, 1, 1], [d, d, n])
    # anomalous: 4 in a (flagged 3), 3 in b (flagged 2): FNR 2/7; unlabelled-kind anomalous 2 of 7
    assert closed_loop_fnr([a, b], "m") == pytest.approx(2 / 7)
    assert label_noise_floor([a, b]) == pytest.approx(2 / 7)
    assert drift_recall_by_rate([a, b], "m") == {"0.3": 0.5, "0.5": 1.0}
