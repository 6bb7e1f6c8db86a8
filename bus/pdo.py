"""PDO mapping (CiA 301 §7.2.2): mapping entries to a packed struct, both directions.

A mapping entry is ``index << 16 | subindex << 8 | bit length``. Both the simulated node
(encode TPDO, decode RPDO) and the master (encode RPDO, decode TPDO) use :class:`Layout`.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

import canopen

from stand.errors import ProfileError

#: CiA 301 data type code to struct format character.
_FORMATS = {0x1: "?", 0x2: "b", 0x3: "h", 0x4: "i", 0x5: "B", 0x6: "H", 0x7: "I", 0x8: "f",
            0x15: "q", 0x1B: "Q", 0x11: "d"}
#: Bit 31 of a PDO COB-ID: the PDO does not exist / is disabled.
COB_ID_INVALID = 0x8000_0000
#: An object to map: its index (the variable at sub-index 0), or (index, sub-index).
Mapped = int | tuple[int, int]
#: Transmission type: synchronous, every SYNC.
SYNCHRONOUS = 1
MAX_PDO_BYTES = 8


def entry(index: int, subindex: int, bits: int) -> int:
    """A mapping entry for object ``index:subindex`` of ``bits`` bits."""
    return (index << 16) | (subindex << 8) | bits


@dataclass(frozen=True)
class Layout:
    """The objects one PDO carries and how they are packed (little endian)."""

    objects: tuple[tuple[int, int], ...]
    packer: struct.Struct

    @classmethod
    def from_entries(cls, od: canopen.ObjectDictionary, entries: Sequence[int]) -> Layout:
        objects, fmt = [], "<"
        for value in entries:
            index, subindex = value >> 16, (value >> 8) & 0xFF
            try:
                fmt += _FORMATS[int(mapped_variable(od, index, subindex).data_type or 0)]
            except (KeyError, ProfileError) as exc:
                raise ProfileError(
                    f"PDO mapping entry 0x{value:08X}: object 0x{index:04X}:{subindex} is not in "
                    "the object dictionary or has no fixed-size type"
                ) from exc
            objects.append((index, subindex))
        packer = struct.Struct(fmt)
        if packer.size > MAX_PDO_BYTES:
            raise ProfileError(f"PDO mapping of {len(objects)} objects needs {packer.size} bytes > 8")
        return cls(tuple(objects), packer)

    @property
    def indices(self) -> tuple[int, ...]:
        return tuple(index for index, _ in self.objects)

    def pack(self, values: Sequence[float | int]) -> bytes:
        return self.packer.pack(*values)

    def unpack(self, data: bytes | bytearray) -> tuple[int, ...]:
        return self.packer.unpack_from(data)


def entries_for(od: canopen.ObjectDictionary, objects: Sequence[Mapped]) -> list[int]:
    """Mapping entries of ``objects`` (an index: the variable at sub-index 0; or (index,
    sub-index): an entry of a record or array), with their bit lengths."""
    return [entry(index, sub, len(mapped_variable(od, index, sub)))
            for index, sub in (o if isinstance(o, tuple) else (o, 0) for o in objects)]


def mapped_variable(od: canopen.ObjectDictionary, index: int,
                    sub: int = 0) -> canopen.objectdictionary.ODVariable:
    """The variable ``index:sub`` of ``od`` (a variable's own sub-index is 0)."""
    try:
        obj = od[index]
        if isinstance(obj, canopen.objectdictionary.ODVariable):
            if sub:
                raise KeyError(sub)
            return obj
        return obj[sub]
    except KeyError as exc:
        raise ProfileError(f"object 0x{index:04X}:{sub:02X} is not in the drive's EDS") from exc
