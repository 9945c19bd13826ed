"""Batches of the `zenoh` transport and its keys (pure functions)."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

from fleet.dataplane.batch import BatchError, batches, messages, record
from fleet.wire import protocol as p


def test_a_batch_gives_back_its_messages_in_order():
    sent = [("/a1/odom", b"\x00\x01odom"), ("/clock", b""), ("/a1/odom", bytes(range(256)) * 10)]
    payload = b"".join(record(topic.encode(), message) for topic, message in sent)
    assert list(messages(payload)) == sent


def test_batches_stay_under_the_limit_and_keep_every_record_once():
    records = [record(b"/t", bytes(100)) for _ in range(50)]
    payloads = list(batches(records, limit=1000))
    assert all(len(payload) <= 1000 for payload in payloads)
    assert b"".join(payloads) == b"".join(records)
    assert len(payloads) == 6  # 9 records of 108 bytes fit in 1000


def test_a_record_larger_than_the_limit_goes_alone():
    big, small = record(b"/big", bytes(5000)), record(b"/s", b"x")
    assert list(batches([small, big, small], limit=1000)) == [small, big, small]
    assert list(batches([])) == []


@pytest.mark.parametrize(
    ("payload", "problem"),
    [
        (record(b"/t", b"abc")[:-1], "truncated record at byte 0"),
        (record(b"/t", b"abc") + b"\x01", "truncated record header at byte 11"),
        (record(b"\xff", b""), "not UTF-8"),
    ],
)
def test_a_malformed_batch_is_refused_after_its_good_records(payload, problem):
    with pytest.raises(BatchError, match=problem):
        list(messages(payload))


def test_the_transport_keys_cannot_be_a_ros_topic_and_are_read_back():
    assert p.batch_key("lan", "rack_a") == "fleet/lan/data/-to/rack_a"
    token = p.import_token_key("lan", "rack_a", "/a1/odom")
    assert token == "fleet/lan/data/-imports/rack_a/a1/odom"
    assert p.imported_topic("lan", token) == ("rack_a", "/a1/odom")
    assert p.imported_topic("lan", "fleet/lan/data/a1/odom") is None
    assert p.imported_topic("other", token) is None
    with pytest.raises(ValidationError):  # no ROS topic has such a key
        p.TopicRoute(name="/-to/rack_a", type="std_msgs/msg/String")
