"""Writing a file under its final name only once complete, never over a file another process made.

Every command that writes an archive goes through `OutputClaim`:

1. it holds an exclusive `flock` on `.NAME.lock` beside the output, so a second
   process writing the same output at the same time is refused with one line
   (the kernel drops the lock when its holder dies, so kill -9 leaves no claim);
2. under the lock it refuses an existing output unless replacing is allowed, and
   removes the part files (`.NAME.part-PID`) of writers that are gone;
3. it writes its own part file, created with O_EXCL, and publishes it under the
   final name: `os.replace` when replacing is allowed, otherwise a hard link,
   which fails instead of replacing a file that appeared meanwhile.
"""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path
from typing import BinaryIO

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: the link-based publish still never replaces
    fcntl = None  # type: ignore[assignment]


class OutputBusy(OSError):
    """Another live process is writing the same output."""


class OutputExists(FileExistsError):
    """The output exists and replacing it was not asked for."""


def exists_message(output: Path) -> str:
    """The one line of the no-overwrite rule (as replay.run.outputs words it)."""
    return f"{output} exists: not replaced (give --force to replace it, or another name)"


def part_name(output: Path, pid: int | None = None) -> Path:
    """The part file a process writes `output` through: `.NAME.part-PID` beside it."""
    return output.with_name(f".{output.name}.part-{os.getpid() if pid is None else pid}")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    except (OverflowError, OSError):
        return False
    return True


def remove_stale_parts(output: Path) -> list[Path]:
    """Remove the part files of `output` whose writing process is no longer alive; returns them."""
    pattern = re.compile(rf"^\.{re.escape(output.name)}\.part-(\d+)$")
    removed: list[Path] = []
    try:
        names = os.listdir(output.parent if str(output.parent) else ".")
    except OSError:
        return removed
    for name in names:
        m = pattern.match(name)
        if m is None:
            continue
        pid = int(m.group(1))
        if pid != os.getpid() and not _alive(pid):
            part = output.with_name(name)
            try:
                if part.is_file() and not part.is_symlink():
                    part.unlink()
                    removed.append(part)
            except OSError:
                pass
    return removed


class OutputClaim:
    """The right to write `output`: a lock held until `publish` or `abandon`.

    Raises OutputBusy when another process holds it, OutputExists when `output`
    exists and `replace` is false, IsADirectoryError when it is a directory.
    """

    def __init__(self, output: str | os.PathLike[str], replace: bool = False, part: Path | None = None):
        self.output = Path(output)
        self.replace = replace
        self.part = part if part is not None else part_name(self.output)
        self.lock_path = self.output.with_name(f".{self.output.name}.lock")
        self._fd: int | None = None
        self._lock()
        try:
            if self.output.is_dir():
                raise IsADirectoryError(f"{self.output} is a directory, not a file to write")
            if not replace and (self.output.exists() or self.output.is_symlink()):
                raise OutputExists(exists_message(self.output))
            self.removed = remove_stale_parts(self.output)
        except BaseException:
            self._unlock()
            raise

    def _lock(self) -> None:
        if fcntl is None:  # pragma: no cover
            return
        while True:
            fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                holder = os.read(fd, 32).decode("ascii", "replace").strip()
                os.close(fd)
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise
                who = f" (process {holder})" if holder.isdigit() else ""
                raise OutputBusy(f"{self.output} is being written by another process{who}: "
                                 "not replaced; wait for it to finish or choose another name") from None
            # the holder before us may have removed the lock file after we opened it: lock the one in place
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.lock_path))
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                self._fd = fd
                return
            os.close(fd)

    def _unlock(self) -> None:
        if self._fd is not None:
            try:
                self.lock_path.unlink(missing_ok=True)  # while still held: no one can lock this file after
            except OSError:
                pass
            os.close(self._fd)
            self._fd = None

    def open_part(self) -> BinaryIO:
        """The part file, created now (O_EXCL: a file of that name is never taken over)."""
        fd = os.open(self.part, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        return os.fdopen(fd, "wb")

    def publish(self) -> Path:
        """Move the complete part file to the output name; the claim ends."""
        try:
            if self.replace:
                os.replace(self.part, self.output)
            else:
                publish_new(self.part, self.output)
        finally:
            self._unlock()
        return self.output

    def abandon(self, keep_part: bool = False) -> None:
        """End the claim without publishing; the part file is removed unless `keep_part`."""
        try:
            if not keep_part:
                self.part.unlink(missing_ok=True)
        finally:
            self._unlock()


def publish_new(temp: Path, output: Path) -> None:
    """Move `temp` to `output` unless `output` exists (then OutputExists, `temp` left in place)."""
    try:
        os.link(temp, output)
    except FileExistsError:
        raise OutputExists(exists_message(output)) from None
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
            raise
        # a file system without hard links: the check and the rename are not one step, the lock covers it
        if output.exists() or output.is_symlink():
            raise OutputExists(exists_message(output)) from None
        os.replace(temp, output)
        return
    os.unlink(temp)


def write_new_file(output: str | os.PathLike[str], data: bytes, replace: bool = False) -> Path:
    """Write a small file whole under its name (readers never see it half-written), under the same claim."""
    claim = OutputClaim(output, replace)
    try:
        with claim.open_part() as f:
            f.write(data)
    except BaseException:
        claim.abandon()
        raise
    return claim.publish()
