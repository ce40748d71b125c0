"""Delimited text logs (CSV and the like): rows as dicts keyed by the header's column names."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from dataclasses import dataclass

from .log_blocks import LogText, blocks_in
from .records import Reject, Where


@dataclass(frozen=True, slots=True)
class Row:
    """One data row: column name -> text, and where it was."""

    values: dict[str, str]
    where: Where


def decode(data: LogText, delimiter: str | None = None, comment: str = "#") -> Iterator[Row | Reject]:
    """Rows of a delimited file with a header line; short or long rows are Rejects.

    The delimiter is sniffed from the header (comma, semicolon, tab, '|') unless given. The log may come in
    blocks (`formats.log_blocks`): the header, the line count and the offsets go on from one to the next.
    """
    header: list[str] | None = None
    delim = delimiter or ","
    number = pos = 0  # lines (as `str.splitlines` cuts them) and decoded bytes before the block
    for block in blocks_in(data):
        text = block.data.decode("utf-8-sig" if block.offset == 0 else "utf-8", errors="replace")
        for line in text.splitlines(keepends=True):
            start = pos
            number += 1
            pos += len(line.encode("utf-8", errors="replace"))
            if not line.strip() or line.lstrip().startswith(comment):
                continue
            if header is None:
                delim = delimiter or max(",;\t|", key=line.count)
                header = [h.strip() for h in next(csv.reader([line], delimiter=delim))]
                continue
            yield _row(line, header, delim, Where(start, number))


def _row(line: str, header: list[str], delim: str, where: Where) -> Row | Reject:
    """One data line as a Row, or a Reject saying why it is none."""
    try:
        cells = next(csv.reader(io.StringIO(line), delimiter=delim))
    except (csv.Error, StopIteration) as exc:
        return Reject(where, f"unreadable row ({exc})")
    if len(cells) != len(header):
        return Reject(where, f"row has {len(cells)} columns, header has {len(header)}")
    return Row(dict(zip(header, (c.strip() for c in cells))), where)
