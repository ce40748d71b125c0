"""Decoding a trial's logs in worker processes and the main one, while the main process writes the archive in order.

The recording step is dominated by decoding, which is independent per log;
writing must stay in one process and in manifest order so that the archive is
byte-for-byte the serial one. So a worker turns one log into a `Captured`:
every write the serial recorder would have made, already serialized (one
bytes blob, one int64 array of (topic, end offset, log time, publish time)),
plus the log's statistics and its bytes (for the attachment: the main process
then never reads the file again). The main process replays it with
`ArchiveWriter.write_blob` (the messages between two channels' first uses a call), registering each channel
at its first message exactly as `ArchiveWriter.write` would.

`WorkerPool` is a small fork pool of our own rather than multiprocessing.Pool
(which hangs when a worker dies) or ProcessPoolExecutor (which cannot say
which task killed it, nor stop its workers on Ctrl-C without private API).
The calling process works too: tasks are claimed one at a time, in task
(manifest) order, from a counter in shared memory, by whichever process is
free, so the main process decodes the next log itself straight into the
archive when no worker has taken it yet, and no process waits on another to
be handed work. That order also keeps the results held ahead of their turn
to about one per process. A worker leaves each result in an anonymous file
(memfd) whose descriptor it passes over its pipe, so it never blocks on a
main process busy decoding; the process sentinels are watched beside the
pipes, so a dead worker is noticed at once and named.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
import sys
import tempfile
import threading
import traceback
from array import array
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from multiprocessing.reduction import recv_handle, send_handle
from typing import Any, Generic, TypeVar, cast

import numpy as np
from google.protobuf.message import Message

from formats.json_messages import JsonMessage
from formats.mcap_writer import SOURCE_CLASSES, ArchiveWriter
from formats.ros_messages import RosMessage
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
    # a source topic's (JSON, ROS) schema, as a message of it without its bytes, by its number in `topics`
    sources: dict[int, JsonMessage | RosMessage] = field(default_factory=dict)
    index: array = field(default_factory=lambda: array("q"))
    blob: bytes = b""
    stats: Any = None  # the log's FileStats, filled by the recorder
    data: bytes | None = None  # the log itself, for its attachment (None: a log decoded in blocks, read again)


class Capture:
    """A stand-in for ArchiveWriter.write that keeps serialized messages instead of writing them."""

    def __init__(self) -> None:
        self._numbers: dict[tuple[str, type[Message]], int] = {}
        self._by_topic: dict[str, int] = {}  # a topic's number, as `channel` last registered it
        self._parts: list[bytes] = []
        self._size = 0
        self.captured = Captured()

    def write(self, topic: str, message: Any, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Serialize and keep one message, as ArchiveWriter.write would write it."""
        cls = type(message)
        number = self._numbers.get((topic, cls))
        if number is None:
            number = self._register(topic, cls, message)
        data = message.SerializeToString()
        self._parts.append(data)
        self._size += len(data)
        self.captured.index.extend(
            (number, self._size, log_time_ns, log_time_ns if publish_time_ns is None else publish_time_ns))

    def channel(self, topic: str, message_class: type[Message]) -> int:
        """Register a topic of protobuf messages for `write_captured`, as ArchiveWriter.channel does."""
        number = self._numbers.get((topic, message_class))
        if number is None:
            number = self._register(topic, message_class, None)
        self._by_topic[topic] = number
        return number

    def write_serialized(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Keep one serialized message of a topic registered with `channel`."""
        self._parts.append(data)
        self._size += len(data)
        self.captured.index.extend((self._by_topic[topic], self._size, log_time_ns,
                                    log_time_ns if publish_time_ns is None else publish_time_ns))

    def write_serialized_batch(self, topic: str, payloads: Sequence[bytes], log_times_ns: Sequence[int],
                               publish_times_ns: Sequence[int] | None = None) -> None:
        """Keep serialized messages of a topic registered with `channel`, as ArchiveWriter's method would write."""
        number = self._by_topic[topic]
        index, parts, size = self.captured.index, self._parts, self._size
        for data, log_time, publish_time in zip(payloads, log_times_ns,
                                                log_times_ns if publish_times_ns is None else publish_times_ns):
            parts.append(data)
            size += len(data)
            index.extend((number, size, log_time, publish_time))
        self._size = size

    def write_blob(self, channel_ids: np.ndarray, blob: bytes | memoryview, ends: np.ndarray, log_times_ns: np.ndarray,
                   publish_times_ns: np.ndarray) -> None:
        """Keep serialized messages of topics registered with `channel` (numbers as it returned them), as
        ArchiveWriter.write_blob would write them: message i is blob[ends[i - 1]:ends[i]] (from 0)."""
        ends = np.asarray(ends, dtype=np.int64)
        if not len(ends):
            return
        self._parts.append(bytes(blob[:int(ends[-1])]))
        table = np.stack([np.asarray(channel_ids, dtype=np.int64), ends + self._size,
                          np.asarray(log_times_ns, dtype=np.int64), np.asarray(publish_times_ns, dtype=np.int64)],
                         axis=1)
        self.captured.index.frombytes(table.tobytes())
        self._size += int(ends[-1])

    def _register(self, topic: str, cls: type[Message], message: Any) -> int:
        if cls in SOURCE_CLASSES:  # its schema travels with it: source topics have no class to find again
            number = self._numbers[(topic, cls)] = len(self.captured.topics)
            self.captured.topics.append((topic, message.schema_name))
            self.captured.sources[number] = replace(message, data=b"")
            return number
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
    """Write one log's captured messages, registering each channel at its first message as write() does: the
    messages between two first uses in one `write_blob`."""
    ids: list[int | None] = [None] * len(captured.topics)
    table = np.frombuffer(captured.index, dtype=np.int64).reshape(-1, _FIELDS)
    if not len(table):
        return
    numbers = table[:, 0]
    # each topic's channel is registered at its first message, as write() registers it: the messages between
    # two such firsts go in one write_blob
    _, firsts = np.unique(numbers, return_index=True)
    cuts = [*sorted(firsts.tolist()), len(table)]
    for first, stop in zip(cuts, cuts[1:]):
        number = int(numbers[first])
        topic, name = captured.topics[number]
        source = captured.sources.get(number)
        ids[number] = writer.channel(topic, MESSAGE_CLASSES[name]) if source is None \
            else writer.source_channel(topic, source)
        start = int(table[first - 1, 1]) if first else 0
        channel_ids = np.array([-1 if i is None else i for i in ids], dtype=np.int64)[numbers[first:stop]]
        writer.write_blob(channel_ids, memoryview(captured.blob)[start:], table[first:stop, 1] - start,
                          table[first:stop, 2], table[first:stop, 3])


class WorkerDied(RuntimeError):
    """A worker process ended without answering (killed, crashed in C, out of memory)."""

    def __init__(self, task: int | None, how: str):
        what = "a worker process" if task is None else f"the worker process doing task {task}"
        super().__init__(f"{what} {how}")
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


_CALLER = -1  # in WorkerPool's claim table: the task is the calling process's own


def _take_next(claims: Any, who: int) -> int | None:
    """The next unclaimed task, marked as `who`'s; the caller holds the lock."""
    task = claims[0]
    if task >= len(claims) - 1:
        return None
    claims[0] = task + 1
    claims[1 + task] = who
    return task


def _anonymous_file() -> int:
    if hasattr(os, "memfd_create"):
        return os.memfd_create("auvreplay-result", os.MFD_CLOEXEC)
    fd, path = tempfile.mkstemp(prefix="auvreplay-result-")  # where there is no memfd: a file gone from view
    os.unlink(path)
    return fd


def _hand_over(conn: Connection, task: int, answer: tuple[bool, Any]) -> None:
    """Leave a task's answer in an anonymous file and pass its descriptor to the main process."""
    fd = _anonymous_file()
    try:
        with open(fd, "wb", closefd=False) as f:
            pickle.dump(answer, f, protocol=pickle.HIGHEST_PROTOCOL)  # large bytes go straight to the file
        conn.send(task)
        send_handle(conn, fd, os.getppid())
    finally:
        os.close(fd)  # the message in flight holds the file now


def _take_over(fd: int) -> tuple[bool, Any]:
    """The answer a worker left in the file `fd` (closed here).

    Unpickling is safe here, as in multiprocessing's own pipes: the file is an
    anonymous memfd that our forked worker wrote and handed over its pipe; no
    archive or log byte from elsewhere is ever unpickled.
    """
    with open(fd, "rb") as f:
        f.seek(0)  # the worker's writes moved the offset the descriptor shares
        return pickle.load(f)


def _worker(number: int, conn: Connection, others: list[Connection], fn: Callable[[int], Any],
            lock: Any, claims: Any) -> None:
    # Ctrl-C is the main process's to handle: it stops the workers itself
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    for other in others:  # parent ends inherited by fork; keeping them would hide the parent's exit
        other.close()
    try:
        while True:
            with lock:
                task = _take_next(claims, number)
            if task is None:
                return  # every task is taken: exit at once, while the main process still writes
            _hand_over(conn, task, _answer(fn, task))
    except (EOFError, OSError):  # the main process is gone
        return


class WorkerPool(Generic[T]):
    """`fn(0) ... fn(tasks - 1)` shared in task order between forked workers and the calling process.

    Each task is claimed once, in increasing order, by whoever is free: a
    worker (the caller gets its result with `result`) or the caller itself
    (`claim`, then it runs the task as it likes). With `caller_first`, task 0
    is the caller's before any worker starts. A context manager: leaving it
    (normally, on an error or on Ctrl-C) stops every worker and waits for it,
    so none is left behind.
    """

    def __init__(self, fn: Callable[[int], T], tasks: int, workers: int, caller_first: bool = False):
        ctx = multiprocessing.get_context("fork")
        self._tasks = tasks
        self._lock = ctx.Lock()
        # [0]: the next task; [1 + t]: who took task t (0 nobody, _CALLER, or worker number from 1)
        self._claims = ctx.RawArray("i", 1 + tasks)
        self._reserved: list[int] = []  # taken for the caller before the forks, handed out by claim()
        first = _take_next(self._claims, _CALLER) if caller_first and tasks else None
        if first is not None:  # always, with a task to take
            self._reserved.append(first)
        self._results: dict[int, int] = {}  # task -> descriptor of the file holding its answer
        self._received: set[int] = set()
        self._live: dict[Connection, tuple[BaseProcess, int]] = {}
        self._all: list[tuple[BaseProcess, Connection]] = []
        sys.stdout.flush()  # else a child could flush the parent's pending output a second time
        sys.stderr.flush()
        try:
            # SIGINT blocked across the forks: a child must not take a KeyboardInterrupt before it ignores them
            old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
            try:
                pipes = [ctx.Pipe() for _ in range(workers)]
                parent_ends = [p for p, _ in pipes]
                for number, (parent, child) in enumerate(pipes, 1):
                    proc = ctx.Process(target=_worker, args=(number, child, parent_ends, fn, self._lock,
                                                             self._claims), daemon=True)
                    proc.start()
                    child.close()
                    self._all.append((proc, parent))
                    self._live[parent] = (proc, number)
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)  # a pending Ctrl-C is raised here
        except BaseException:
            self.close()  # no __exit__ for a constructor that failed: stop what was started
            raise

    def claim(self) -> int | None:
        """The next unclaimed task, now the caller's to run; None when every task is taken."""
        if self._reserved:
            return self._reserved.pop()
        # a worker killed while holding the lock would hold it for ever: look for dead workers meanwhile
        while not self._lock.acquire(timeout=0.1):
            self._poll(0)
        try:
            return _take_next(self._claims, _CALLER)
        finally:
            self._lock.release()

    def ready(self, task: int) -> bool:
        """Whether a worker's result for `task` is in, without waiting."""
        if task not in self._results:
            self._poll(0)
        return task in self._results

    def result(self, task: int) -> T:
        """The result of a worker's `fn(task)`, waiting for it; its exception is raised here."""
        while task not in self._results:
            if task in self._received or self._claims[1 + task] <= 0 or not self._live:
                raise RuntimeError(f"task {task} is not a worker's to answer")
            self._poll(None)
        ok, value = _take_over(self._results.pop(task))
        if not ok:
            raise value
        return value

    def _poll(self, timeout: float | None) -> None:
        if not self._live:
            return
        sentinels = {proc.sentinel: conn for conn, (proc, _) in self._live.items()}
        gone = set()
        for ready in wait([*self._live, *sentinels], timeout):
            # wait() hands back what it was given: a pipe end of ours, or the sentinel (an int) of an ended
            # worker, whose pipe end we read to take in what it sent before it went
            conn = sentinels[ready] if isinstance(ready, int) else cast(Connection, ready)
            if conn in gone:
                continue
            while conn.poll():
                if not self._receive(conn):
                    gone.add(conn)  # its end of the pipe is closed: it has exited or is exiting
                    break
            if not self._live[conn][0].is_alive():
                gone.add(conn)
        for conn in gone:
            proc, number = self._live.pop(conn)
            proc.join(1.0)
            lost = [t for t in range(self._claims[0]) if self._claims[1 + t] == number and t not in self._received]
            if lost or proc.exitcode != 0:
                raise WorkerDied(lost[0] if lost else None, _exit_description(proc.exitcode))

    def _receive(self, conn: Connection) -> bool:
        """Take in one answer from `conn`; False at its end (the worker exited)."""
        try:
            task = conn.recv()
            fd = recv_handle(conn)
        except (EOFError, OSError, pickle.UnpicklingError):
            return False
        self._results[task] = fd
        self._received.add(task)
        return True

    def close(self) -> None:
        """Stop every worker: none takes a new task, busy ones are terminated; all are waited for."""
        if self._lock.acquire(timeout=1.0):  # a worker that died holding it: the others are terminated below
            self._claims[0] = self._tasks
            self._lock.release()
        for proc, number in self._live.values():  # the others exit on their own: no task is left
            if any(self._claims[1 + t] == number and t not in self._received for t in range(self._tasks)):
                proc.terminate()
        for proc, conn in self._all:
            proc.join(2.0)
            if proc.is_alive():
                proc.kill()
                proc.join()
            conn.close()
        for fd in self._results.values():
            os.close(fd)
        self._all, self._live, self._results = [], {}, {}

    def __enter__(self) -> WorkerPool[T]:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
