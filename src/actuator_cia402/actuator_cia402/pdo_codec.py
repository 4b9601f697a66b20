# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Fast packing of a PDO's mapped objects with one precompiled struct (CiA 301 PDO mapping).

canopen's PdoVariable.raw decodes and encodes through the object dictionary on every access
(about 10 us per object here); the cycle path packs the whole frame at once instead. Only
byte-aligned mappings of whole objects are compiled; ``PdoCodec.compile`` returns None for
any other, and the caller keeps canopen's accessors.
"""

from __future__ import annotations

import struct
from typing import Optional, Sequence


class PdoCodec:
    """Pack/unpack the objects of one mapped PDO (little endian, in mapping order)."""

    def __init__(self, fmt: struct.Struct, cob_id: int):
        """Return a compiled layout for the frames of ``cob_id``."""
        self.struct = fmt
        self.cob_id = cob_id

    @classmethod
    def compile(cls, pdo_map) -> Optional['PdoCodec']:
        """Codec of a canopen PdoMap whose variables are whole, byte-aligned and contiguous.

        None otherwise.
        """
        chars, offset = [], 0
        for var in pdo_map.map:
            od = var.od
            fmt = od.STRUCT_TYPES.get(od.data_type) if hasattr(od, 'STRUCT_TYPES') else None
            if fmt is None or var.offset != offset or var.length != 8 * fmt.size:
                return None
            chars.append(fmt.format.lstrip('<'))
            offset += var.length
        return cls(struct.Struct('<' + ''.join(chars)), pdo_map.cob_id)

    def pack(self, values: Sequence[int]) -> bytes:
        """Return the frame's data bytes for ``values`` (one per mapped object)."""
        return self.struct.pack(*values)

    def unpack(self, data: bytes) -> tuple:
        """Return the mapped objects' values from a received frame."""
        return self.struct.unpack_from(data)
