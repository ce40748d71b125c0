"""Helpers for tests that start a program in its own process group."""

from __future__ import annotations

import os
import signal
import subprocess


def end_group(proc: subprocess.Popen) -> None:
    """SIGTERM the process group, SIGKILL if it lingers; a group already gone is fine."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.wait(timeout=10)
            break
        except subprocess.TimeoutExpired:
            continue
    proc.poll()
