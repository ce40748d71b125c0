"""What real captures showed (issue 18): EvoLogics' own Unix times used without a host prefix, NovAtel
BESTVEL velocity on a topic of its own (tests/test_recorders_nav.py), Micro-Modem lines all counted."""

from __future__ import annotations

import pytest

from formats.evologics import notifications as ev
from recorders import modem, usbl
from recorders.base import LogContext, Output
from tests import reference_converters as reference

BOOK = {1: "buoy", 3: "auv"}


def _run(convert, data: bytes, vehicle: str = "buoy"):
    items = list(convert(data, LogContext(vehicle, address_book=BOOK, options={"carrier_hz": 75000.0},
                                          sound_speed_mps=1500.0, clock_offset_ns=2_000_000_000)))
    return [i for i in items if isinstance(i, Output)], [i for i in items if not isinstance(i, Output)]


@pytest.mark.parametrize("fast, slow", [(modem.convert_evologics, reference.convert_modem_evologics_reference),
                                        (usbl.convert_evologics, reference.convert_usbl_evologics_reference)])
def test_evologics_own_unix_time_is_used_without_a_host_prefix(fast, slow):
    new = ev.encode_usbllong(3, 100.0, 200.0, -5.0, 0.15, current_time_s=1464207778.481274,
                             measurement_time_s=1464207778.381274)
    old = ev.encode_usbllong(3, 100.0, 200.0, -5.0, 0.15, current_time_s=603.26, measurement_time_s=603.24)
    outs, rejects = _run(fast, (new + old).encode())
    assert len(outs) == 1 and len(rejects) == 1 and "not Unix time" in rejects[0].reason
    # the modem's measurement time and the log's clock offset, less the one-way travel time
    assert outs[0].log_time_ns == 1464207778_381274_000 + 2_000_000_000 - 150_000_000
    assert outs[0].publish_time_ns == outs[0].log_time_ns
    ref_outs, ref_rejects = _run(slow, (new + old).encode())
    assert [(o.topic, o.log_time_ns, o.publish_time_ns, o.message) for o in outs] == \
        [(o.topic, o.log_time_ns, o.publish_time_ns, o.message) for o in ref_outs]
    assert [r.reason for r in rejects] == [r.reason for r in ref_rejects]


def test_every_micromodem_line_of_the_sample_trial_is_counted(tmp_path):
    """The leaders' logs are all $CAMPA (pings heard): each is now an event on /<v>/modem/events, and every
    line of every modem log is archived, rejected or ignored with a reason."""
    from pathlib import Path

    from formats.mcap_reader import ArchiveReader
    from recorders.manifest import load_manifest
    from recorders.record import record

    sample = Path(__file__).resolve().parent.parent / "samples" / "lake_trial"
    summary = record(load_manifest(sample / "trial.toml"), tmp_path / "t.mcap", workers=1)
    modems = [f for f in summary.files if f.format == "micromodem"]
    for f in modems:
        lines = sum(1 for x in (sample / f.path).read_bytes().splitlines() if x.strip())
        assert f.parsed + f.skipped + f.ignored == lines, f.path
    with ArchiveReader(tmp_path / "t.mcap") as r:
        events = [m for m in r.messages(["/leader1/modem/events"])]
    leader1 = next(f for f in modems if f.vehicle == "leader1")
    assert len(events) == leader1.parsed == 350
    assert events[0].message.message == "ping 3 -> 1 heard" and events[0].log_time_ns == 1476237601 * 10**9
