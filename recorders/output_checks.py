"""Where `record` may write: never over one of its inputs, never over a file it did not make.

The archive is written to a part file beside the output (`.NAME.part-PID`,
see formats.mcap_writer) and moved over the output name when complete. A
part file left by a process that is gone (kill -9, power loss) is removed by
the next run of any command writing the same output (formats.output_files).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from formats.mcap_records import MAGIC
from formats.output_files import remove_stale_parts

__all__ = ["OutputProblem", "check_output", "remove_stale_parts"]


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
