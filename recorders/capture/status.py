"""Per-source counters and the status line: bytes, records, rejects, seconds since the last record."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class SourceStatus:
    """What one live source has given so far."""

    name: str
    url: str
    bytes: int = 0
    reads: int = 0
    records: int = 0
    rejects: int = 0
    opens: int = 0
    last_data_s: float | None = None      # monotonic time of the last bytes
    last_record_s: float | None = None    # monotonic time of the last decoded record
    state: str = "waiting"                # waiting | open | streaming | retrying
    quiet: bool = False
    error: str = ""

    def since_record(self, now_s: float) -> float | None:
        """Seconds since the last decoded record, None before the first."""
        return None if self.last_record_s is None else now_s - self.last_record_s

    def line(self, now_s: float, width: int) -> str:
        """One status line."""
        since = self.since_record(now_s)
        ago = "     -" if since is None else f"{since:5.1f}s"
        note = " QUIET" if self.quiet else ""
        if self.state == "retrying" and self.error:
            note += f" ({self.error})"
        return (f"{self.name:<{width}} {_size(self.bytes):>9} {self.records:>8} rec {self.rejects:>6} rej "
                f"{ago} ago  {self.state}{note}")

    def as_json(self) -> dict:
        """The entry stored in the archive's `capture` metadata."""
        return {"name": self.name, "source": self.url, "bytes": self.bytes, "reads": self.reads,
                "records": self.records, "rejects": self.rejects, "opens": self.opens}


def _size(n: int) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024  # type: ignore[assignment]
    return str(n)


def status_block(statuses: list[SourceStatus], now_s: float) -> list[str]:
    """The status lines of every source, names aligned."""
    width = max((len(s.name) for s in statuses), default=8)
    return [s.line(now_s, width) for s in statuses]
