"""Messages rewritten in their serialized bytes equal the same messages serialized by rclpy.

Compared as messages and by length, not byte for byte: CDR's alignment padding is whatever was
in the serializer's memory (seen differing between two serializations in a long test run)."""

import struct

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import LaserScan

from fleet.world import frames as frames_module
from fleet.world.description import LidarSpec, RobotSpec
from fleet.world.frames import Field, SerializedFrames
from fleet.world.ros_bridge import odom_template, scan_template

ODOM = (
    Field("header.stamp.sec", "i4"),
    Field("header.stamp.nanosec", "u4"),
    Field("pose.pose.position.x", "f8"),
    Field("pose.pose.orientation.w", "f8"),
    Field("twist.twist.angular.z", "f8"),
)


def same(data: bytes, expected) -> bool:
    """`data` is what rclpy makes of `expected`: the same length, and the same message read back
    (both read back, so float32 fields are compared as float32)."""
    serialized = serialize_message(expected)
    kind = type(expected)
    return len(data) == len(serialized) and deserialize_message(data, kind) == deserialize_message(serialized, kind)


def test_odometry_fields_written_in_place_match_rclpy_serialization():
    specs = [RobotSpec(name, f"/{name}") for name in ("r1", "robot_with_a_longer_name", "r3")]
    frames = SerializedFrames([odom_template(spec) for spec in specs], ODOM)
    slots = np.array([2, 0])
    frames.write("header.stamp.sec", slots, 12)
    frames.write("header.stamp.nanosec", slots, 345_000_000)
    frames.write("pose.pose.position.x", slots, np.array([1.5, -2.25]))
    frames.write("pose.pose.orientation.w", slots, np.array([0.5, 1.0]))
    frames.write("twist.twist.angular.z", slots, np.array([0.125, -0.3]))
    got = frames.messages(np.array([0, 1, 2]))
    for slot, x, w, wz in ((2, 1.5, 0.5, 0.125), (0, -2.25, 1.0, -0.3)):
        expected = odom_template(specs[slot])
        expected.header.stamp.sec, expected.header.stamp.nanosec = 12, 345_000_000
        expected.pose.pose.position.x, expected.pose.pose.orientation.w, expected.twist.twist.angular.z = x, w, wz
        assert same(got[slot], expected)
    assert same(got[1], odom_template(specs[1]))  # not written: as built
    assert deserialize_message(got[2], Odometry).child_frame_id == "r3/base_link"


def test_scan_ranges_written_in_place_match_rclpy_serialization():
    spec = RobotSpec("r1", "/r1", lidar=LidarSpec(beams=7))
    frames = SerializedFrames([scan_template(spec)] * 2, (Field("header.stamp.sec", "i4"), Field("ranges", "f4", 7)))
    ranges = np.array([[0.5, np.inf, -np.inf, 1.0, 2.0, 3.0, 7.25]], dtype=np.float32)
    frames.write("ranges", np.array([1]), ranges)
    frames.write("header.stamp.sec", np.array([1]), 3)
    expected = scan_template(spec)
    expected.ranges = ranges[0].tolist()
    expected.header.stamp.sec = 3
    assert same(frames.messages(np.array([1]))[0], expected)
    assert deserialize_message(frames.messages(np.array([0]))[0], LaserScan).ranges.tolist() == [0.0] * 7


def test_a_field_the_message_does_not_have_is_refused():
    with pytest.raises(AttributeError):
        SerializedFrames([odom_template(RobotSpec("r1", "/r1"))], (Field("pose.pose.position.q", "f8"),))


def test_padding_that_holds_part_of_a_marker_is_not_taken_for_the_field(monkeypatch):
    """CDR padding holds whatever the serializer's memory held before.  Seen live (a robot
    respawned after the world restarted): the frame id's terminating NUL and the three padding
    bytes after it, left holding an earlier message's marker, were taken for the ranges, and
    every scan of that robot was written over its own header and could not be read."""
    frame_id = "robot2/base_scan"  # 16 characters: its NUL ends at an odd place, 3 bytes of padding follow

    def serialize_leaving_marker_bytes_in_padding(message):
        data = bytearray(serialize_message(message))
        if message.ranges[0] != 0.0:  # the probe, its ranges set to their marker
            after_nul = data.index(frame_id.encode()) + len(frame_id) + 1
            data[after_nul : after_nul + 3] = struct.pack("<f", message.ranges[0])[1:]
        return bytes(data)

    monkeypatch.setattr(frames_module, "serialize_message", serialize_leaving_marker_bytes_in_padding)
    spec = RobotSpec("robot2", "/robot2", lidar=LidarSpec(beams=7))
    frames = SerializedFrames([scan_template(spec)], (Field("header.stamp.sec", "i4"), Field("ranges", "f4", 7)))
    ranges = np.array([[0.5, np.inf, 1.0, 2.0, 3.0, 4.0, 7.25]], dtype=np.float32)
    frames.write("ranges", np.array([0]), ranges)
    expected = scan_template(spec)
    expected.ranges = ranges[0].tolist()
    assert same(frames.messages(np.array([0]))[0], expected)


def test_no_marker_has_a_zero_byte():
    """A zero byte would let a string's NUL stand for a marker's first byte (previous test)."""
    for dtype in ("f4", "f8", "i4", "u4"):
        for k in range(16):
            assert 0 not in np.array([frames_module._marker(dtype, k)], dtype="<" + dtype).tobytes()
