"""The committed sample trial: it is `simulate --seed 0`, it records cleanly, and its statistics match the source."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest

from samples.scenario import Scenario
from samples.simulator import simulate_trial
from samples.writer import render

SAMPLE = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
T0_NS = 1476237600 * 1_000_000_000  # 2016-10-12T02:00:00Z, the trial start
ROLE_TOPICS = {
    "leader": ("gps", "gps/status", "ins", "dvl"),
    "follower": ("gps", "gps/status", "ins", "dvl", "modem/range"),
    "buoy": ("gps", "gps/status", "usbl"),
}


def _csv(name: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO((SAMPLE / name).read_text())))


def test_sample_is_simulate_seed_0_byte_for_byte():
    expected = render(simulate_trial(Scenario(), 0))
    on_disk = {p.relative_to(SAMPLE).as_posix(): p.read_bytes() for p in SAMPLE.rglob("*") if p.is_file()}
    assert sorted(on_disk) == sorted(expected), "regenerate: auvreplay simulate --seed 0 -o samples/lake_trial --force"
    for rel, data in expected.items():
        assert on_disk[rel] == data, f"{rel} differs from simulate --seed 0"
    assert sum(len(d) for d in on_disk.values()) < 5_000_000


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    """The sample recorded into an MCAP archive, with the recording summary."""
    from formats.mcap_reader import ArchiveReader
    from recorders.manifest import load_manifest
    from recorders.record import record

    out = tmp_path_factory.mktemp("sample") / "lake.mcap"
    manifest = load_manifest(SAMPLE / "trial.toml")
    summary = record(manifest, out)
    with ArchiveReader(out) as reader:
        yield manifest, summary, reader


def test_recording_populates_every_topic_with_no_diagnostics(archive):
    manifest, summary, reader = archive
    topics = reader.summary().topics
    assert summary.skipped == 0 and all(f.bad_checksum == 0 for f in summary.files)
    assert "/diagnostics" not in topics
    for v in manifest.vehicles:
        for suffix in ROLE_TOPICS[v.role]:
            assert topics.get(f"/{v.name}/{suffix}", {}).get("count", 0) > 0, f"/{v.name}/{suffix}"


def _seconds(df) -> np.ndarray:
    return (df["timestamp"].astype("int64").to_numpy() - T0_NS) / 1e9


def test_recorded_gps_fixes_are_within_5_sigma_of_truth(archive):
    from formats.geodesy import LocalFrame

    _, _, reader = archive
    frame = LocalFrame(45.70, 126.60)
    truth = _csv("truth.csv")
    for name in ("leader1", "leader2", "follower"):
        rows = [r for r in truth if r["vehicle"] == name]
        t = np.array([float(r["t_s"]) for r in rows])
        te, tn = frame.to_local(np.array([float(r["latitude_deg"]) for r in rows]),
                                np.array([float(r["longitude_deg"]) for r in rows]))
        fix = reader.to_dataframe(f"/{name}/gps")
        ts = _seconds(fix)
        e, n = frame.to_local(fix["latitude"].to_numpy(), fix["longitude"].to_numpy())
        sigma = 1.8 / np.sqrt(2.0)  # per axis, for 1.8 m RMS horizontal
        assert len(ts) == 1701
        assert np.abs(e - np.interp(ts, t, te)).max() < 5 * sigma
        assert np.abs(n - np.interp(ts, t, tn)).max() < 5 * sigma


def test_recorded_ranges_are_truth_plus_noise_outside_injected_anomalies(archive):
    _, _, reader = archive
    rng = reader.to_dataframe("/follower/modem/range")
    truth = _csv("ranges.csv")
    t_true = np.array([float(r["t_s"]) for r in truth])
    t = _seconds(rng)
    assert len(t) == len(truth) and np.abs(t - t_true).max() < 1e-3
    err = rng["range_m"].to_numpy() - np.array([float(r["range_true_m"]) for r in truth])
    clean = np.array([r["injected"] == "" for r in truth])
    assert np.abs(err[clean]).max() < 5 * 3.0
    assert err[clean].std() == pytest.approx(3.0, rel=0.1)
    assert np.abs(err[~clean]).max() > 15.0  # the anomalies are in the logs too
    assert list(rng["source"].iloc[:2]) == ["leader1", "leader2"]


def test_recorded_statistics_match_the_source_trial(archive):
    """About 340 ranges per leader; ~462 epochs in 600-1700 s, ~57 of them anomalous (docs/design.md section 15)."""
    from samples.anomalies import gps_range, horizontal_range, label

    _, _, reader = archive
    rng = reader.to_dataframe("/follower/modem/range")
    t = _seconds(rng)
    src = rng["source"].to_numpy()
    for leader in ("leader1", "leader2"):
        assert abs((src == leader).sum() - 340) <= 0.05 * 340
    test = t > 600.0
    assert abs(test.sum() - 462) <= 0.05 * 462
    fixes = {n: reader.to_dataframe(f"/{n}/gps") for n in ("leader1", "leader2", "follower")}
    depth = {n: float(reader.to_dataframe(f"/{n}/ins")["depth_m"].median()) for n in fixes}
    f = fixes["follower"]
    ft = _seconds(f)
    z_gps = np.empty(len(t))
    z = np.empty(len(t))
    for leader in ("leader1", "leader2"):
        m = src == leader
        lf = fixes[leader]
        lt = _seconds(lf)
        z_gps[m] = gps_range(np.interp(t[m], ft, f["latitude"]), np.interp(t[m], ft, f["longitude"]),
                             np.interp(t[m], lt, lf["latitude"]), np.interp(t[m], lt, lf["longitude"]),
                             np.full(m.sum(), depth["follower"]), np.full(m.sum(), depth[leader]))
        z[m] = horizontal_range(rng["range_m"].to_numpy()[m], depth["follower"], depth[leader])
    labels = label(z_gps, z)
    assert (depth["follower"], depth["leader1"]) == (2.5, 1.5)
    assert abs(int(labels[test].sum()) - 57) <= 0.05 * 57
