"""Shared fixtures: small, built in the test."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture
def venv_bin() -> Path:
    """The bin directory of the interpreter running the tests (console scripts live there)."""
    return Path(sys.executable).parent
