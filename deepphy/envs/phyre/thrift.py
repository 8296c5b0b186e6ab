"""A minimal reader for Thrift's binary protocol (TBinaryProtocol), enough for PHYRE's data.

PHYRE stores its tasks as one Thrift `TaskCollection` (IDL: `src/if/task.thrift` and
`scene.thrift` in facebookresearch/phyre). This reader knows no schema: a struct becomes
a dict from field id to value, so the caller maps ids to names (see `data.py`). Values:
bool, int (byte, i16, i32, i64), float (double), bytes (string/binary), list (list,
set), dict (map), dict (struct). Big-endian throughout, as the protocol specifies.
"""

from __future__ import annotations

import struct
from typing import Any

STOP, BOOL, BYTE, DOUBLE, I16, I32, I64, STRING, STRUCT, MAP, SET, LIST = 0, 2, 3, 4, 6, 8, 10, 11, 12, 13, 14, 15

_FIXED = {  # type -> (struct format, size)
    BOOL: (">?", 1), BYTE: (">b", 1), DOUBLE: (">d", 8), I16: (">h", 2), I32: (">i", 4), I64: (">q", 8),
}


class ThriftError(ValueError):
    """The bytes are not a well-formed binary-protocol value."""


class _Reader:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.pos = 0

    def value(self, kind: int) -> Any:
        data, pos = self.data, self.pos
        if kind == STRUCT:
            return self.struct()
        if kind in _FIXED:
            fmt, size = _FIXED[kind]
            self.pos = pos + size
            return struct.unpack_from(fmt, data, pos)[0]
        if kind == STRING:
            (n,) = struct.unpack_from(">i", data, pos)
            self.pos = pos + 4 + n
            if n < 0 or self.pos > len(data):
                raise ThriftError(f"bad string length {n} at byte {pos}")
            return data[pos + 4 : self.pos]
        if kind in (LIST, SET):
            element = data[pos]
            (n,) = struct.unpack_from(">i", data, pos + 1)
            self.pos = pos + 5
            return [self.value(element) for _ in range(n)]
        if kind == MAP:
            key, val = data[pos], data[pos + 1]
            (n,) = struct.unpack_from(">i", data, pos + 2)
            self.pos = pos + 6
            return {self.value(key): self.value(val) for _ in range(n)}
        raise ThriftError(f"unknown field type {kind} at byte {pos}")

    def struct(self) -> dict[int, Any]:
        out: dict[int, Any] = {}
        data = self.data
        while True:
            kind = data[self.pos]
            if kind == STOP:
                self.pos += 1
                return out
            (field,) = struct.unpack_from(">h", data, self.pos + 1)
            self.pos += 3
            out[field] = self.value(kind)


def read_struct(data: bytes) -> dict[int, Any]:
    """Decode one binary-protocol struct that spans all of `data`."""
    reader = _Reader(data)
    try:
        out = reader.struct()
    except (IndexError, struct.error) as e:
        raise ThriftError(f"truncated Thrift data near byte {reader.pos}") from e
    if reader.pos != len(data):
        raise ThriftError(f"{len(data) - reader.pos} bytes left after the struct")
    return out
