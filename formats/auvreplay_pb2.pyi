import datetime

from google.protobuf import timestamp_pb2 as _timestamp_pb2
from google.protobuf.internal import containers as _containers
from google.protobuf.internal import enum_type_wrapper as _enum_type_wrapper
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class GnssStatus(_message.Message):
    __slots__ = ("timestamp", "frame_id", "fix_quality", "satellites", "hdop", "source_format", "speed_over_ground_mps", "course_over_ground_deg", "heading_deg")
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    FRAME_ID_FIELD_NUMBER: _ClassVar[int]
    FIX_QUALITY_FIELD_NUMBER: _ClassVar[int]
    SATELLITES_FIELD_NUMBER: _ClassVar[int]
    HDOP_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FORMAT_FIELD_NUMBER: _ClassVar[int]
    SPEED_OVER_GROUND_MPS_FIELD_NUMBER: _ClassVar[int]
    COURSE_OVER_GROUND_DEG_FIELD_NUMBER: _ClassVar[int]
    HEADING_DEG_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    frame_id: str
    fix_quality: int
    satellites: int
    hdop: float
    source_format: str
    speed_over_ground_mps: float
    course_over_ground_deg: float
    heading_deg: float
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., frame_id: _Optional[str] = ..., fix_quality: _Optional[int] = ..., satellites: _Optional[int] = ..., hdop: _Optional[float] = ..., source_format: _Optional[str] = ..., speed_over_ground_mps: _Optional[float] = ..., course_over_ground_deg: _Optional[float] = ..., heading_deg: _Optional[float] = ...) -> None: ...

class InsState(_message.Message):
    __slots__ = ("timestamp", "frame_id", "latitude", "longitude", "depth_m", "roll_deg", "pitch_deg", "heading_deg", "velocity_north_mps", "velocity_east_mps", "velocity_down_mps", "heading_std_deg", "position_std_north_m", "position_std_east_m", "status", "source_format", "roll_std_deg", "pitch_std_deg", "altitude_m", "angular_velocity_x_radps", "angular_velocity_y_radps", "angular_velocity_z_radps", "linear_acceleration_x_mps2", "linear_acceleration_y_mps2", "linear_acceleration_z_mps2")
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    FRAME_ID_FIELD_NUMBER: _ClassVar[int]
    LATITUDE_FIELD_NUMBER: _ClassVar[int]
    LONGITUDE_FIELD_NUMBER: _ClassVar[int]
    DEPTH_M_FIELD_NUMBER: _ClassVar[int]
    ROLL_DEG_FIELD_NUMBER: _ClassVar[int]
    PITCH_DEG_FIELD_NUMBER: _ClassVar[int]
    HEADING_DEG_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_NORTH_MPS_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_EAST_MPS_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_DOWN_MPS_FIELD_NUMBER: _ClassVar[int]
    HEADING_STD_DEG_FIELD_NUMBER: _ClassVar[int]
    POSITION_STD_NORTH_M_FIELD_NUMBER: _ClassVar[int]
    POSITION_STD_EAST_M_FIELD_NUMBER: _ClassVar[int]
    STATUS_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FORMAT_FIELD_NUMBER: _ClassVar[int]
    ROLL_STD_DEG_FIELD_NUMBER: _ClassVar[int]
    PITCH_STD_DEG_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_M_FIELD_NUMBER: _ClassVar[int]
    ANGULAR_VELOCITY_X_RADPS_FIELD_NUMBER: _ClassVar[int]
    ANGULAR_VELOCITY_Y_RADPS_FIELD_NUMBER: _ClassVar[int]
    ANGULAR_VELOCITY_Z_RADPS_FIELD_NUMBER: _ClassVar[int]
    LINEAR_ACCELERATION_X_MPS2_FIELD_NUMBER: _ClassVar[int]
    LINEAR_ACCELERATION_Y_MPS2_FIELD_NUMBER: _ClassVar[int]
    LINEAR_ACCELERATION_Z_MPS2_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    frame_id: str
    latitude: float
    longitude: float
    depth_m: float
    roll_deg: float
    pitch_deg: float
    heading_deg: float
    velocity_north_mps: float
    velocity_east_mps: float
    velocity_down_mps: float
    heading_std_deg: float
    position_std_north_m: float
    position_std_east_m: float
    status: str
    source_format: str
    roll_std_deg: float
    pitch_std_deg: float
    altitude_m: float
    angular_velocity_x_radps: float
    angular_velocity_y_radps: float
    angular_velocity_z_radps: float
    linear_acceleration_x_mps2: float
    linear_acceleration_y_mps2: float
    linear_acceleration_z_mps2: float
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., frame_id: _Optional[str] = ..., latitude: _Optional[float] = ..., longitude: _Optional[float] = ..., depth_m: _Optional[float] = ..., roll_deg: _Optional[float] = ..., pitch_deg: _Optional[float] = ..., heading_deg: _Optional[float] = ..., velocity_north_mps: _Optional[float] = ..., velocity_east_mps: _Optional[float] = ..., velocity_down_mps: _Optional[float] = ..., heading_std_deg: _Optional[float] = ..., position_std_north_m: _Optional[float] = ..., position_std_east_m: _Optional[float] = ..., status: _Optional[str] = ..., source_format: _Optional[str] = ..., roll_std_deg: _Optional[float] = ..., pitch_std_deg: _Optional[float] = ..., altitude_m: _Optional[float] = ..., angular_velocity_x_radps: _Optional[float] = ..., angular_velocity_y_radps: _Optional[float] = ..., angular_velocity_z_radps: _Optional[float] = ..., linear_acceleration_x_mps2: _Optional[float] = ..., linear_acceleration_y_mps2: _Optional[float] = ..., linear_acceleration_z_mps2: _Optional[float] = ...) -> None: ...

class DvlVelocity(_message.Message):
    __slots__ = ("timestamp", "frame_id", "frame", "velocity_x_mps", "velocity_y_mps", "velocity_z_mps", "error_velocity_mps", "beam_range_m", "altitude_m", "valid", "figure_of_merit", "sound_speed_mps", "source_format", "temperature_c", "device_time")
    class Frame(int, metaclass=_enum_type_wrapper.EnumTypeWrapper):
        __slots__ = ()
        FRAME_UNKNOWN: _ClassVar[DvlVelocity.Frame]
        BODY_FRD: _ClassVar[DvlVelocity.Frame]
        EARTH_NED: _ClassVar[DvlVelocity.Frame]
        INSTRUMENT: _ClassVar[DvlVelocity.Frame]
    FRAME_UNKNOWN: DvlVelocity.Frame
    BODY_FRD: DvlVelocity.Frame
    EARTH_NED: DvlVelocity.Frame
    INSTRUMENT: DvlVelocity.Frame
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    FRAME_ID_FIELD_NUMBER: _ClassVar[int]
    FRAME_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_X_MPS_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_Y_MPS_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_Z_MPS_FIELD_NUMBER: _ClassVar[int]
    ERROR_VELOCITY_MPS_FIELD_NUMBER: _ClassVar[int]
    BEAM_RANGE_M_FIELD_NUMBER: _ClassVar[int]
    ALTITUDE_M_FIELD_NUMBER: _ClassVar[int]
    VALID_FIELD_NUMBER: _ClassVar[int]
    FIGURE_OF_MERIT_FIELD_NUMBER: _ClassVar[int]
    SOUND_SPEED_MPS_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FORMAT_FIELD_NUMBER: _ClassVar[int]
    TEMPERATURE_C_FIELD_NUMBER: _ClassVar[int]
    DEVICE_TIME_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    frame_id: str
    frame: DvlVelocity.Frame
    velocity_x_mps: float
    velocity_y_mps: float
    velocity_z_mps: float
    error_velocity_mps: float
    beam_range_m: _containers.RepeatedScalarFieldContainer[float]
    altitude_m: float
    valid: bool
    figure_of_merit: float
    sound_speed_mps: float
    source_format: str
    temperature_c: float
    device_time: _timestamp_pb2.Timestamp
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., frame_id: _Optional[str] = ..., frame: _Optional[_Union[DvlVelocity.Frame, str]] = ..., velocity_x_mps: _Optional[float] = ..., velocity_y_mps: _Optional[float] = ..., velocity_z_mps: _Optional[float] = ..., error_velocity_mps: _Optional[float] = ..., beam_range_m: _Optional[_Iterable[float]] = ..., altitude_m: _Optional[float] = ..., valid: _Optional[bool] = ..., figure_of_merit: _Optional[float] = ..., sound_speed_mps: _Optional[float] = ..., source_format: _Optional[str] = ..., temperature_c: _Optional[float] = ..., device_time: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ...) -> None: ...

class AcousticRange(_message.Message):
    __slots__ = ("timestamp", "source", "destination", "source_address", "destination_address", "travel_time_s", "range_m", "sound_speed_mps", "kind", "source_format")
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FIELD_NUMBER: _ClassVar[int]
    DESTINATION_FIELD_NUMBER: _ClassVar[int]
    SOURCE_ADDRESS_FIELD_NUMBER: _ClassVar[int]
    DESTINATION_ADDRESS_FIELD_NUMBER: _ClassVar[int]
    TRAVEL_TIME_S_FIELD_NUMBER: _ClassVar[int]
    RANGE_M_FIELD_NUMBER: _ClassVar[int]
    SOUND_SPEED_MPS_FIELD_NUMBER: _ClassVar[int]
    KIND_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FORMAT_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    source: str
    destination: str
    source_address: int
    destination_address: int
    travel_time_s: float
    range_m: float
    sound_speed_mps: float
    kind: str
    source_format: str
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., source: _Optional[str] = ..., destination: _Optional[str] = ..., source_address: _Optional[int] = ..., destination_address: _Optional[int] = ..., travel_time_s: _Optional[float] = ..., range_m: _Optional[float] = ..., sound_speed_mps: _Optional[float] = ..., kind: _Optional[str] = ..., source_format: _Optional[str] = ...) -> None: ...

class UsblObservation(_message.Message):
    __slots__ = ("timestamp", "node", "target", "travel_time_s", "range_m", "bearing_deg", "elevation_deg", "phase_x_rad", "phase_y_rad", "relative_east_m", "relative_north_m", "relative_up_m", "source_format", "integrity", "rssi_db")
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    NODE_FIELD_NUMBER: _ClassVar[int]
    TARGET_FIELD_NUMBER: _ClassVar[int]
    TRAVEL_TIME_S_FIELD_NUMBER: _ClassVar[int]
    RANGE_M_FIELD_NUMBER: _ClassVar[int]
    BEARING_DEG_FIELD_NUMBER: _ClassVar[int]
    ELEVATION_DEG_FIELD_NUMBER: _ClassVar[int]
    PHASE_X_RAD_FIELD_NUMBER: _ClassVar[int]
    PHASE_Y_RAD_FIELD_NUMBER: _ClassVar[int]
    RELATIVE_EAST_M_FIELD_NUMBER: _ClassVar[int]
    RELATIVE_NORTH_M_FIELD_NUMBER: _ClassVar[int]
    RELATIVE_UP_M_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FORMAT_FIELD_NUMBER: _ClassVar[int]
    INTEGRITY_FIELD_NUMBER: _ClassVar[int]
    RSSI_DB_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    node: str
    target: str
    travel_time_s: float
    range_m: float
    bearing_deg: float
    elevation_deg: float
    phase_x_rad: float
    phase_y_rad: float
    relative_east_m: float
    relative_north_m: float
    relative_up_m: float
    source_format: str
    integrity: float
    rssi_db: float
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., node: _Optional[str] = ..., target: _Optional[str] = ..., travel_time_s: _Optional[float] = ..., range_m: _Optional[float] = ..., bearing_deg: _Optional[float] = ..., elevation_deg: _Optional[float] = ..., phase_x_rad: _Optional[float] = ..., phase_y_rad: _Optional[float] = ..., relative_east_m: _Optional[float] = ..., relative_north_m: _Optional[float] = ..., relative_up_m: _Optional[float] = ..., source_format: _Optional[str] = ..., integrity: _Optional[float] = ..., rssi_db: _Optional[float] = ...) -> None: ...

class Detection(_message.Message):
    __slots__ = ("timestamp", "follower", "leader", "method", "flagged", "score", "threshold", "feature_innovation_m", "feature_mahalanobis2", "feature_r_adapted_m2", "label", "isolation_capped", "repeat_count", "dr_residual_m", "leader_consistency_m", "usbl_residual_m", "lag_residual_m", "drift_residual_m", "drift_cusum_m", "exclusion_residual_m", "drift_z", "exclusion_z", "model_innovation_m")
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    FOLLOWER_FIELD_NUMBER: _ClassVar[int]
    LEADER_FIELD_NUMBER: _ClassVar[int]
    METHOD_FIELD_NUMBER: _ClassVar[int]
    FLAGGED_FIELD_NUMBER: _ClassVar[int]
    SCORE_FIELD_NUMBER: _ClassVar[int]
    THRESHOLD_FIELD_NUMBER: _ClassVar[int]
    FEATURE_INNOVATION_M_FIELD_NUMBER: _ClassVar[int]
    FEATURE_MAHALANOBIS2_FIELD_NUMBER: _ClassVar[int]
    FEATURE_R_ADAPTED_M2_FIELD_NUMBER: _ClassVar[int]
    LABEL_FIELD_NUMBER: _ClassVar[int]
    ISOLATION_CAPPED_FIELD_NUMBER: _ClassVar[int]
    REPEAT_COUNT_FIELD_NUMBER: _ClassVar[int]
    DR_RESIDUAL_M_FIELD_NUMBER: _ClassVar[int]
    LEADER_CONSISTENCY_M_FIELD_NUMBER: _ClassVar[int]
    USBL_RESIDUAL_M_FIELD_NUMBER: _ClassVar[int]
    LAG_RESIDUAL_M_FIELD_NUMBER: _ClassVar[int]
    DRIFT_RESIDUAL_M_FIELD_NUMBER: _ClassVar[int]
    DRIFT_CUSUM_M_FIELD_NUMBER: _ClassVar[int]
    EXCLUSION_RESIDUAL_M_FIELD_NUMBER: _ClassVar[int]
    DRIFT_Z_FIELD_NUMBER: _ClassVar[int]
    EXCLUSION_Z_FIELD_NUMBER: _ClassVar[int]
    MODEL_INNOVATION_M_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    follower: str
    leader: str
    method: str
    flagged: bool
    score: float
    threshold: float
    feature_innovation_m: float
    feature_mahalanobis2: float
    feature_r_adapted_m2: float
    label: int
    isolation_capped: bool
    repeat_count: float
    dr_residual_m: float
    leader_consistency_m: float
    usbl_residual_m: float
    lag_residual_m: float
    drift_residual_m: float
    drift_cusum_m: float
    exclusion_residual_m: float
    drift_z: float
    exclusion_z: float
    model_innovation_m: float
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., follower: _Optional[str] = ..., leader: _Optional[str] = ..., method: _Optional[str] = ..., flagged: _Optional[bool] = ..., score: _Optional[float] = ..., threshold: _Optional[float] = ..., feature_innovation_m: _Optional[float] = ..., feature_mahalanobis2: _Optional[float] = ..., feature_r_adapted_m2: _Optional[float] = ..., label: _Optional[int] = ..., isolation_capped: _Optional[bool] = ..., repeat_count: _Optional[float] = ..., dr_residual_m: _Optional[float] = ..., leader_consistency_m: _Optional[float] = ..., usbl_residual_m: _Optional[float] = ..., lag_residual_m: _Optional[float] = ..., drift_residual_m: _Optional[float] = ..., drift_cusum_m: _Optional[float] = ..., exclusion_residual_m: _Optional[float] = ..., drift_z: _Optional[float] = ..., exclusion_z: _Optional[float] = ..., model_innovation_m: _Optional[float] = ...) -> None: ...

class BellMembership(_message.Message):
    __slots__ = ("input", "index", "a", "b", "c")
    INPUT_FIELD_NUMBER: _ClassVar[int]
    INDEX_FIELD_NUMBER: _ClassVar[int]
    A_FIELD_NUMBER: _ClassVar[int]
    B_FIELD_NUMBER: _ClassVar[int]
    C_FIELD_NUMBER: _ClassVar[int]
    input: int
    index: int
    a: float
    b: float
    c: float
    def __init__(self, input: _Optional[int] = ..., index: _Optional[int] = ..., a: _Optional[float] = ..., b: _Optional[float] = ..., c: _Optional[float] = ...) -> None: ...

class AnfisSnapshot(_message.Message):
    __slots__ = ("time", "leader", "epoch", "membership", "consequents", "input_min", "input_max", "training_rmse", "inputs", "mfs_per_input", "rule_structure", "threshold", "trainer")
    TIME_FIELD_NUMBER: _ClassVar[int]
    LEADER_FIELD_NUMBER: _ClassVar[int]
    EPOCH_FIELD_NUMBER: _ClassVar[int]
    MEMBERSHIP_FIELD_NUMBER: _ClassVar[int]
    CONSEQUENTS_FIELD_NUMBER: _ClassVar[int]
    INPUT_MIN_FIELD_NUMBER: _ClassVar[int]
    INPUT_MAX_FIELD_NUMBER: _ClassVar[int]
    TRAINING_RMSE_FIELD_NUMBER: _ClassVar[int]
    INPUTS_FIELD_NUMBER: _ClassVar[int]
    MFS_PER_INPUT_FIELD_NUMBER: _ClassVar[int]
    RULE_STRUCTURE_FIELD_NUMBER: _ClassVar[int]
    THRESHOLD_FIELD_NUMBER: _ClassVar[int]
    TRAINER_FIELD_NUMBER: _ClassVar[int]
    time: _timestamp_pb2.Timestamp
    leader: str
    epoch: int
    membership: _containers.RepeatedCompositeFieldContainer[BellMembership]
    consequents: _containers.RepeatedScalarFieldContainer[float]
    input_min: _containers.RepeatedScalarFieldContainer[float]
    input_max: _containers.RepeatedScalarFieldContainer[float]
    training_rmse: float
    inputs: int
    mfs_per_input: int
    rule_structure: str
    threshold: float
    trainer: str
    def __init__(self, time: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., leader: _Optional[str] = ..., epoch: _Optional[int] = ..., membership: _Optional[_Iterable[_Union[BellMembership, _Mapping]]] = ..., consequents: _Optional[_Iterable[float]] = ..., input_min: _Optional[_Iterable[float]] = ..., input_max: _Optional[_Iterable[float]] = ..., training_rmse: _Optional[float] = ..., inputs: _Optional[int] = ..., mfs_per_input: _Optional[int] = ..., rule_structure: _Optional[str] = ..., threshold: _Optional[float] = ..., trainer: _Optional[str] = ...) -> None: ...

class RawBytes(_message.Message):
    __slots__ = ("timestamp", "stream", "offset", "data", "connection")
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    STREAM_FIELD_NUMBER: _ClassVar[int]
    OFFSET_FIELD_NUMBER: _ClassVar[int]
    DATA_FIELD_NUMBER: _ClassVar[int]
    CONNECTION_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    stream: str
    offset: int
    data: bytes
    connection: int
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., stream: _Optional[str] = ..., offset: _Optional[int] = ..., data: _Optional[bytes] = ..., connection: _Optional[int] = ...) -> None: ...

class GnssVelocity(_message.Message):
    __slots__ = ("timestamp", "frame_id", "velocity_north_mps", "velocity_east_mps", "velocity_up_mps", "speed_over_ground_mps", "course_over_ground_deg", "speed_std_mps", "source_format")
    TIMESTAMP_FIELD_NUMBER: _ClassVar[int]
    FRAME_ID_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_NORTH_MPS_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_EAST_MPS_FIELD_NUMBER: _ClassVar[int]
    VELOCITY_UP_MPS_FIELD_NUMBER: _ClassVar[int]
    SPEED_OVER_GROUND_MPS_FIELD_NUMBER: _ClassVar[int]
    COURSE_OVER_GROUND_DEG_FIELD_NUMBER: _ClassVar[int]
    SPEED_STD_MPS_FIELD_NUMBER: _ClassVar[int]
    SOURCE_FORMAT_FIELD_NUMBER: _ClassVar[int]
    timestamp: _timestamp_pb2.Timestamp
    frame_id: str
    velocity_north_mps: float
    velocity_east_mps: float
    velocity_up_mps: float
    speed_over_ground_mps: float
    course_over_ground_deg: float
    speed_std_mps: float
    source_format: str
    def __init__(self, timestamp: _Optional[_Union[datetime.datetime, _timestamp_pb2.Timestamp, _Mapping]] = ..., frame_id: _Optional[str] = ..., velocity_north_mps: _Optional[float] = ..., velocity_east_mps: _Optional[float] = ..., velocity_up_mps: _Optional[float] = ..., speed_over_ground_mps: _Optional[float] = ..., course_over_ground_deg: _Optional[float] = ..., speed_std_mps: _Optional[float] = ..., source_format: _Optional[str] = ...) -> None: ...
