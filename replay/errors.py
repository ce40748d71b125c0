"""Errors the command line turns into one clear line and exit code 1, and the one line warning of damage."""

import sys


class UserError(Exception):
    """Bad input from the user (a file, a manifest, an option): message only, exit 1."""


def warn_damage(command: str, warning: str | None) -> None:
    """Print the one line every command ends with when an archive it read had records skipped (none: nothing).

    `warning` is `formats.mcap_reader.ArchiveReader.warning()`, or several of them joined by the command.
    """
    if warning:
        print(f"auvreplay {command}: warning: {warning}", file=sys.stderr)
