"""The one rule for files a command writes: never replace an existing file it did not create in the same call.

Every command claims all of its outputs before it writes the first of them, so
a file that exists at that moment was made by someone else (an earlier call, a
colleague's run) and is refused with one line naming it; `--force` replaces it.
Files a call creates after its claim are its own to write and rename.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from replay.errors import UserError


def claim_output(path: str | os.PathLike[str], force: bool = False) -> Path:
    """`path` as a Path when it may be written: it does not exist, or `force` is set and it is not a directory."""
    out = Path(path)
    if out.is_dir():
        raise UserError(f"{out} is a directory, not a file to write")
    if (out.exists() or out.is_symlink()) and not force:
        raise UserError(f"{out} exists: not replaced (give --force to replace it, or another name)")
    return out


def claim_outputs(paths: Iterable[str | os.PathLike[str] | None], force: bool = False) -> list[Path]:
    """Every given path claimed (None skipped) before any is written, so a refusal leaves nothing half-done."""
    return [claim_output(p, force) for p in paths if p is not None and str(p) != ""]


def claim_directory(path: str | os.PathLike[str], force: bool = False) -> Path:
    """A directory to write into: missing or empty, or any directory with `force`; never a file."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UserError(f"{out} exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise UserError(f"{out} is not empty: nothing written (give --force to write into it)")
    return out
