"""A share of `make fuzz` (tests/fuzz/fuzz.py): every decoder entry point, archive-damage kind, importer and live
source, no exception and no hang."""

from __future__ import annotations

import pytest

from recorders.registry import converters
from tests.fuzz.fuzz import DAMAGE_KINDS, PAYLOAD_TARGETS, archive_cases, decoder_cases, payload_cases, seeds
from tests.fuzz.importers import IMPORTERS, importer_cases
from tests.fuzz.live import live_cases

SEEDS = seeds()


@pytest.mark.parametrize("name", sorted(SEEDS))
def test_decoder_entry_point_never_raises(name):
    data, options = SEEDS[name]
    counts = decoder_cases(name, data, options, 30, base_seed=7)
    assert counts["exceptions"] == 0, "\n".join(counts["examples"])
    assert counts["cases"] == 30 and counts["outputs"] + counts["rejects"] + counts["refused"] > 0


@pytest.mark.parametrize("name", PAYLOAD_TARGETS)
def test_damaged_payloads_in_a_valid_container_never_raise(name):
    counts = payload_cases(name, 300, base_seed=7)
    assert counts["exceptions"] == 0, "\n".join(counts["examples"])
    # the container opens: the damaged messages reach their decoders (decoded or rejected one by one)
    assert counts["refused"] == 0 and counts["outputs"] > 0 and counts["cases"] >= 300  # whole files of damaged payloads


def test_every_converter_has_a_seed():
    assert {f"{s}/{f}" for s, f in converters()} == set(SEEDS)


@pytest.mark.parametrize("kind", DAMAGE_KINDS)
def test_archive_damage_never_raises(kind, tmp_path):
    counts = archive_cases(kind, 80, base_seed=7, folder=tmp_path)
    assert counts["exceptions"] == 0, "\n".join(counts["examples"])
    assert counts["damaged"] > 0  # the damage was seen and said, not silently read


@pytest.mark.parametrize("name", IMPORTERS)
def test_damaged_files_through_record_give_an_archive_or_one_line(name, tmp_path):
    counts = importer_cases(name, 40, base_seed=7, folder=tmp_path)
    assert counts["exceptions"] == 0 and counts["hangs"] == 0, "\n".join(counts["examples"])
    assert counts["cases"] == 40 and counts["clean"] + counts["skips"] > 0   # not all refused at the open


@pytest.mark.parametrize("name", ["capture/stream", "capture/udp", "capture/tail", "capture/tcp-listen",
                                  "capture/stalled"])
def test_hostile_streams_into_capture_never_raise_nor_hang(name, tmp_path):
    counts = live_cases(name, 4 if name == "capture/tcp-listen" else 8, base_seed=7, folder=tmp_path)
    assert counts["exceptions"] == 0 and counts["hangs"] == 0, "\n".join(counts["examples"])
    assert counts["ok"] == counts["cases"]
