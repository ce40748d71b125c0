"""The notebook API: open an archive, run a configuration, get metrics and per-epoch results as DataFrames.

    from replay import api
    archive = api.open_archive("trial.mcap")          # ArchiveReader: messages(), to_dataframe(topic)
    run = api.run("trial.mcap", {"anfis.model": "shared", "r_m": 2.5})
    api.metrics_frame(run)                            # one row per method
    run.review.detections, run.review.errors          # per epoch / per GPS fix
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from formats.mcap_reader import ArchiveReader
from replay.run.config import load_config
from replay.run.metrics import metrics_table
from replay.run.pipeline import RunOutcome, replay_archive


def open_archive(path: str | Path) -> ArchiveReader:
    """An archive reader (use as a context manager, or close it)."""
    return ArchiveReader(path)


def run(archive: str | Path, overrides: Mapping[str, Any] | Sequence[str] = (), config: str | Path | None = None,
        output: str | Path | None = None) -> RunOutcome:
    """Replay with the defaults, a TOML file and overrides ({"r_m": 2.5} or ["r_m=2.5"]); review data kept.

    The defaults are those of docs/design.md sections 7-14.

    No results file is written unless `output` is given; a program asked for it, so it replaces one there.
    """
    items = [f"{k}={v}" for k, v in overrides.items()] if isinstance(overrides, Mapping) else list(overrides)
    cfg = load_config(config, items)
    return replay_archive(archive, cfg, output, write_output=output is not None, review=True, force=True)


def metrics_frame(outcome: RunOutcome) -> pd.DataFrame:
    """The run's metrics, one row per method (the result keys of docs/design.md section 6 as columns)."""
    return pd.DataFrame(metrics_table(outcome.metrics)).set_index("method")
