"""Mission seconds, the one time base a reviewer reads: seconds from the trial start, beside UTC.

The trial starts at the first message of the trial archive (what the engine
takes as t = 0); a results archive records that instant in its `run`
metadata (`trial_start_ns`), since its own first message comes later.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from formats.mcap_reader import ArchiveReader
from formats.units import NS
from replay.errors import UserError


def trial_start_ns(reader: ArchiveReader, run: dict[str, Any] | None = None) -> int:
    """The trial start of an open archive: its run's `trial_start_ns`, else its first message's time."""
    meta = run if run is not None else reader.metadata_json("run")
    if meta and str(meta.get("trial_start_ns", "")).lstrip("-").isdigit():
        return int(meta["trial_start_ns"])
    start = reader.summary().start_ns
    if start is None:
        raise UserError(f"{reader.path}: the archive holds no messages")
    return int(start)


def mission_seconds(time_ns: np.ndarray | int, start_ns: int) -> np.ndarray:
    """Seconds from the trial start of UTC ns times (exact to the ns before the division)."""
    return (np.asarray(time_ns, dtype="int64") - np.int64(start_ns)) / NS
