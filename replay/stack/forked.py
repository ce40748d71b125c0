"""Run groups of independent jobs side by side: the first group in this process, the others in forked children.

The detectors trained at t_a are many small numpy calls each, bound by the
interpreter, not by BLAS: on threads they only contend for the GIL. A
forked child has its own interpreter and the parent's memory as it was, so
a job runs there exactly as it would here (same code, same data, same
seed), and only its result comes back, pickled through a pipe. A job
whose result does not come back (its child died, or the result does not
pickle) runs here afterwards, so the outcome never depends on the children.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Callable, Sequence
from typing import TypeVar

T = TypeVar("T")


def can_fork() -> bool:
    """True where `os.fork` exists (POSIX)."""
    return hasattr(os, "fork")


def balance(costs: Sequence[float], groups: int) -> list[list[int]]:
    """Job indices in at most `groups` non-empty groups of about equal cost: the costliest first, each to the
    lightest group so far (ties by index, so the split is the same every time); indices ascending per group."""
    n = max(1, min(groups, len(costs)))
    load = [0.0] * n
    out: list[list[int]] = [[] for _ in range(n)]
    for i in sorted(range(len(costs)), key=lambda k: (-costs[k], k)):
        g = min(range(n), key=lambda k: (load[k], k))
        out[g].append(i)
        load[g] += costs[i]
    return [sorted(g) for g in out if g]


def run_groups(job: Callable[[int], T], groups: Sequence[Sequence[int]]) -> dict[int, T]:
    """job(i) for every index of every group: groups[0] here, each other group in a forked child, side by side.

    Without fork, or for a job whose result did not come back from its child, job(i) runs here.
    """
    children = [_spawn(job, g) for g in groups[1:]] if can_fork() else []
    out: dict[int, T] = {i: job(i) for i in (groups[0] if groups else ())}
    for child in children:
        out.update(_collect(child))
    for group in groups:
        out.update({i: job(i) for i in group if i not in out})
    return out


def _spawn(job: Callable[[int], T], group: Sequence[int]) -> tuple[int, int, Sequence[int]]:
    """Fork a child that runs the group's jobs and writes their pickled results to a pipe; (pid, read end, group)."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:     # the child: never returns into the caller's code, never flushes the parent's buffers
        status = 1
        try:
            os.close(read)
            parts = []
            for i in group:
                try:
                    parts.append(pickle.dumps(job(i), protocol=pickle.HIGHEST_PROTOCOL))
                except Exception:  # noqa: BLE001 - this job's result stays None; the parent runs it
                    parts.append(b"")
            _write_all(write, pickle.dumps(parts, protocol=pickle.HIGHEST_PROTOCOL))
            status = 0
        finally:
            os._exit(status)
    os.close(write)
    return pid, read, group


def _collect(child: tuple[int, int, Sequence[int]]) -> dict[int, T]:
    """The results a child wrote, by job index (those it could not give left out); waits for it to end."""
    pid, read, group = child
    chunks = []
    try:
        while chunk := os.read(read, 1 << 20):
            chunks.append(chunk)
    finally:
        os.close(read)
        os.waitpid(pid, 0)
    out: dict[int, T] = {}
    try:
        # only our own forked child wrote this pipe (never a file, archive or log byte): pickle is safe here
        parts = pickle.loads(b"".join(chunks))
        for i, part in zip(group, parts, strict=False):
            if part:
                out[i] = pickle.loads(part)
    except Exception:  # noqa: BLE001 - the child died before writing everything: the rest run here
        pass
    return out


def _write_all(fd: int, data: bytes) -> None:
    """Write every byte (a pipe takes a large write in parts), then close."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]
    os.close(fd)
