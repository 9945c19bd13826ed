"""Many messages of one type kept serialized, their changing fields rewritten in place with numpy.

Publishing a message object costs rclpy ~16 us of conversion and serialization (an Odometry has
two 36-double covariances); publishing bytes it already has costs ~2 us.  Each robot's message
is serialized once (its frame ids and constant fields fixed), the byte offsets of the fields that
change are found by serializing marker values, and every later message is the same bytes with
those fields overwritten for all robots at once.  Subscribers receive exactly the message the
object would have given.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from rclpy.serialization import serialize_message

# CDR aligns a field to its size counted from the end of the 4-byte encapsulation header, so a
# message placed at 4 modulo 8 in the shared buffer has every double at a multiple of 8.
_HEADER = 4
_ALIGN = 8


@dataclass(frozen=True)
class Field:
    """A numeric field of the message, by attribute path ("pose.pose.position.x"), or a float32
    sequence of fixed length ("ranges", with `count`)."""

    path: str
    dtype: str  # "f8", "i4", "u4" or "f4"
    count: int = 1


def _set(msg, path: str, value) -> None:
    *parents, leaf = path.split(".")
    for name in parents:
        msg = getattr(msg, name)
    setattr(msg, leaf, value)


# The bytes a field is set to while its offset is looked for, by dtype (the first byte varies with
# the field): unlikely anywhere else in a message, and none of them zero (see _offset).
_MARKER_BYTES = {
    "f4": bytes([0x56, 0x9A, 0x44]),  # about 1,234.8
    "f8": bytes([0x43, 0xFA, 0xED, 0xD6, 0x1C, 0xF8, 0x40]),  # about 98,765.4
    "i4": bytes([0x3C, 0x5A, 0x5A]),
    "u4": bytes([0x3C, 0x5A, 0x5A]),
}


def _marker(dtype: str, k: int):
    """The marker value of field k."""
    return np.frombuffer(bytes([0x11 + k]) + _MARKER_BYTES[dtype], dtype="<" + dtype)[0].item()


def _offset(marked: bytes, field: Field, k: int) -> int:
    """Where `field` (the k-th) starts in `marked`, a message serialized with every field set to its
    marker: the one place, aligned as CDR aligns the field, that holds the whole field's marker.

    CDR's padding holds whatever the serializer's memory held before, once an earlier message's
    marker: a string's terminating NUL and the three padding bytes after it read as the old
    float32 marker, whose first byte was zero, and a robot's scans were written over its header.
    An aligned place that takes in such padding takes in the NUL too, which no marker has (the
    fields fleet writes follow strings only where the padding is shorter than the field)."""
    item = np.dtype("<" + field.dtype)
    needle = np.full(field.count, _marker(field.dtype, k), dtype=item).tobytes()
    found = []
    at = marked.find(needle)
    while at >= 0:
        if (at - _HEADER) % item.itemsize == 0:
            found.append(at)
        at = marked.find(needle, at + 1)
    if len(found) != 1:
        raise ValueError(f"cannot locate field {field.path}: {len(found)} places hold its marker")
    return found[0]


class SerializedFrames:
    """One serialized message per slot (robot), with `fields` writable by slot index."""

    def __init__(self, templates: Sequence, fields: Sequence[Field]) -> None:
        self.fields = {field.path: field for field in fields}
        blobs, offsets = [], []
        for template in templates:
            probe = copy.deepcopy(template)
            for k, field in enumerate(fields):
                value = _marker(field.dtype, k)
                _set(probe, field.path, [value] * field.count if field.count > 1 else value)
            marked = serialize_message(probe)
            try:
                offsets.append({field.path: _offset(marked, field, k) for k, field in enumerate(fields)})
            except ValueError as error:
                raise ValueError(f"{type(template).__name__}: {error}") from None
            blobs.append(serialize_message(template))
        starts, position = [], _HEADER
        for blob in blobs:
            starts.append(position)
            position += -(-len(blob) // _ALIGN) * _ALIGN
        self._buffer = np.zeros(-(-position // _ALIGN) * _ALIGN, dtype=np.uint8)
        for start, blob in zip(starts, blobs, strict=True):
            self._buffer[start : start + len(blob)] = np.frombuffer(blob, dtype=np.uint8)
        self.starts = np.array(starts, dtype=np.int64)
        self.ends = self.starts + np.array([len(blob) for blob in blobs], dtype=np.int64)
        self._views = {dtype: self._buffer.view("<" + dtype) for dtype in {f.dtype for f in fields}}
        self._index = {}
        for field in fields:
            size = np.dtype(field.dtype).itemsize
            absolute = self.starts + np.array([found[field.path] for found in offsets], dtype=np.int64)
            if np.any(absolute % size):
                raise ValueError(f"field {field.path} of {type(templates[0]).__name__} is not aligned")
            self._index[field.path] = absolute // size

    def __len__(self) -> int:
        return len(self.starts)

    def write(self, path: str, slots: np.ndarray, values) -> None:
        """Set field `path` of the messages in `slots` (values: one per slot, or one for all;
        (slots, count) for a sequence)."""
        field = self.fields[path]
        index = self._index[path][slots]
        if field.count > 1:
            index = index[:, None] + np.arange(field.count)
        self._views[field.dtype][index] = values

    def messages(self, slots: np.ndarray) -> list[bytes]:
        """The serialized messages of `slots`, as they are now."""
        data = self._buffer.tobytes() if len(slots) * 4 > len(self) else None
        out = []
        for start, end in zip(self.starts[slots].tolist(), self.ends[slots].tolist(), strict=True):
            out.append(data[start:end] if data is not None else self._buffer[start:end].tobytes())
        return out
