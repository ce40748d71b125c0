"""Shared fixtures (small, built in the test) and the hypothesis profiles.

`make test` runs hypothesis under the "ci" profile: derandomized (each test's
examples are drawn from a seed derived from the test itself, and no example
database is read), no deadline, so the same commit gives the same result on
every run and machine. Random exploration is `make fuzz`: HYPOTHESIS_PROFILE=fuzz
draws fresh examples each run, FUZZ_FACTOR times as many as each test asks
for; a failing case it finds is pinned in its test with `@example`.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

FUZZ_FACTOR = 10
settings.register_profile("ci", max_examples=100, derandomize=True, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])  # too_slow is a timing: never red by chance
settings.register_profile("fuzz", max_examples=100 * FUZZ_FACTOR, derandomize=False, database=None, deadline=None,
                          print_blob=True, suppress_health_check=[HealthCheck.too_slow])
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
settings.load_profile(PROFILE)

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture
def venv_bin() -> Path:
    """The bin directory of the interpreter running the tests (console scripts live there)."""
    return Path(sys.executable).parent


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Under the fuzz profile, a test's own `@settings(max_examples=n)` becomes n x FUZZ_FACTOR."""
    if PROFILE != "fuzz":
        return
    for item in items:
        test = getattr(item, "obj", None)
        own = getattr(test, "_hypothesis_internal_use_settings", None)
        if own is not None and own.max_examples < settings.default.max_examples:
            test._hypothesis_internal_use_settings = settings(own, max_examples=own.max_examples * FUZZ_FACTOR)
