"""`auvreplay batch` on a two-worker LocalCluster: the combined table against runs done one at a time,
failed runs as error rows, simulated seeds, sweep parsing, and `reproduce kmcdf` on the same cluster."""

from __future__ import annotations

import contextlib
import io
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from recorders.manifest import load_manifest
from recorders.record import record
from replay import cli
from replay.errors import UserError
from replay.reproduce import kmcdf as rk
from replay.run.batch import (
    Configuration,
    batch,
    dask_client,
    parse_seeds,
    parse_sweeps,
    plan_batch,
    split_values,
    summary_table,
    sweep_configurations,
    trial_names,
)
from replay.run.config import load_config
from replay.run.metrics import metrics_table
from replay.run.pipeline import replay_archive
from samples.scenario import Scenario
from samples.simulator import simulate_trial
from samples.writer import render, write_trial
from tests.hostile import rewrite

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
# short runs: four methods and 200 s scored after the 600 s training window
BASE = ["methods=dead_reckoning,ckf,ackf,chi_square", "window_s=[0,800]"]
SWEEP = [("r_m", ["3", "5"])]


@pytest.fixture(scope="module")
def archives(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The sample trial, a different simulated trial (seed 1, 800 s), and a corrupt archive."""
    d = tmp_path_factory.mktemp("archives")
    record(load_manifest(SAMPLE / "trial.toml"), d / "lake.mcap")
    write_trial(simulate_trial(Scenario().with_options(800.0, None), 1), d / "short")
    record(load_manifest(d / "short" / "trial.toml"), d / "short.mcap")
    # the MCAP magic, then bytes that are no record
    (d / "corrupt.mcap").write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 8)
    return {"lake": d / "lake.mcap", "short": d / "short.mcap", "corrupt": d / "corrupt.mcap"}


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    """A LocalCluster with two worker processes, shared by the module."""
    with dask_client(None, workers=2) as c:
        yield c


@pytest.fixture(scope="module")
def batch_run(archives: dict[str, Path], client: Any, tmp_path_factory: pytest.TempPathFactory):
    """Three archives x two configurations through the cluster."""
    out = tmp_path_factory.mktemp("batch")
    calls: list[tuple[int, int, int]] = []
    df, records = batch([archives["lake"], archives["short"], archives["corrupt"]], out,
                        base_overrides=BASE, sweeps=SWEEP, client=client,
                        progress=lambda *a: calls.append(a))
    return df, records, out, calls


def _same(a: Any, b: Any) -> bool:
    """Equal JSON-like values, floats to 1e-9 relative (BLAS threading may move the last bits)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def _without_wall(metrics: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in metrics.items() if k != "wall_s"}


def test_table_matches_runs_done_one_at_a_time(batch_run, archives: dict[str, Path]) -> None:
    df, records, out, _ = batch_run
    ok = df[df["error"].isna()]
    assert sorted(set(ok["trial"])) == ["lake", "short"]
    for trial in ("lake", "short"):
        for r_m in (3, 5):
            serial = replay_archive(archives[trial], load_config(None, [*BASE, f"r_m={r_m}"]), write_output=False)
            rows = ok[(ok["trial"] == trial) & (ok["r_m"] == r_m)]
            assert set(rows["run_id"]) == {serial.run_id}
            assert set(rows["configuration"]) == {f"r_m={r_m}"}
            expected = metrics_table(serial.metrics)
            assert list(rows["method"]) == [e["method"] for e in expected]
            for (_, got), want in zip(rows.iterrows(), expected):
                for key, value in want.items():
                    cell = got[key]
                    if value is None:
                        assert pd.isna(cell), (trial, r_m, want["method"], key)
                    else:
                        assert _same(float(value), float(cell)) if isinstance(value, float) else cell == value
            assert (rows["epochs"] == serial.metrics["epochs"]).all()
            rec = next(r for r in records if r["trial"] == trial and r["run_id"] == serial.run_id)
            assert _same(_without_wall(rec["metrics"]), _without_wall(serial.metrics))
    # the two trials and the two ranging sigmas really give different results
    assert ok.groupby(["trial", "r_m"])["error_p50_m"].apply(tuple).nunique() == 4


def test_corrupt_archive_gets_error_rows_and_the_others_finish(batch_run) -> None:
    df, records, _, calls = batch_run
    bad = df[df["trial"] == "corrupt"]
    assert len(bad) == 2 and bad["method"].isna().all() and bad["tp"].isna().all()
    assert all("corrupt.mcap" in e for e in bad["error"])
    assert list(bad["configuration"]) == ["r_m=3", "r_m=5"]
    assert sum(r["error"] is not None for r in records) == 2
    assert df[df["trial"] != "corrupt"]["error"].isna().all()
    # progress: once per run, ending at 6 of 6 with 2 failed
    assert len(calls) == 6 and calls[-1] == (6, 6, 2)


def test_files_per_run_and_combined_table(batch_run) -> None:
    df, records, out, _ = batch_run
    for r in records:
        if r["error"] is None:
            assert Path(r["output"]) == out / "runs" / f"{r['trial']}-{r['run_id']}.mcap"
            assert Path(r["output"]).is_file() and Path(r["output"]).with_suffix(".metrics.json").is_file()
    assert len(list((out / "runs").glob("*.mcap"))) == 4
    parquet = pd.read_parquet(out / "metrics.parquet")
    pd.testing.assert_frame_equal(parquet, df)
    csv = pd.read_csv(out / "metrics.csv")
    assert list(csv.columns) == list(df.columns)
    assert csv["tp"].sum() == df["tp"].sum() and csv["error"].notna().sum() == 2
    assert list(df.columns[:6]) == ["trial", "archive", "run_id", "configuration", "r_m", "method"]
    assert df["r_m"].dtype.kind == "i"
    # rows in task order: archive-major, then sweep order, whatever order the runs finished in
    assert list(dict.fromkeys(zip(df["trial"], df["r_m"]))) == [
        ("lake", 3), ("lake", 5), ("short", 3), ("short", 5), ("corrupt", 3), ("corrupt", 5)]


def test_summary_pools_confusion_counts_over_trials(batch_run) -> None:
    df = batch_run[0]
    s = summary_table(df)
    row = s[(s["configuration"] == "r_m=3") & (s["method"] == "chi_square")].iloc[0]
    ok = df[(df["r_m"] == 3) & (df["method"] == "chi_square")]
    assert row["runs"] == 2 and row["fp"] == ok["fp"].sum()
    assert row["fpr"] == pytest.approx(ok["fp"].sum() / (ok["fp"].sum() + ok["tn"].sum()))
    assert pd.isna(s[(s["configuration"] == "r_m=3") & (s["method"] == "ckf")].iloc[0]["fpr"])


@pytest.fixture()
def cli_batch(monkeypatch: pytest.MonkeyPatch) -> None:
    """The parser with batch and reproduce alone, so these tests do not depend on other commands."""
    monkeypatch.setattr(cli, "COMMANDS", {k: cli.COMMANDS[k] for k in ("batch", "reproduce")})


def _main(argv: list[str]) -> tuple[int, str]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = cli.main(argv)
    return code, buf.getvalue()


def test_simulated_seeds_on_an_existing_scheduler(cli_batch: None, client: Any, tmp_path: Path) -> None:
    code, text = _main(["batch", "--simulate-seeds", "2", "--duration", "700", "--scheduler",
                        client.scheduler.address, "-o", str(tmp_path), "--json",
                        *[a for s in BASE[:1] for a in ("--set", s)]])
    assert code == 0
    result = json.loads(text)
    assert result["failed"] == 0 and [r["trial"] for r in result["runs"]] == ["seed-2"]
    archive = tmp_path / "trials" / "seed-2.mcap"
    # the trial the batch simulated is `simulate --seed 2 --duration 700`, file for file
    expected = render(simulate_trial(Scenario().with_options(700.0, None), 2))
    for rel, data in expected.items():
        assert (tmp_path / "trials" / "seed-2" / rel).read_bytes() == data
    serial = replay_archive(archive, load_config(None, BASE[:1]), write_output=False)
    assert result["runs"][0]["run_id"] == serial.run_id
    assert _same(_without_wall(result["runs"][0]["metrics"]), _without_wall(serial.metrics))
    assert set(pd.read_csv(tmp_path / "metrics.csv")["trial"]) == {"seed-2"}


def test_failed_run_gives_exit_code_1(cli_batch: None, client: Any, archives: dict[str, Path], tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    code = cli.main(["batch", str(archives["corrupt"]), "--scheduler", client.scheduler.address,
                     "-o", str(tmp_path), "--quiet"])
    assert code == 1
    err = capsys.readouterr().err
    assert err.startswith("failed: corrupt: ") and "corrupt.mcap" in err
    assert pd.read_csv(tmp_path / "metrics.csv")["error"].notna().all()


def test_a_damaged_archive_gives_one_warning_line(cli_batch: None, client: Any, archives: dict[str, Path],
                                                  tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def garbage(topic: str, data: bytes, rng: Any) -> bytes:
        return rng.randbytes(len(data) + 1) if rng.random() < 1 / 97 else data

    damaged = rewrite(archives["lake"], tmp_path / "damaged.mcap", message=garbage, seed=5)
    code = cli.main(["batch", str(damaged), "--scheduler", client.scheduler.address, "-o", str(tmp_path / "out"),
                     "--quiet", "--set", "methods=dead_reckoning", "--window", "0", "700", "--sweep", "r_m=3,5"])
    lines = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert code == 0 and len(lines) == 1, lines
    # two runs of the one archive: it is named once
    assert lines[0].startswith("auvreplay batch: warning: ") and lines[0].count(str(damaged)) == 1
    assert "do not decode" in lines[0]


def test_user_errors_stop_the_batch_before_any_run(cli_batch: None, archives: dict[str, Path], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    lake = str(archives["lake"])
    for argv in (["--sweep", "no_such_key=1,2"], ["--sweep", "r_m=3,3.0"], ["--sweep", "r_m="],
                 ["--simulate-seeds", "5-2"], ["--duration", "100"]):
        assert cli.main(["batch", lake, "-o", str(tmp_path), *argv]) == 1
    assert cli.main(["batch", str(tmp_path / "missing.mcap"), "-o", str(tmp_path)]) == 1
    assert "no such archive" in capsys.readouterr().err
    assert not (tmp_path / "metrics.csv").exists()


def test_reproduce_kmcdf_on_dask_equals_the_serial_path(cli_batch: None, client: Any) -> None:
    tasks = [(4, 1, "kmcdf1", 20, 3, rk.KmcdfParams()), (6, 3, "kmcdf2", 20, 3, rk.KmcdfParams()),
             (4, 2, "gar", 20, 5, rk.KmcdfParams())]
    assert rk.run_tasks(tasks, 2, client) == rk.run_tasks(tasks, 1)
    code, text = _main(["reproduce", "kmcdf", "--trials", "3", "--json", "--png", "", "--rrd", "",
                        "--scheduler", client.scheduler.address])
    assert code == 0
    assert json.loads(text)["layouts"] == rk.reproduce(trials=3, workers=1).layouts


def test_sweep_parsing() -> None:
    assert parse_sweeps(["r_m=3,5", "methods=ckf,ackf;ckf", "window_s=[0,800],[0,900]"]) == [
        ("r_m", ["3", "5"]), ("methods", ["ckf,ackf", "ckf"]), ("window_s", ["[0,800]", "[0,900]"])]
    configs = sweep_configurations([("a", ["1", "2"]), ("b", ["x", "y", "z"])])
    assert len(configs) == 6 and configs[1] == Configuration((("a", "1"), ("b", "y")))
    assert configs[1].text == "a=1 b=y" and configs[1].overrides() == ["a=1", "b=y"]
    assert sweep_configurations([]) == [Configuration()] and Configuration().text == ""
    for bad in (["r_m"], ["=1"], ["r_m=1,,2"], ["r_m=1", "r_m=2"], ["r_m=1,1"], ["method=a,b"]):
        with pytest.raises(UserError):
            parse_sweeps(bad)


def test_plan_is_archive_major_and_names_are_unique(tmp_path: Path) -> None:
    tasks = plan_batch(["a/x.mcap", "b/x.mcap", "y.mcap"], tmp_path, base_overrides=["lag_s=4"],
                       sweeps=[("r_m", ["2", "4"])])
    assert [(t.trial, t.configuration.text) for t in tasks] == [
        ("x", "r_m=2"), ("x", "r_m=4"), ("x-2", "r_m=2"), ("x-2", "r_m=4"), ("y", "r_m=2"), ("y", "r_m=4")]
    assert tasks[1].overrides == ("lag_s=4", "r_m=4") and Path(tasks[0].archive).is_absolute()
    assert trial_names(["seed-1.mcap", "q/seed-1.mcap"], taken=["seed-1"]) == ["seed-1-2", "seed-1-3"]


@settings(deadline=None, max_examples=60)
@given(st.lists(st.tuples(st.integers(0, 500), st.integers(0, 20)), min_size=1, max_size=6))
def test_seed_ranges_round_trip(spans: list[tuple[int, int]]) -> None:
    seeds: list[int] = []
    parts: list[str] = []
    for start, length in spans:
        new = [s for s in range(start, start + length + 1) if s not in seeds]
        if not new or new != list(range(new[0], new[-1] + 1)):
            continue
        seeds += new
        parts.append(f"{new[0]}-{new[-1]}" if len(new) > 1 else str(new[0]))
    if parts:
        assert parse_seeds(",".join(parts)) == seeds


@settings(deadline=None, max_examples=60)
@given(st.lists(st.text(alphabet="abc019._-", min_size=1, max_size=8), min_size=1, max_size=5))
def test_split_values_round_trip(values: list[str]) -> None:
    assert split_values(",".join(values)) == values
    lists = [f"[{v},{v}]" for v in values]
    assert split_values(",".join(lists)) == lists
    if len(values) > 1:     # one list value has no ';' to say so: that is `--set`, not a sweep
        assert split_values(";".join(f"{v},{v}" for v in values)) == [f"{v},{v}" for v in values]
