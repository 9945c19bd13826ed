"""Batches of serialized ROS messages: what one Zenoh put of the `zenoh` transport carries.

A batch is a sequence of records, each `<topic length: u16><message length: u32><topic: utf-8>
<message: CDR bytes>` (little endian).  Packing many messages into one put spares Zenoh and
Python a call, a routing decision and a callback per message: at 100 robots' odometry and scans
(6,000 messages/s) that per-message cost was what the bridges could not keep up with.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator

HEADER = struct.Struct("<HI")
MAX_BATCH_BYTES = 60_000  # under Zenoh's 64 KiB transport batch: a put is never fragmented for its size


class BatchError(ValueError):
    """A payload that is not a batch (truncated, or from something else)."""


def record(topic: bytes, message: bytes) -> bytes:
    """One message's record; `topic` is the topic name in UTF-8."""
    return HEADER.pack(len(topic), len(message)) + topic + message


def batches(records: list[bytes], limit: int = MAX_BATCH_BYTES) -> Iterator[bytes]:
    """The records joined into payloads of at most `limit` bytes (a larger record goes alone)."""
    start, size = 0, 0
    for end, one in enumerate(records):
        if size and size + len(one) > limit:
            yield b"".join(records[start:end])
            start, size = end, 0
        size += len(one)
    if size:
        yield b"".join(records[start:])


def messages(payload: bytes) -> Iterator[tuple[str, bytes]]:
    """(topic, message) of every record of a batch, in order; BatchError at a malformed record
    (the records before it are still yielded)."""
    view, offset = memoryview(payload), 0
    while offset < len(view):
        if offset + HEADER.size > len(view):
            raise BatchError(f"truncated record header at byte {offset}")
        topic_length, message_length = HEADER.unpack_from(view, offset)
        offset += HEADER.size
        end = offset + topic_length + message_length
        if end > len(view):
            raise BatchError(f"truncated record at byte {offset - HEADER.size}")
        try:
            topic = bytes(view[offset : offset + topic_length]).decode()
        except UnicodeDecodeError:
            raise BatchError(f"topic name of the record at byte {offset - HEADER.size} is not UTF-8") from None
        yield topic, bytes(view[offset + topic_length : end])
        offset = end
