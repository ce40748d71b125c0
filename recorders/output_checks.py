"""Where `record` may write: never over one of its inputs, never over a file it did not make.

The archive is written to a part file beside the output (`.NAME.part-PID`,
see formats.mcap_writer) and moved over the output name when complete. A
part file left by a process that is gone (kill -9, power loss) is removed by
the next run on the same output.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from pathlib import Path

from formats.mcap_records import MAGIC


class OutputProblem(ValueError):
    """An output path `record` refuses, with the reason."""


def check_output(output: Path, inputs: Iterable[Path], replace: bool) -> None:
    """Refuse an output that is an input (the manifest or a log, symlinks followed), a directory, or an
    existing file: one that is not an MCAP archive always, an archive unless `replace`."""
    real = os.path.realpath(output)
    for path in inputs:
        if os.path.realpath(path) == real:
            raise OutputProblem(f"-o {output} is an input of this trial ({path}): not overwritten")
    if output.is_dir():
        raise OutputProblem(f"-o {output} is a directory; name the archive file to write")
    if output.exists() or output.is_symlink():
        if not _is_archive(output):
            raise OutputProblem(f"-o {output} exists and is not an MCAP archive: not overwritten")
        if not replace:
            raise OutputProblem(f"-o {output} exists; --force to replace it")


def _is_archive(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
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
