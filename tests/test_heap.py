"""replay.run.heap: the mmap threshold is fixed only for an hour of mission or more, and once."""

import ctypes.util
import sys

import pytest

from replay.run import heap


def test_short_mission_leaves_the_heap_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(heap, "_done", False)
    assert heap.fix_mmap_threshold(1700.0) is False     # the sample trial's span
    assert heap._done is False


def test_long_mission_fixes_it_once(monkeypatch: pytest.MonkeyPatch) -> None:
    if not (sys.platform.startswith("linux") and ctypes.util.find_library("c")):
        pytest.skip("no glibc here")
    monkeypatch.setattr(heap, "_done", False)
    assert heap.fix_mmap_threshold(3600.0) is True
    assert heap.fix_mmap_threshold(60.0) is True        # set for the rest of the process
