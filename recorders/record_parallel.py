"""Decoding a trial's logs in worker processes while the main process writes the archive in order.

The recording step is dominated by decoding, which is independent per log;
writing must stay in one process and in manifest order so that the archive is
byte-for-byte the serial one. So a worker turns one log into a `Captured`:
every write the serial recorder would have made, already serialized (one
bytes blob, one int64 array of (topic, end offset, log time, publish time)),
plus the log's statistics. The main process replays it with
`ArchiveWriter.write_serialized`, registering each channel at its first
message exactly as `ArchiveWriter.write` would.

`WorkerPool` is a small fork pool of our own rather than multiprocessing.Pool
(which hangs when a worker dies) or ProcessPoolExecutor (which cannot say
which task killed it, nor stop its workers on Ctrl-C without private API):
one pipe per worker, one task in flight per worker, and the process sentinels
watched beside the pipes, so a dead worker is noticed at once and named.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
import sys
import threading
import traceback
from array import array
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from typing import Any, Callable, Generic, TypeVar

from formats.mcap_writer import ArchiveWriter
from formats.schemas import MESSAGE_CLASSES

T = TypeVar("T")
_FIELDS = 4  # per message in Captured.index: topic number, end offset in the blob, log time, publish time


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS tells, else os.cpu_count())."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def can_fork() -> bool:
    """Whether worker processes can be forked here: a fork start method, and not inside a daemonic worker."""
    # multiprocessing refuses children to daemonic processes (a batch's pool workers, say)
    return "fork" in multiprocessing.get_all_start_methods() and not multiprocessing.current_process().daemon


def only_thread() -> bool:
    """Whether this process runs a single thread: fork copies only the caller, not the locks others hold."""
    return threading.active_count() == 1


@dataclass
class Captured:
    """One log's archive writes, serialized: the topics, a blob of message bytes and their index."""

    topics: list[tuple[str, str]] = field(default_factory=list)  # (topic, schema name), by first use
    index: array = field(default_factory=lambda: array("q"))
    blob: bytes = b""
    stats: Any = None  # the log's FileStats, filled by the recorder


class Capture:
    """A stand-in for ArchiveWriter.write that keeps serialized messages instead of writing them."""

    def __init__(self) -> None:
        self._numbers: dict[tuple[str, type], int] = {}
        self._parts: list[bytes] = []
        self._size = 0
        self.captured = Captured()

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Serialize and keep one message, as ArchiveWriter.write would write it."""
        cls = type(message)
        number = self._numbers.get((topic, cls))
        if number is None:
            number = self._register(topic, cls)
        data = message.SerializeToString()
        self._parts.append(data)
        self._size += len(data)
        self.captured.index.extend(
            (number, self._size, log_time_ns, log_time_ns if publish_time_ns is None else publish_time_ns))

    def _register(self, topic: str, cls: type) -> int:
        name = cls.DESCRIPTOR.full_name
        # the main process finds the class again by name (foxglove's classes do not pickle)
        if MESSAGE_CLASSES.get(name) is not cls:
            raise TypeError(f"{topic}: {name} is not an archive message class (formats.schemas.MESSAGE_CLASSES)")
        number = self._numbers[(topic, cls)] = len(self.captured.topics)
        self.captured.topics.append((topic, name))
        return number

    def finish(self, stats: Any) -> Captured:
        """The captured writes with the log's statistics, the blob joined once."""
        self.captured.blob = b"".join(self._parts)
        self._parts = []
        self.captured.stats = stats
        return self.captured


def write_captured(writer: ArchiveWriter, captured: Captured) -> None:
    """Write one log's captured messages, registering each channel at its first message as write() does."""
    ids: list[int | None] = [None] * len(captured.topics)
    index, blob = captured.index, memoryview(captured.blob)
    write = writer.write_serialized
    start = 0
    for k in range(0, len(index), _FIELDS):
        number, end = index[k], index[k + 1]
        cid = ids[number]
        if cid is None:
            topic, name = captured.topics[number]
            cid = ids[number] = writer.channel(topic, MESSAGE_CLASSES[name])
        write(cid, blob[start:end], index[k + 2], index[k + 3])
        start = end


class WorkerDied(RuntimeError):
    """A worker process ended without answering (killed, crashed in C, out of memory)."""

    def __init__(self, task: int, how: str):
        super().__init__(f"the worker process doing task {task} {how}")
        self.task, self.how = task, how


def _exit_description(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return f"was killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"was killed by signal {-code}"
    return f"exited with status {code}"


def _answer(fn: Callable[[int], Any], task: int) -> tuple[bool, Any]:
    """(True, result) or (False, exception), the exception made picklable and noted with its traceback."""
    try:
        return True, fn(task)
    except Exception as exc:  # noqa: BLE001 - re-raised in the main process
        exc.add_note("in a worker process:\n" + "".join(traceback.format_exception(exc)).rstrip())
        try:
            pickle.dumps(exc)
        except Exception:  # noqa: BLE001 - an exception class that does not pickle
            exc = RuntimeError(f"{type(exc).__name__}: {exc}")
        return False, exc


def _worker(conn: Connection, others: list[Connection], fn: Callable[[int], Any]) -> None:
    # Ctrl-C is the main process's to handle: it stops the workers itself
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    for other in others:  # parent ends inherited by fork; keeping them would hide the parent's exit
        other.close()
    while True:
        try:
            task = conn.recv()
            if task is None:
                return
            conn.send(_answer(fn, task))
        except (EOFError, OSError):  # the main process is gone
            return


class WorkerPool(Generic[T]):
    """`fn(0) ... fn(tasks - 1)` in forked worker processes, results taken back in any order.

    A context manager: leaving it (normally, on an error or on Ctrl-C) stops
    every worker and waits for it, so none is left behind.
    """

    def __init__(self, fn: Callable[[int], T], tasks: int, workers: int):
        self._next = 0
        self._tasks = tasks
        self._results: dict[int, tuple[bool, Any]] = {}
        self._busy: dict[Connection, tuple[multiprocessing.Process, int]] = {}
        self._idle: list[tuple[multiprocessing.Process, Connection]] = []
        self._all: list[tuple[multiprocessing.Process, Connection]] = []
        ctx = multiprocessing.get_context("fork")
        sys.stdout.flush()  # else a child could flush the parent's pending output a second time
        sys.stderr.flush()
        try:
            # SIGINT blocked across the forks: a child must not take a KeyboardInterrupt before it ignores them
            old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
            try:
                pipes = [ctx.Pipe() for _ in range(workers)]
                parent_ends = [p for p, _ in pipes]
                for parent, child in pipes:
                    proc = ctx.Process(target=_worker, args=(child, parent_ends, fn), daemon=True)
                    proc.start()
                    child.close()
                    self._all.append((proc, parent))
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)  # a pending Ctrl-C is raised here
            for proc, conn in self._all:
                self._dispatch(proc, conn)
        except BaseException:
            self.close()  # no __exit__ for a constructor that failed: stop what was started
            raise

    def _dispatch(self, proc: multiprocessing.Process, conn: Connection) -> None:
        if self._next < self._tasks:
            task = self._next
            try:
                conn.send(task)
            except OSError:  # the worker is gone
                proc.join(1.0)
                raise WorkerDied(task, _exit_description(proc.exitcode)) from None
            self._busy[conn] = (proc, task)
            self._next += 1
        else:
            self._idle.append((proc, conn))

    def result(self, task: int) -> T:
        """The result of `fn(task)`, waiting for it; its exception is raised here."""
        self._poll(0)  # take in whatever is ready, so no worker waits on a full pipe
        while task not in self._results:
            if not self._busy:
                raise RuntimeError(f"task {task} was never dispatched")
            self._poll(None)
        ok, value = self._results.pop(task)
        if not ok:
            raise value
        return value

    def _poll(self, timeout: float | None) -> None:
        sentinels = {proc.sentinel: conn for conn, (proc, _) in self._busy.items()}
        ready = wait([*self._busy, *sentinels], timeout)
        if not ready:
            return
        answered = set()
        for conn in [c for c in ready if c in self._busy]:
            proc, task = self._busy[conn]
            try:
                self._results[task] = conn.recv()
            except (EOFError, OSError, pickle.UnpicklingError):
                proc.join(1.0)
                raise WorkerDied(task, _exit_description(proc.exitcode)) from None
            answered.add(conn)
            del self._busy[conn]
            self._dispatch(proc, conn)
        for sentinel in ready:
            conn = sentinels.get(sentinel)
            if conn is not None and conn not in answered and not conn.poll():
                proc, task = self._busy[conn]
                proc.join(1.0)
                raise WorkerDied(task, _exit_description(proc.exitcode))

    def close(self) -> None:
        """Stop every worker: idle ones are told to exit, busy ones are terminated; all are waited for."""
        for proc, conn in self._all:
            if conn in self._busy or not proc.is_alive():
                proc.terminate()
            else:
                try:
                    conn.send(None)
                except OSError:
                    proc.terminate()
        for proc, conn in self._all:
            proc.join(2.0)
            if proc.is_alive():
                proc.kill()
                proc.join()
            conn.close()
        self._all, self._busy, self._idle = [], {}, []

    def __enter__(self) -> "WorkerPool[T]":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
