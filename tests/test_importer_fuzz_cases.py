"""Cases the importer fuzz (tests/fuzz/importers.py) found, pinned: each is one line or a counted skip.

Every file is built here: the dataflash log with tests.trial_shapes' record layout, the ROS 2 database with
rosbags' writer (tests.fuzz.importers.db3_seeds) and then spoiled with sqlite3.
"""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path

import pytest

from formats.mcap_reader import ArchiveReader
from recorders.manifest import ManifestError, load_manifest
from recorders.record import record
from tests.fuzz.importers import HANG_S, TARGETS, bounded, db3_seeds, manifest_text
from tests.trial_shapes import NOGPS_TYPES, dataflash_formats, dataflash_record


def _record(folder: Path, name: str, data: bytes | None = None) -> Path:
    target = TARGETS[name]
    if data is not None:
        (folder / target.filename).write_bytes(data)
    (folder / "trial.toml").write_text(manifest_text(target))
    with bounded(HANG_S * 6):   # a regression fails here instead of hanging the run
        record(load_manifest(folder / "trial.toml"), folder / "out.mcap", workers=1)
    return folder / "out.mcap"


def test_a_dataflash_fmt_declaring_a_zero_length_is_refused_in_one_line(tmp_path):
    # pymavlink's indexer steps on by a type's declared length: 0 kept it on the same record forever, its list
    # of offsets growing without bound (past 600 MB in 10 s)
    data = dataflash_formats({k: v for k, v in NOGPS_TYPES.items() if k != "ATT"})
    data += dataflash_record(128, "BBnNZ", 131, 0, b"ATT", b"Qccf", b"TimeUS,Roll,Pitch,Yaw")
    data += b"".join(dataflash_record(131, "Qccf", 1_000_000 * k, 150, -250, 30.0) for k in range(1, 4))
    with pytest.raises(ManifestError) as caught:
        _record(tmp_path, "record/bin", data)
    text = str(caught.value)
    assert "\n" not in text
    assert text == "a.BIN: a FMT record declares 'ATT' (type 131) 0 bytes long, less than a record's 3-byte header"
    assert not (tmp_path / "out.mcap").exists()


def _db3(folder: Path, *statements: str) -> None:
    _, relaxed = db3_seeds()
    path = folder / TARGETS["record/ros2-db3"].filename
    path.write_bytes(relaxed)
    with contextlib.closing(sqlite3.connect(path)) as con, con:
        for sql in statements:
            con.execute(sql)


def test_a_ros2_topic_whose_qos_is_not_yaml_is_refused_in_one_line(tmp_path):
    # rosbags' YAML error spans five lines; the user's error is one
    _db3(tmp_path, "UPDATE topics SET offered_qos_profiles = '{a: [1, 2' WHERE id = 1")
    with pytest.raises(ManifestError) as caught:
        _record(tmp_path, "record/ros2-db3")
    text = str(caught.value)
    assert "\n" not in text and text.startswith("a.db3: rosbags cannot open a.db3: ReaderError: Could not load YAML")


@pytest.mark.parametrize("value", ["42", "NULL", "x'00'"])
def test_a_ros2_topic_whose_type_is_not_text_is_a_counted_skip(tmp_path, value):
    # the type came back as an int and `ros_type` raised AttributeError
    _db3(tmp_path, f"UPDATE topics SET type = {value} WHERE name = '/nmea'")
    with ArchiveReader(_record(tmp_path, "record/ros2-db3")) as r:
        files = r.metadata_json("recording")["files"]
        fixes = sum(1 for _ in r.messages(["/a/gps"]))
    assert files[0]["skipped"] == 6   # the six /nmea rows, each a counted skip
    assert fixes == 6                 # the /gps/fix NavSatFixes archived as before
