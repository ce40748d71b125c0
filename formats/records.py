"""Record types shared by every vendor decoder; imports nothing of ours."""

from __future__ import annotations

from dataclasses import dataclass


class FormatError(ValueError):
    """A file or record that cannot be decoded at all."""


def library_error(exc: BaseException) -> str:
    """A third-party reader's exception as one line, "Type: message" (a YAML error spans several lines)."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


@dataclass(frozen=True, slots=True)
class Where:
    """Where a record came from: byte offset, 1-based line (text formats), host time, 1-based message number.

    `message` is set by container formats (bags, tlogs) whose records are messages rather than bytes or lines.
    """

    offset: int
    line: int | None = None
    host_time_ns: int | None = None
    message: int | None = None

    def describe(self) -> str:
        """Human-readable position, e.g. 'line 12', 'byte 4096' or 'message 7'."""
        if self.message is not None:
            return f"message {self.message}"
        return f"line {self.line}" if self.line is not None else f"byte {self.offset}"


@dataclass(frozen=True, slots=True)
class Reject:
    """A record a decoder skipped: where it was, why, and whether a checksum failed."""

    where: Where
    reason: str
    bad_checksum: bool = False
