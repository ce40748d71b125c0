"""ROS messages kept as they are: the bag's serialized bytes on MCAP `ros1` / `cdr` channels with their schema.

Every message of a bag is archived as itself, as the MCAP specification's
well-known encodings define them (mcap.dev/spec/registry) and as rosbag2's MCAP
storage writes them, so that Foxglove, Rerun and the `mcap` library's ROS
decoders read them without our code:

- ROS 1: message encoding ``ros1``, schema encoding ``ros1msg``, schema name
  ``pkg/Type``; the schema is the connection's full definition text as the bag
  carries it (the type's ``.msg`` text, then each type it uses after a line of 80
  ``=`` and ``MSG: pkg/Type``).
- ROS 2: message encoding ``cdr``, schema encoding ``ros2msg``, schema name
  ``pkg/msg/Type``; the schema is the bag's own ``.msg`` definition when it carries
  one (MCAP storage, sqlite3 from Iron on), else the text rosbags' type store
  generates in rosbag2's layout from the types the bag, ``msg_paths`` or rosbags'
  common types define (a type given in ``.idl`` gets its ``.msg`` form).

The bytes are the bag's own (never serialized again): what `unpack` gives back
from the attachment and what the archive's messages carry are the same bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

ROS1_MESSAGE_ENCODING, ROS1_SCHEMA_ENCODING = "ros1", "ros1msg"
ROS2_MESSAGE_ENCODING, ROS2_SCHEMA_ENCODING = "cdr", "ros2msg"
ENCODINGS = {ROS1_MESSAGE_ENCODING: ROS1_SCHEMA_ENCODING, ROS2_MESSAGE_ENCODING: ROS2_SCHEMA_ENCODING}
TOPIC = "ros"   # /<vehicle>/ros/<the bag's topic>


@dataclass(frozen=True, slots=True, eq=False)   # eq=False: hashed by identity, one per connection type
class RosSchema:
    """A ROS message type as an MCAP schema: its name, schema encoding and definition text, and the channel's
    message encoding."""

    schema_name: str
    schema_encoding: str
    schema: str
    message_encoding: str


@dataclass(slots=True)  # not frozen: one per bag message, and frozen's __setattr__ path costs
class RosMessage:
    """One ROS message as the bag stores it: its type's schema and its serialized bytes."""

    kind: RosSchema
    data: bytes

    def SerializeToString(self) -> bytes:  # the protobuf message method the writers call
        """The message's bytes on the wire: the bag's own."""
        return self.data

    @property
    def schema_name(self) -> str:
        """The schema's name ("sensor_msgs/Imu", "sensor_msgs/msg/Imu")."""
        return self.kind.schema_name

    @property
    def schema_encoding(self) -> str:
        """``ros1msg`` or ``ros2msg``."""
        return self.kind.schema_encoding

    @property
    def schema(self) -> str:
        """The schema's definition text."""
        return self.kind.schema

    @property
    def message_encoding(self) -> str:
        """``ros1`` or ``cdr``."""
        return self.kind.message_encoding


def ros_schema(msgtype: str, bag_text: str, bag_format: str, store: Any, ros1: bool) -> RosSchema:
    """The schema of a bag connection's type ("pkg/msg/Type" as rosbags names it): the bag's own ``.msg`` text
    (`bag_format` "MSG") when it has one, else the definition rosbags' `store` generates (KeyError-like
    exceptions of rosbags when the store does not know the type)."""
    if bag_format != "MSG" or not bag_text.strip():
        bag_text = store.generate_msgdef(msgtype, ros_version=1 if ros1 else 2)[0]
    if ros1:
        return RosSchema(msgtype.replace("/msg/", "/"), ROS1_SCHEMA_ENCODING, bag_text, ROS1_MESSAGE_ENCODING)
    return RosSchema(msgtype, ROS2_SCHEMA_ENCODING, bag_text, ROS2_MESSAGE_ENCODING)


def topic_path(topic: str) -> str:
    """A bag topic as the levels below ``/<vehicle>/ros/``: "/auv2/odom" -> "auv2/odom" (its path kept, empty
    levels dropped)."""
    return "/".join(p for p in topic.split("/") if p) or "unnamed"
