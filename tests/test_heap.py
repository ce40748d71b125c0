"""replay.run.heap: the mmap threshold is fixed once, and saying so again changes nothing."""

import ctypes.util
import sys

import pytest

from replay.run.heap import fix_mmap_threshold


def test_fixed_once_and_idempotent() -> None:
    first = fix_mmap_threshold()
    assert fix_mmap_threshold() is first
    if sys.platform.startswith("linux") and ctypes.util.find_library("c"):
        assert first is True
    else:
        pytest.skip("no glibc here")
