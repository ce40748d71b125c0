"""tail:PATH: a file another logger is still writing, read from its start as it grows."""

from __future__ import annotations

import os
from typing import BinaryIO

from .base import READ_SIZE, Source, SourceClosed, SourceError


class TailSource(Source):
    """Polled (a regular file is always readable); a replaced or truncated file is read again from its start."""

    selectable = False

    def __init__(self, url: str):
        super().__init__(url)
        self.path = url.partition(":")[2]
        if not self.path:
            raise SourceError(f"{url}: expected tail:PATH")
        self._file: BinaryIO | None = None
        self._inode = -1

    def open(self) -> None:
        """Open the file (raises OSError while it does not exist)."""
        self._file = open(self.path, "rb")
        self._inode = os.fstat(self._file.fileno()).st_ino

    def fileno(self) -> int:
        """The file's descriptor."""
        assert self._file is not None
        return self._file.fileno()

    def read(self) -> bytes:
        """New bytes; SourceClosed when the file was rotated, truncated or removed."""
        assert self._file is not None
        data = self._file.read(READ_SIZE)
        if data:
            return data
        try:
            st = os.stat(self.path)
        except OSError as exc:
            raise SourceClosed(f"{self.path} is gone") from exc
        if st.st_ino != self._inode or st.st_size < self._file.tell():
            raise SourceClosed(f"{self.path} was replaced or truncated")
        return b""

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None
