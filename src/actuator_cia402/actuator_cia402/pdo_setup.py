# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The cycle's PDO mapping written to a drive over SDO, then read back entry by entry.

canopen's ``PdoMap.save()`` skips, without an error, a mapping entry its EDS marks as not
writable, and a drive may answer a write and keep its own entry (a fixed mapping): the frame's
layout then differs from the one the master decodes. So every entry, the number of entries,
the COB-ID and the transmission type are read back after writing; the first difference is
returned as one line (the master refuses the drive with it).
"""

from __future__ import annotations

from typing import Optional

from actuator_cia402 import profile as p
from actuator_cia402.pdo_codec import PdoCodec

#: Transmission type 1: synchronous, every SYNC (CiA 301).
SYNCHRONOUS = 1
#: Cycle PDO layout: RPDO1, TPDO1, TPDO2 (docs/cia402.md#bus-load: 4, 8, 5 bytes).
RPDO1 = (p.CONTROLWORD, p.TARGET_TORQUE)
TPDO1 = (p.STATUSWORD, p.POSITION_ACTUAL, p.TORQUE_ACTUAL)
TPDO2 = (p.CURRENT_ACTUAL, p.ERROR_CODE, p.MODES_OF_OPERATION_DISPLAY)


#: COB-ID bit 30 of a PDO communication record: no RTR (the drive's own business).
RTR_NOT_ALLOWED = 1 << 30
NAMES = ('RPDO1', 'TPDO1', 'TPDO2')


def layout(node, cob_ids: tuple[int, int, int]) -> tuple:
    """Return ((pdo_map, cob_id, objects), ...) of RPDO1, TPDO1, TPDO2 on a canopen RemoteNode."""
    rpdo_cob, tpdo1_cob, tpdo2_cob = cob_ids
    return (
        (node.rpdo[1], rpdo_cob, RPDO1),
        (node.tpdo[1], tpdo1_cob, TPDO1),
        (node.tpdo[2], tpdo2_cob, TPDO2),
    )


def write_mapping(node, cob_ids: tuple[int, int, int]) -> tuple:
    """Map RPDO1, TPDO1, TPDO2 synchronously, disable the other PDOs; return their codecs."""
    used = layout(node, cob_ids)
    for pdo_map, cob_id, objects in used:
        pdo_map.clear()
        for index in objects:
            pdo_map.add_variable(index)
        pdo_map.cob_id, pdo_map.trans_type, pdo_map.enabled = cob_id, SYNCHRONOUS, True
        pdo_map.save()
    for maps, count in ((node.rpdo, 1), (node.tpdo, 2)):
        for number, pdo_map in maps.map.items():
            if number > count:
                pdo_map.clear()
                pdo_map.cob_id = pdo_map.predefined_cob_id or (0x100 * (number + 1) + node.id)
                pdo_map.trans_type, pdo_map.enabled = SYNCHRONOUS, False
                pdo_map.save()
    return tuple(PdoCodec.compile(m) for m, _, _ in used)


def expected_objects(node, cob_ids: tuple[int, int, int]) -> list[tuple[int, int, int, str]]:
    """Return (index, subindex, value, what) of every object the mapping should show."""
    wanted = []
    for name, (pdo_map, cob_id, _) in zip(NAMES, layout(node, cob_ids)):
        com, mapping = pdo_map.com_record.od.index, pdo_map.map_array.od.index
        wanted.append((com, 1, cob_id, f'{name} COB-ID'))
        wanted.append((com, 2, SYNCHRONOUS, f'{name} transmission type'))
        wanted.append((mapping, 0, len(pdo_map.map), f'{name} number of mapped objects'))
        for sub, var in enumerate(pdo_map.map, start=1):
            entry = var.index << 16 | var.subindex << 8 | var.length
            wanted.append((mapping, sub, entry, f'{name} mapping entry {sub}'))
    return wanted


def read_back(sdo_read, wanted) -> Optional[str]:
    """Compare the drive's objects (``sdo_read(index, sub)``) with ``wanted``; the first miss."""
    for index, sub, value, what in wanted:
        back = sdo_read(index, sub)
        if what.endswith('COB-ID'):
            back &= ~RTR_NOT_ALLOWED
        if back != value:
            return (
                f'{what} 0x{index:04X}:{sub} reads 0x{back:08X} after writing 0x{value:08X} '
                '(an entry the drive keeps, or that canopen skipped as not writable in the '
                "EDS): the frame's layout would not be the one decoded"
            )
    return None
