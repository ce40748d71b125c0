"""`auvreplay reproduce kmcdf`: JSON shape, ordering of methods, table, PNG and .rrd outputs."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from replay import cli
from replay.reproduce import kmcdf as rk
from replay.stack.positioning.kmcdf_montecarlo import METHODS


@pytest.fixture()
def only_reproduce(monkeypatch: pytest.MonkeyPatch) -> None:
    """Build the parser with the reproduce command alone, so this test does not depend on others."""
    monkeypatch.setattr(cli, "COMMANDS", {"reproduce": cli.COMMANDS["reproduce"]})


@pytest.fixture(scope="module")
def small_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path]:
    """One small run through the command line, shared by the JSON checks."""
    out = tmp_path_factory.mktemp("kmcdf")
    mp = pytest.MonkeyPatch()
    mp.setattr(cli, "COMMANDS", {"reproduce": cli.COMMANDS["reproduce"]})
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            code = cli.main(["reproduce", "kmcdf", "--trials", "60", "--json", "--workers", "1",
                             "--png", str(out / "fig.png"), "--rrd", str(out / "fig.rrd")])
    finally:
        mp.undo()
    assert code == 0
    return json.loads(buf.getvalue()), out


def test_json_shape(small_run: tuple[dict, Path]) -> None:
    data, _ = small_run
    assert data["trials"] == 60 and data["phase_noise_rad"] == 0.1
    assert set(data["layouts"]) == {"6", "4"}
    for layout, n in (("6", 6), ("4", 4)):
        methods = data["layouts"][layout]
        assert set(methods) == set(METHODS) == {"kmcdf1", "kmcdf2", "gar", "ear", "lms", "lhc"}
        for curve in methods.values():
            assert list(curve) == [str(k) for k in range(n + 1)]
            assert all(0.0 <= v <= 1.0 for v in curve.values())


def test_methods_rank_as_the_paper_says(small_run: tuple[dict, Path]) -> None:
    six, four = small_run[0]["layouts"]["6"], small_run[0]["layouts"]["4"]
    assert six["kmcdf1"]["3"] > six["lms"]["3"] and six["lms"]["3"] == 0.0
    assert six["kmcdf1"]["3"] > 0.8 and six["kmcdf1"]["6"] > 0.8
    assert six["kmcdf2"]["3"] > six["gar"]["3"] and six["kmcdf2"]["6"] == 0.0
    assert four["kmcdf1"]["2"] > 0.8 and four["gar"]["2"] == 0.0
    assert six["gar"]["1"] > six["gar"]["4"] and six["lhc"]["0"] > six["lhc"]["3"]


def test_figure_files_are_written(small_run: tuple[dict, Path]) -> None:
    _, out = small_run
    assert (out / "fig.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "fig.rrd").stat().st_size > 1000


def test_table_mode_prints_paper_beside_ours(only_reproduce: None, capsys: pytest.CaptureFixture[str],
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rk, "LAYOUTS", (4,))
    code = cli.main(["reproduce", "kmcdf", "--trials", "20", "--workers", "1", "--png", "", "--rrd", ""])
    text = capsys.readouterr().out
    assert code == 0
    assert "N = 4: success (%)" in text and "Against the paper" in text
    assert " 4 kmcdf1    2     94.8" in text
    assert "wrote" not in text


def test_bad_trials_is_a_usage_error(only_reproduce: None, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["reproduce", "kmcdf", "--trials", "0"]) == 1
    assert "--trials" in capsys.readouterr().err


def test_claims_verdicts() -> None:
    result = rk.KmcdfReproduction(10, 0, 0.1, {"6": {"kmcdf1": {"3": 0.9}, "ear": {"3": 0.5}}})
    text = rk.format_claims(result)
    assert "-4.2 points" in text and "DOES NOT HOLD" in text
    assert rk.paper_points()["4"]["kmcdf2"] == {"2": 0.838}


def test_results_do_not_depend_on_workers() -> None:
    one = rk.run_tasks([(4, 1, "kmcdf1", 30, 3, rk.KmcdfParams()), (4, 2, "gar", 30, 3, rk.KmcdfParams())], 1)
    two = rk.run_tasks([(4, 1, "kmcdf1", 30, 3, rk.KmcdfParams()), (4, 2, "gar", 30, 3, rk.KmcdfParams())], 2)
    assert one == two


def test_sensitivity_table_shape() -> None:
    table = rk.sensitivity(trials=20, noises=(0.01, 0.2), workers=1)
    assert list(table) == ["0.01", "0.2"]
    assert set(table["0.01"]) == {f"N{n} {m} @{k}" for n, k, m in rk.SENSITIVITY_POINTS}
    assert "sigma_phase" in rk.format_sensitivity(table)
