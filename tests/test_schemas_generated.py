"""The committed protobuf modules are what the pinned generator makes of the .proto sources."""

from __future__ import annotations

import math
from pathlib import Path

from formats import auvreplay_pb2

ROOT = Path(__file__).resolve().parent.parent
PROTO_DIR = ROOT / "formats" / "proto"


def test_generated_modules_are_current(tmp_path):
    import grpc_tools  # the pinned generator of the test extra
    from grpc_tools import protoc

    well_known = Path(grpc_tools.__file__).parent / "_proto"
    for proto in sorted(PROTO_DIR.glob("*.proto")):
        rc = protoc.main(["protoc", f"-I{PROTO_DIR}", f"-I{well_known}", f"--python_out={tmp_path}", f"--pyi_out={tmp_path}", str(proto)])
        assert rc == 0, f"protoc failed on {proto.name}"
        for suffix in ("_pb2.py", "_pb2.pyi"):
            name = proto.stem + suffix
            assert (tmp_path / name).read_bytes() == (ROOT / "formats" / name).read_bytes(), (
                f"formats/{name} is stale: regenerate with `python -m grpc_tools.protoc -Iformats/proto "
                f"--python_out=formats --pyi_out=formats formats/proto/{proto.name}`"
            )


def test_design_table_fields_exist():
    """Field names of the archive schema table of docs/design.md section 3 are a public contract."""
    wanted = {
        "GnssStatus": "timestamp fix_quality satellites hdop source_format",
        "InsState": "timestamp latitude longitude depth_m roll_deg pitch_deg heading_deg velocity_north_mps "
                    "velocity_east_mps velocity_down_mps heading_std_deg position_std_north_m "
                    "position_std_east_m status",
        "DvlVelocity": "timestamp frame velocity_x_mps velocity_y_mps velocity_z_mps error_velocity_mps "
                       "beam_range_m altitude_m valid figure_of_merit sound_speed_mps",
        "AcousticRange": "timestamp source destination source_address destination_address travel_time_s "
                         "range_m sound_speed_mps kind",
        "UsblObservation": "timestamp node target travel_time_s range_m bearing_deg elevation_deg phase_x_rad "
                           "phase_y_rad relative_east_m relative_north_m relative_up_m",
        "Detection": "timestamp leader method flagged score threshold feature_innovation_m "
                     "feature_mahalanobis2 feature_r_adapted_m2 label",
        "AnfisSnapshot": "time epoch membership consequents input_min input_max training_rmse",
        # proposed row (issue 18): /<v>/gps/velocity
        "GnssVelocity": "timestamp frame_id velocity_north_mps velocity_east_mps velocity_up_mps "
                        "speed_over_ground_mps course_over_ground_deg speed_std_mps source_format",
    }
    for message, fields in wanted.items():
        names = set(getattr(auvreplay_pb2, message).DESCRIPTOR.fields_by_name)
        assert set(fields.split()) <= names, message
    assert set(auvreplay_pb2.DvlVelocity.Frame.keys()) >= {"BODY_FRD", "EARTH_NED", "INSTRUMENT"}


def test_nan_survives_serialization():
    msg = auvreplay_pb2.InsState(depth_m=float("nan"))
    assert math.isnan(auvreplay_pb2.InsState.FromString(msg.SerializeToString()).depth_m)
