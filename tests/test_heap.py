"""replay.run.heap: the mmap threshold is fixed only for an hour of mission or more, and once."""

import ctypes.util
import subprocess
import sys
from pathlib import Path

import pytest

from replay.run import heap


def test_short_mission_leaves_the_heap_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(heap, "_done", False)
    assert heap.fix_mmap_threshold(1700.0) is False     # the sample trial's span
    assert heap._done is False


def test_long_mission_fixes_it_once() -> None:
    if not (sys.platform.startswith("linux") and ctypes.util.find_library("c")):
        pytest.skip("no glibc here")
    # in a child: the threshold stays fixed for the rest of a process, and this one runs the other tests
    code = ("from replay.run import heap; "
            "print(heap.fix_mmap_threshold(1700.0), heap.fix_mmap_threshold(3600.0), heap.fix_mmap_threshold(60.0))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[1])
    assert out.stdout.split() == ["False", "True", "True"]
