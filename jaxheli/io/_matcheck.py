"""Structure check of a MATLAB v5 file before scipy parses it.

scipy's compiled MAT reader trusts element tags: an unknown data type in a tag (one changed byte) makes it
index past its type table and kill the process. This walk reads every tag first, inflating compressed
variables, and refuses the file unless each element has a known type and lies inside its parent, and the
arrays agree with their headers (numeric data as long as the dimensions say, cells and structs with as many
children as they declare). Files that are not v5 (v4, v7.3/HDF5) are left to scipy.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

from ..data.flight import FlightDataError

_HEADER = 128
_MATRIX, _COMPRESSED = 14, 15
_SIZES = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8, 16: 1, 17: 2, 18: 4}
"""Bytes per value of each MAT-v5 data type (miINT8 .. miUTF32, without the matrix and compressed tags)."""
_NUMERIC_CLASSES = range(6, 16)  # mxDOUBLE .. mxUINT64
_CELL, _STRUCT, _OBJECT, _CHAR, _OPAQUE = 1, 2, 3, 4, 17
_CLASSES = range(1, 18)
_MAX_DEPTH = 64


class _Corrupt(Exception):
    """A structural fault (the message says where)."""


def check_mat(path: Path) -> None:
    """Raise :class:`FlightDataError` naming the file, the variable's offset (and the array, where it has a
    name) and the fault when a v5 file's structure is inconsistent; return quietly for well-formed v5 files
    and for files of other versions."""
    data = path.read_bytes()
    if len(data) < _HEADER or data[126:128] not in (b"IM", b"MI") or 0 in data[:4]:
        return
    order = "<" if data[126:128] == b"IM" else ">"
    if struct.unpack_from(order + "H", data, 124)[0] != 0x0100:
        return
    pos = _HEADER
    try:
        while pos < len(data):
            if len(data) - pos < 8:
                raise _Corrupt(f"{len(data) - pos} stray bytes after the last variable")
            kind, size = struct.unpack_from(order + "II", data, pos)
            if kind not in (_MATRIX, _COMPRESSED) or size == 0 or pos + 8 + size > len(data):
                raise _Corrupt(f"variable tag (type {kind}, {size} bytes) invalid or past the end of the file")
            body = data[pos + 8: pos + 8 + size]
            if kind == _COMPRESSED:
                body = _inflate(body)
                inner, length = struct.unpack_from(order + "II", body, 0) if len(body) >= 8 else (0, 0)
                if inner != _MATRIX or 8 + length > len(body):
                    raise _Corrupt(f"compressed variable holds no valid matrix tag (type {inner}, {length} bytes)")
                body = body[8: 8 + length]
            _matrix(order, body, 0)
            pos += 8 + size
    except _Corrupt as exc:
        raise FlightDataError(f"{path}: not a readable MATLAB file: corrupt variable at byte {pos}: {exc}") from None


def _inflate(block: bytes) -> bytes:
    """The inflated variable; its zlib stream must be whole (it ends with a checksum, checked here)."""
    stream = zlib.decompressobj()
    try:
        body = stream.decompress(block)
    except zlib.error as exc:
        raise _Corrupt(f"compressed variable does not inflate ({exc})") from None
    if not stream.eof:
        raise _Corrupt("compressed variable ends before its zlib stream does (truncated)")
    return body


def _elements(order: str, body: bytes) -> list[tuple[int, int, int]]:
    """``(type, start, size)`` of each tagged element in a matrix body (small elements included)."""
    out, pos = [], 0
    while pos < len(body):
        if len(body) - pos < 8:
            raise _Corrupt(f"{len(body) - pos} stray bytes at the end of a matrix")
        word, size = struct.unpack_from(order + "II", body, pos)
        if word >> 16:
            kind, size, start, step = word & 0xFFFF, word >> 16, pos + 4, 8
            if size > 4:
                raise _Corrupt(f"small element of {size} bytes (at most 4)")
        else:
            kind, start, step = word, pos + 8, 8 + -(-size // 8) * 8
        if kind not in _SIZES and kind != _MATRIX:
            raise _Corrupt(f"element of unknown data type {kind}")
        if start + size > len(body):
            raise _Corrupt(f"element of type {kind} runs {start + size - len(body)} bytes past its matrix")
        out.append((kind, start, size))
        pos += step
    return out


def _ints(order: str, body: bytes, element: tuple[int, int, int]) -> tuple[int, ...]:
    _, start, size = element
    return struct.unpack_from(f"{order}{size // 4}i", body, start)


def _matrix(order: str, body: bytes, depth: int) -> None:
    """Check one matrix body and its children."""
    if depth > _MAX_DEPTH:
        raise _Corrupt(f"arrays nested deeper than {_MAX_DEPTH} levels")
    parts = _elements(order, body)
    if not parts:
        return
    flags_kind, flags_at, flags_size = parts[0]
    if (flags_kind, flags_size) != (6, 8):
        raise _Corrupt("matrix without its array-flags element")
    cls = struct.unpack_from(order + "I", body, flags_at)[0] & 0xFF
    if cls == _OPAQUE:  # class-system objects: type-name strings, then the matrices holding their data
        _children(order, body, parts[1:], depth)
        return
    if len(parts) < 3:
        raise _Corrupt(f"matrix header of {len(parts)} elements (array flags, dimensions, name)")
    (dims_kind, _, dims_size), (name_kind, name_at, name_size) = parts[1:3]
    if dims_kind != 5 or dims_size % 4 or dims_size < 8 or name_kind != 1:
        raise _Corrupt("matrix header (array flags, dimensions, name) malformed")
    dims = _ints(order, body, parts[1])
    name = body[name_at: name_at + name_size].decode("latin-1")
    if cls not in _CLASSES or min(dims) < 0:
        raise _Corrupt(f"array '{name}': class {cls} or dimensions {dims} invalid")
    count = 1
    for d in dims:
        count *= d
    rest = parts[3:]
    if cls in _NUMERIC_CLASSES:
        _numeric(name, rest, count)
    elif cls == _CHAR:
        if len(rest) > 1 or any(kind == _MATRIX for kind, _, _ in rest):
            raise _Corrupt(f"char array '{name}': {len(rest)} data elements")
    else:
        _children(order, body, _fields(order, body, name, cls, rest, count) if cls in (_CELL, _STRUCT, _OBJECT)
                  else rest, depth)


def _children(order: str, body: bytes, parts: list[tuple[int, int, int]], depth: int) -> None:
    """Check the matrices among ``parts``, one level deeper."""
    for kind, start, size in parts:
        if kind == _MATRIX:
            _matrix(order, body[start: start + size], depth + 1)


def _numeric(name: str, rest: list[tuple[int, int, int]], count: int) -> None:
    """Real (and imaginary) data of a numeric array: ``count`` values each."""
    if len(rest) not in (1, 2) or any(kind == _MATRIX for kind, _, _ in rest):
        raise _Corrupt(f"numeric array '{name}': {len(rest)} data elements (expected real and optional imaginary)")
    for kind, _, size in rest:
        if size != count * _SIZES[kind]:
            raise _Corrupt(f"numeric array '{name}': {size} data bytes for {count} values of {_SIZES[kind]} bytes")


def _fields(
    order: str, body: bytes, name: str, cls: int, rest: list[tuple[int, int, int]], count: int
) -> list[tuple[int, int, int]]:
    """The child matrices of a cell, struct or object, checked against the declared count."""
    per = 1
    if cls != _CELL:
        rest = rest[1:] if cls == _OBJECT else rest  # an object's class name comes first
        if len(rest) < 2 or rest[0][0] != 5 or rest[0][2] != 4 or rest[1][0] != 1:
            raise _Corrupt(f"struct '{name}': field-name header malformed")
        width = _ints(order, body, rest[0])[0]
        if width <= 0 or rest[1][2] % width:
            raise _Corrupt(f"struct '{name}': field names of {rest[1][2]} bytes in width {width}")
        per, rest = rest[1][2] // width, rest[2:]
    if len(rest) != count * per or any(kind != _MATRIX for kind, _, _ in rest):
        raise _Corrupt(f"{'cell' if cls == _CELL else 'struct'} '{name}': {len(rest)} elements for {count} x {per}")
    return rest
