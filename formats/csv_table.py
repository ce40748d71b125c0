"""Delimited text logs (CSV and the like): rows as dicts keyed by the header's column names."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from dataclasses import dataclass

from .records import Reject, Where


@dataclass(frozen=True, slots=True)
class Row:
    """One data row: column name -> text, and where it was."""

    values: dict[str, str]
    where: Where


def decode(data: bytes, delimiter: str | None = None, comment: str = "#") -> Iterator[Row | Reject]:
    """Rows of a delimited file with a header line; short or long rows are Rejects.

    The delimiter is sniffed from the header (comma, semicolon, tab, '|') unless given.
    """
    text = data.decode("utf-8-sig", errors="replace")
    lines = text.splitlines(keepends=True)
    offsets, pos = [], 0
    for line in lines:
        offsets.append(pos)
        pos += len(line.encode("utf-8", errors="replace"))
    body = [(i, line) for i, line in enumerate(lines) if line.strip() and not line.lstrip().startswith(comment)]
    if not body:
        return
    header_index, header_line = body[0]
    delim = delimiter or max(",;\t|", key=header_line.count)
    header = [h.strip() for h in next(csv.reader([header_line], delimiter=delim))]
    for i, line in body[1:]:
        where = Where(offsets[i], i + 1)
        try:
            cells = next(csv.reader(io.StringIO(line), delimiter=delim))
        except (csv.Error, StopIteration) as exc:
            yield Reject(where, f"unreadable row ({exc})")
            continue
        if len(cells) != len(header):
            yield Reject(where, f"row has {len(cells)} columns, header has {len(header)}")
            continue
        yield Row(dict(zip(header, (c.strip() for c in cells))), where)
