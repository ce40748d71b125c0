"""tail:PATH: a file another logger is still writing, read from its start as it grows."""

from __future__ import annotations

import os

from .base import READ_SIZE, Source, SourceClosed, SourceError


class TailSource(Source):
    """Polled (a regular file is always readable); a replaced or truncated file is read again from its start."""

    selectable = False

    def __init__(self, url: str):
        super().__init__(url)
        self.path = url.partition(":")[2]
        if not self.path:
            raise SourceError(f"{url}: expected tail:PATH")
        self._fd = -1
        self._inode = -1
        self._pos = 0

    def open(self) -> None:
        """Open the file (raises OSError while it does not exist)."""
        self._fd = os.open(self.path, os.O_RDONLY)
        self._inode = os.fstat(self._fd).st_ino
        self._pos = 0

    def fileno(self) -> int:
        """The file's descriptor."""
        return self._fd

    def read(self) -> bytes:
        """New bytes; SourceClosed when the file was rotated, truncated or removed."""
        data = os.read(self._fd, READ_SIZE)
        if data:
            self._pos += len(data)
            return data
        try:
            st = os.stat(self.path)
        except OSError as exc:
            raise SourceClosed(f"{self.path} is gone") from exc
        if st.st_ino != self._inode or st.st_size < self._pos:
            raise SourceClosed(f"{self.path} was replaced or truncated")
        return b""

    def close(self) -> None:
        """Close the file."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
