"""Getting the original logs back out of an archive, byte for byte, safely."""

from __future__ import annotations

import hashlib
import os
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import BinaryIO

from formats.mcap_reader import ArchiveReader
from formats.output_files import OutputExists

RAW_PREFIX = "/raw/"  # a capture's raw streams (recorders.capture.session)


@dataclass
class UnpackResult:
    """Files written, names refused (unsafe), repeated names not written, checksum mismatches, and
    the reader's one-line account of what it skipped (None when nothing)."""

    written: list[Path] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    mismatched: list[str] = field(default_factory=list)
    incomplete: list[str] = field(default_factory=list)  # captured streams with bytes missing (a gap)
    repeated: list[str] = field(default_factory=list)
    warning: str | None = None


def safe_target(root: Path, name: str) -> Path | None:
    """Where attachment `name` goes under `root`, or None if it would land outside it.

    Archives come from other people's machines: absolute paths, drive letters,
    '..' components, backslash tricks and symlinked parents are all refused.
    """
    if not name or "\x00" in name or "\\" in name or name.startswith("/") or ":" in name.split("/")[0]:
        return None
    parts = PurePosixPath(name).parts
    if not parts or any(p in ("..", ".", "") for p in parts):
        return None
    target = root.joinpath(*parts)
    real_root = os.path.realpath(root)
    real_parent = os.path.realpath(target.parent)
    if os.path.commonpath([real_root, real_parent]) != real_root:
        return None
    return target


def _check_targets(reader: ArchiveReader, root: Path, replace: bool) -> None:
    """Refuse before anything is written when a file to write exists (unless `replace`) or cannot be a file."""
    summary = reader.summary()
    names = [a.name for a in summary.attachments] + [t[len(RAW_PREFIX):] for t in summary.topics
                                                     if t.startswith(RAW_PREFIX)]
    for name in dict.fromkeys(names):
        target = safe_target(root, name)
        if target is None or target.is_symlink():
            continue  # refused when its turn comes, and counted
        for parent in target.relative_to(root).parents:
            if (root / parent).exists() and not (root / parent).is_dir():
                raise NotADirectoryError(f"{root / parent} is not a directory: nothing unpacked ({name} goes in it)")
        if target.is_dir():
            raise IsADirectoryError(f"{target} is a directory: nothing unpacked ({name} would replace it)")
        if target.exists() and not replace:
            raise OutputExists(f"{target} exists: nothing unpacked (give --force to replace the files there)")


def unpack(archive_path: str | os.PathLike[str], target_dir: str | os.PathLike[str],
           replace: bool = False) -> UnpackResult:
    """Write every attachment under target_dir; refuse unsafe names, verify recorded sha256.

    Every name is checked before the first file is written: an existing file
    there refuses the whole unpack (OutputExists) unless `replace`. A second
    attachment of a name already written is not written over the first: it is
    listed in `repeated`.
    """
    root = Path(target_dir)
    if root.exists() and not root.is_dir():
        raise NotADirectoryError(f"{root} exists and is not a directory: nothing unpacked")
    result = UnpackResult()
    with ArchiveReader(archive_path) as reader:
        _check_targets(reader, root, replace)
        root.mkdir(parents=True, exist_ok=True)
        recording = reader.metadata_json("recording") or {}
        files = recording.get("files")
        files = [f for f in (files if isinstance(files, list) else [])
                 if isinstance(f, dict) and isinstance(f.get("path"), str)]
        expected = {f["path"]: f.get("sha256", "") for f in files}
        # a split log's files are attached one by one, each with its own checksum
        expected.update({p["path"]: p.get("sha256", "") for f in files for p in f.get("parts") or []
                         if isinstance(p, dict) and isinstance(p.get("path"), str)})
        seen: set[str] = set()
        for att in reader.attachments():
            if att.name in seen:
                result.repeated.append(att.name)
                continue
            seen.add(att.name)
            target = safe_target(root, att.name)
            if target is None:
                result.refused.append(att.name)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            # re-check once the parents exist: a symlinked directory may point elsewhere
            if safe_target(root, att.name) is None or target.is_symlink():
                result.refused.append(att.name)
                continue
            target.write_bytes(att.data)
            result.written.append(target)
            want = expected.get(att.name)
            if want and hashlib.sha256(att.data).hexdigest() != want:
                result.mismatched.append(att.name)
        _unpack_streams(reader, root, expected, result)
        result.warning = reader.warning()
    return result


def _unpack_streams(reader: ArchiveReader, root: Path, expected: dict[str, str], result: UnpackResult) -> None:
    """A capture's streams (its RawBytes messages), each written back at its offsets: the bytes as received."""
    topics = [t for t in reader.summary().topics if t.startswith(RAW_PREFIX)]
    if not topics:
        return
    files: dict[str, tuple[BinaryIO, list[int]]] = {}  # stream -> (file, [bytes written, end])
    with ExitStack() as stack:
        for m in reader.messages(topics):
            raw = m.message
            # a stream is named by its topic, as _check_targets saw it (a crafted message's name is not trusted)
            raw.stream = m.topic[len(RAW_PREFIX):]
            got = files.get(raw.stream)
            if got is None:
                target = safe_target(root, raw.stream)
                if target is None or raw.stream in result.refused:
                    if raw.stream not in result.refused:
                        result.refused.append(raw.stream)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                if safe_target(root, raw.stream) is None or target.is_symlink():
                    result.refused.append(raw.stream)
                    continue
                got = files[raw.stream] = (stack.enter_context(open(target, "wb")), [0, 0])
                result.written.append(target)
            f, counts = got
            f.seek(raw.offset)  # in offset order whatever the receive times say
            f.write(raw.data)
            counts[0] += len(raw.data)
            counts[1] = max(counts[1], raw.offset + len(raw.data))
    for stream, (f, (written, end)) in files.items():
        if written != end:
            result.incomplete.append(stream)
            continue
        want = expected.get(stream)
        if want and hashlib.sha256(Path(f.name).read_bytes()).hexdigest() != want:
            result.mismatched.append(stream)
