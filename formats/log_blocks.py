"""A log read in bounded blocks cut at line ends, so that decoding it holds one block, not the whole log.

A text log's converter sees a sequence of `Block`s: consecutive pieces of
the log, each ending with a line end (except the last, and a line longer
than a block, which is cut where the block is full: such a line is no
sentence of any format we read, and cutting it keeps memory bounded). The
block knows where it sits in the log (byte offset, lines before it), so
positions in diagnostics are the log's. A rotated or split log's files are
one stream, as their concatenation is.

Decoders that read lines (`formats.lines.iter_lines`, `nmea.sentences.iter_frames`,
`phins.scan`) take a `LogText`: the log's bytes, or `LogBlocks` wrapping its
blocks. A converter written over such a decoder then reads a log in blocks
unchanged, its state (an open epoch, a day clock) going on from block to
block because it is one loop over the log's lines.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

BLOCK_BYTES = 4 << 20  # a converter holds about ten times this while it decodes a block


@dataclass(frozen=True, slots=True)
class Block:
    """Consecutive bytes of a log: `data`, at byte `offset` of the log, after `lines` line ends."""

    data: bytes
    offset: int = 0
    lines: int = 0  # line ends before the block: its first line is line `lines + 1`


def cut_blocks(pieces: Iterable[bytes], size: int = BLOCK_BYTES) -> Iterator[Block]:
    """The stream of `pieces` (read in any sizes) as blocks of about `size` bytes cut after a line end."""
    pending = b""
    offset = lines = 0
    for piece in pieces:
        pending = pending + piece if pending else piece
        while len(pending) >= size:
            cut = pending.rfind(b"\n", 0, size) + 1 or size  # no line end in a full block: cut it there
            block = pending[:cut]
            yield Block(block, offset, lines)
            offset += cut
            lines += block.count(b"\n")
            pending = pending[cut:]
    if pending:
        yield Block(pending, offset, lines)


class LogBlocks:
    """A log as its blocks, read once, for decoders that take a `LogText` (see `blocks_in`)."""

    __slots__ = ("blocks",)

    def __init__(self, blocks: Iterable[Block]):
        self.blocks = blocks

    def __iter__(self) -> Iterator[Block]:
        return iter(self.blocks)


LogText = bytes | LogBlocks  # a log whole in memory, or read in blocks


def blocks_in(data: LogText) -> Iterable[Block]:
    """The blocks of a `LogText`: a log in memory is one block (none when empty), as it is, not copied."""
    if isinstance(data, LogBlocks):
        return data
    return (Block(data),) if data else ()


def blocks_of(data: bytes, size: int = BLOCK_BYTES) -> Iterator[Block]:
    """A log already in memory as blocks (one block, no copy, when it fits in one)."""
    if len(data) <= size:
        if data:
            yield Block(data)
        return
    yield from cut_blocks((data[i:i + size] for i in range(0, len(data), size)), size)


class ChangedWhileRead(OSError):
    """A file whose size is not what it was when the recording started."""


@dataclass
class FileDigest:
    """One file of a log as it was read: its size and SHA-256."""

    path: Path
    size: int = 0
    sha256: str = ""


@dataclass
class LogFiles:
    """A log's files read in order as one stream of pieces, each file's size and SHA-256 taken on the way.

    `sizes` are the files' sizes when the recording started; a file that reads
    to another size raises ChangedWhileRead (the archive would not hold what
    was decoded).
    """

    paths: list[Path]
    sizes: list[int]
    digests: list[FileDigest] = field(default_factory=list)
    sha256: str = ""  # of all files as one stream, once read to the end
    piece: int = BLOCK_BYTES

    def pieces(self) -> Iterator[bytes]:
        """The files' bytes, in order, in pieces of at most `piece` bytes."""
        self.digests = []
        whole = hashlib.sha256()
        several = len(self.paths) > 1  # one file: its digest is the whole stream's, hashed once
        for path, expected in zip(self.paths, self.sizes):
            digest, h = FileDigest(path), hashlib.sha256()
            with open(path, "rb") as stream:
                while piece := stream.read(self.piece):
                    whole.update(piece)
                    if several:
                        h.update(piece)
                    digest.size += len(piece)
                    yield piece
            if digest.size != expected:
                raise ChangedWhileRead(f"{path}: {digest.size} bytes read, {expected} when the recording started")
            digest.sha256 = h.hexdigest()
            self.digests.append(digest)
        self.sha256 = whole.hexdigest()
        if not several and self.digests:
            self.digests[0].sha256 = self.sha256

    def read_whole(self) -> list[bytes]:
        """Each file's bytes read at once, for a log small enough to hold; ChangedWhileRead as for `pieces`."""
        out = []
        for path, expected in zip(self.paths, self.sizes):
            with open(path, "rb") as stream:
                data = stream.read(expected + 1)  # one byte over tells a file that grew, without reading it all
            if len(data) != expected:
                more = "more than " if len(data) > expected else ""
                raise ChangedWhileRead(f"{path}: {more}{expected if more else len(data)} bytes read, "
                                       f"{expected} when the recording started")
            out.append(data)
        return out

    def blocks(self, size: int | None = None) -> Iterator[Block]:
        """The log as blocks of about `size` bytes (default BLOCK_BYTES, read when called; see `cut_blocks`)."""
        size = size or BLOCK_BYTES
        self.piece = min(self.piece, size)
        return cut_blocks(self.pieces(), size)

    @property
    def size(self) -> int:
        """Bytes in all files, as they were at the start."""
        return sum(self.sizes)
