"""Small ROS bags written by rosbags' own writers, for the tests that build bags message by message."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any


def write_bag(folder: Path, ros1: bool, store: Any, streams: Iterable[Sequence[Any]],
              items: Iterable[tuple[int, str, str, bytes]]) -> Path:
    """A ROS 1 `dive.bag` or a ROS 2 sqlite3 folder `dive` in `folder`: one connection per (topic, type, ...)
    of `streams`, the serialized `items` (time ns, topic, type, bytes) written in their order."""
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1
        path = folder / "dive.bag"
        with Writer1(path) as w:
            conns = {tp: w.add_connection(tp, mt, typestore=store) for tp, mt, *_ in streams}
            for t, tp, _, data in items:
                w.write(conns[tp], t, data)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer
        path = folder / "dive"
        with Writer(path, version=8, storage_plugin=StoragePlugin.SQLITE3) as w2:
            conns = {tp: w2.add_connection(tp, mt, typestore=store) for tp, mt, *_ in streams}
            for t, tp, _, data in items:
                w2.write(conns[tp], t, data)
    return path
