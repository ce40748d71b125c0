"""Foxglove LocationFix in our archives shows up as GeoPoints in Rerun, with no plugin."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from formats import schemas as S
from formats.mcap_writer import ArchiveWriter

T0 = 1_476_259_200_000_000_000


def test_rerun_mcap_convert_yields_geopoints(tmp_path, venv_bin):
    rerun_cli = venv_bin / "rerun"
    if not rerun_cli.exists():
        pytest.fail("the rerun CLI that rerun-sdk installs is missing")
    from rerun.chunk import RrdReader

    mcap_path, rrd_path = tmp_path / "x.mcap", tmp_path / "x.rrd"
    lats = 45.7 + np.arange(30) * 1e-5
    with ArchiveWriter(mcap_path) as w:
        for i, lat in enumerate(lats):
            w.write("/x/gps", S.location_fix(T0 + i * 10**9, "x", float(lat), 126.6, 0.0), T0 + i * 10**9)
    subprocess.run([str(rerun_cli), "mcap", "convert", str(mcap_path), "-o", str(rrd_path)],
                   check=True, capture_output=True)
    points = []
    for chunk in RrdReader(rrd_path).stream().to_chunks():
        if chunk.entity_path != "/x/gps":
            continue
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.endswith("GeoPoints:positions"):
                for cell in batch.column(name).to_pylist():
                    points.extend(cell)
    assert len(points) == 30
    got = np.array(sorted(points))
    np.testing.assert_allclose(got[:, 0], lats, atol=1e-9)
    np.testing.assert_allclose(got[:, 1], 126.6, atol=1e-9)
