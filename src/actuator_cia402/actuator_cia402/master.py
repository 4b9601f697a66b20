# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The CiA 402 master for one joint drive on a canopen.Network (RemoteNode from the drive's EDS).

Layered like ros2_canopen's cia402 driver: ROS-free, called by the driver node's lifecycle
transitions and by its cycle thread.

  configure   NMT pre-operational; object dictionary checks over SDO (device type 0x1000 =
              profile 402, CST supported in 0x6502, rated current 0x6075 / torque 0x6076 and
              encoder resolution 0x608F as configured, max torque 0x6072); PDO mapping (RPDO1:
              0x6040 + 0x6071; TPDO1: 0x6041 + 0x6064 + 0x6077; TPDO2: 0x6078 + 0x603F; all
              synchronous, transmission type 1); communication cycle 0x1006; mode of operation
              0x6060 = CST (10), checked in 0x6061.
  activate    fault reset if the drive is in fault; shutdown, switch on, enable operation (each
              waited for in the statusword); NMT operational. SYNC then comes from the cycle.
  cycle       write RPDO1 (controlword, target torque), send SYNC, wait at most a deadline for
              TPDO1 of this SYNC (after a miss, for the newest of two); never an SDO transfer or
              a state wait.
  deactivate  quick stop, disable voltage (the drive engages its brake), NMT pre-operational.
  error       the statusword fault bit (TPDO1) or an EMCY with a non-zero error register sets
              ``fault`` with the drive's error code (0x603F / EMCY) and its text.
"""

from __future__ import annotations

import threading
import time
from typing import NamedTuple, Optional

import canopen

from actuator_cia402 import profile as p
from actuator_cia402.pdo_codec import PdoCodec
from actuator_cia402.scaling import Scaling


class Cia402Error(RuntimeError):
    """A drive did not do what the master asked (one line: what, and what the drive said)."""


class Feedback(NamedTuple):
    """Process data of one SYNC, in SI units."""

    position_rad: float
    torque_nm: float
    current_a: float
    statusword: int
    error_code: int
    received_s: float  # canopen receive timestamp of TPDO1


class DriveFault(NamedTuple):
    """What made the master leave operation: the drive's error code and its text."""

    code: int
    text: str
    source: str  # 'statusword', 'emcy' or 'feedback timeout'


#: Transmission type 1: synchronous, every SYNC (CiA 301).
SYNCHRONOUS = 1
STATE_TIMEOUT_S = 1.0


class Cia402Master:
    """One drive in cyclic synchronous torque mode."""

    def __init__(
        self,
        network: canopen.Network,
        node_id: int,
        eds_path: str,
        scaling: Scaling,
        sync_period_s: float,
        rpdo_cob_id: int,
        tpdo1_cob_id: int,
        tpdo2_cob_id: int,
        max_current_a: float,
        state_timeout_s: float = STATE_TIMEOUT_S,
        sdo_timeout_s: float = 0.3,
    ):
        """Attach a RemoteNode built from the drive's EDS to ``network`` (already connected)."""
        self.network = network
        self.node = canopen.RemoteNode(node_id, eds_path)
        network.add_node(self.node)
        self.node.sdo.RESPONSE_TIMEOUT = sdo_timeout_s
        self.state_timeout_s = state_timeout_s
        self.scaling = scaling
        self.sync_period_s = sync_period_s
        self.cob_ids = (rpdo_cob_id, tpdo1_cob_id, tpdo2_cob_id)
        self.max_current_a = max_current_a
        self.fault: Optional[DriveFault] = None
        self.warnings: list[str] = []
        self.feedback: Optional[Feedback] = None
        self.error_code = 0
        self.current_actual_a = 0.0
        self.tpdo1_count = 0
        self._arrived = (
            threading.Condition()
        )  # TPDO1 arrivals since the last SYNC (bus thread -> cycle)
        self._arrivals = 0
        self._missed_last = False
        self._rpdo = None
        self.node.emcy.add_callback(self._on_emcy)

    # --- configure --------------------------------------------------------------------------
    def _sdo(self, index: int, subindex: int | None = None):
        """Return the SDO variable of an object.

        Blocking transfers: configure/activate/deactivate only.
        """
        return self.node.sdo[index] if subindex is None else self.node.sdo[index][subindex]

    def configure(self) -> list[str]:
        """NMT pre-operational, OD checks, PDO mapping, CST mode.

        Returns notes (raises Cia402Error).
        """
        self.node.nmt.state = 'PRE-OPERATIONAL'
        try:
            device_type = self._sdo(p.DEVICE_TYPE).raw
        except canopen.SdoCommunicationError as exc:
            raise Cia402Error(
                f'node {self.node.id} does not answer SDO ({exc}): check node_id, bitrate, '
                f'wiring and termination'
            ) from None
        notes = []
        if device_type & 0xFFFF != p.DEVICE_PROFILE_402:
            raise Cia402Error(
                f'node {self.node.id} is not a CiA 402 drive: device type 0x{device_type:08X}'
            )
        if not self._sdo(p.SUPPORTED_DRIVE_MODES).raw & p.SUPPORTED_CST_BIT:
            raise Cia402Error(
                f'node {self.node.id} does not support cyclic synchronous torque (0x6502 bit 9)'
            )
        self._check_equal(
            p.RATED_CURRENT,
            None,
            round(self.scaling.rated_current_a * 1000),
            'rated current',
            'mA',
        )
        self._check_equal(
            p.RATED_TORQUE,
            None,
            round(self.scaling.rated_torque_nm * 1000),
            'rated torque',
            'mN m',
        )
        increments = self._sdo(p.ENCODER_RESOLUTION, 1).raw / max(
            1, self._sdo(p.ENCODER_RESOLUTION, 2).raw
        )
        if increments != self.scaling.encoder_counts_per_rev:
            raise Cia402Error(
                f'encoder resolution 0x608F is {increments:g} counts/rev, configured '
                f'encoder_counts_per_rev = {self.scaling.encoder_counts_per_rev}'
            )
        max_torque = self._sdo(p.MAX_TORQUE).raw
        needed = self.scaling.current_to_torque_permille(self.max_current_a)
        if max_torque < needed:
            notes.append(
                f'max torque 0x6072 = {max_torque} per mille is below the current limit '
                f'({needed} per mille): the drive clips commands beyond '
                f'{self.scaling.torque_permille_to_current(max_torque):.2f} A'
            )
        self._map_pdos()
        self._sdo(p.COMMUNICATION_CYCLE_US).raw = int(round(self.sync_period_s * 1e6))
        self._sdo(p.MODES_OF_OPERATION).raw = p.MODE_CST
        shown = self._sdo(p.MODES_OF_OPERATION_DISPLAY).raw
        if shown != p.MODE_CST:
            raise Cia402Error(
                f'drive refused mode CST (0x6061 shows {shown} after writing 10 to 0x6060)'
            )
        return notes

    def _check_equal(
        self, index: int, subindex: int | None, expected: int, what: str, unit: str
    ) -> None:
        """Refuse a drive whose object differs from the configured value by more than 1 %."""
        actual = self._sdo(index, subindex).raw
        if abs(actual - expected) > 0.01 * abs(expected):
            raise Cia402Error(
                f'{what} 0x{index:04X} of the drive is {actual} {unit}, '
                f'configured {expected} {unit}'
            )

    def _map_pdos(self) -> None:
        """RPDO1, TPDO1, TPDO2 as listed in the module docstring; the other PDOs disabled."""
        rpdo_cob, tpdo1_cob, tpdo2_cob = self.cob_ids
        layout = (
            (self.node.rpdo[1], rpdo_cob, (p.CONTROLWORD, p.TARGET_TORQUE)),
            (self.node.tpdo[1], tpdo1_cob, (p.STATUSWORD, p.POSITION_ACTUAL, p.TORQUE_ACTUAL)),
            (self.node.tpdo[2], tpdo2_cob, (p.CURRENT_ACTUAL, p.ERROR_CODE)),
        )
        for pdo_map, cob_id, objects in layout:
            pdo_map.clear()
            for index in objects:
                pdo_map.add_variable(index)
            pdo_map.cob_id, pdo_map.trans_type, pdo_map.enabled = cob_id, SYNCHRONOUS, True
            pdo_map.save()
        for maps, used in ((self.node.rpdo, 1), (self.node.tpdo, 2)):
            for number, pdo_map in maps.map.items():
                if number > used:
                    pdo_map.clear()
                    pdo_map.cob_id = pdo_map.predefined_cob_id or (
                        0x100 * (number + 1) + self.node.id
                    )
                    pdo_map.trans_type, pdo_map.enabled = SYNCHRONOUS, False
                    pdo_map.save()
        # The layouts just written, compiled once: the cycle packs and unpacks whole frames.
        self._rpdo = PdoCodec.compile(self.node.rpdo[1])
        self._t1 = PdoCodec.compile(self.node.tpdo[1])
        self._t2 = PdoCodec.compile(self.node.tpdo[2])
        if None in (self._rpdo, self._t1, self._t2):
            raise Cia402Error('the EDS gives a PDO layout that is not byte aligned')
        self.node.tpdo[1].add_callback(self._on_tpdo1)
        self.node.tpdo[2].add_callback(self._on_tpdo2)

    # --- state machine over SDO (transitions only) ------------------------------------------
    def read_state(self) -> tuple[int, p.State | None]:
        """Statusword 0x6041 over SDO and its decoded state."""
        statusword = self._sdo(p.STATUSWORD).raw
        return statusword, p.decode_state(statusword)

    def command(self, command: p.Command, wanted: tuple[p.State, ...]) -> p.State:
        """Write a controlword command and wait for one of the ``wanted`` states.

        Waits up to state_timeout_s until the statusword shows one of ``wanted``.
        """
        timeout_s = self.state_timeout_s
        self._sdo(p.CONTROLWORD).raw = command.value
        deadline = time.monotonic() + timeout_s
        while True:
            statusword, state = self.read_state()
            if state in wanted:
                return state
            if time.monotonic() > deadline:
                names = ' or '.join(f"'{s.value}'" for s in wanted)
                raise Cia402Error(
                    f'{command.name.lower()}: the drive did not reach {names} within '
                    f'{timeout_s:g} s '
                    f'(statusword 0x{statusword:04X} = {state.value if state else "undefined"})'
                )
            time.sleep(0.002)

    def fault_reset(self) -> None:
        """Rising edge of controlword bit 7 (CiA 402 transition 15), then 'switch on disabled'."""
        self._sdo(p.CONTROLWORD).raw = 0
        self.command(p.Command.FAULT_RESET, (p.State.SWITCH_ON_DISABLED,))
        self._sdo(p.CONTROLWORD).raw = p.Command.DISABLE_VOLTAGE.value

    def activate(self) -> list[str]:
        """Fault reset if needed, shutdown, switch on, enable operation, NMT operational.

        Returns notes.
        """
        notes = []
        statusword, state = self.read_state()
        if state in (p.State.FAULT, p.State.FAULT_REACTION_ACTIVE):
            code = self._sdo(p.ERROR_CODE).raw
            notes.append(
                f'drive was in fault (0x603F = 0x{code:04X}: {p.error_text(code)}): fault reset'
            )
            self.fault_reset()
        self.fault = None
        self.node.emcy.reset()
        self.command(p.Command.SHUTDOWN, (p.State.READY_TO_SWITCH_ON,))
        self.command(p.Command.SWITCH_ON, (p.State.SWITCHED_ON,))
        self.command(p.Command.ENABLE_OPERATION, (p.State.OPERATION_ENABLED,))
        self.feedback = None
        self.node.nmt.state = 'OPERATIONAL'
        # NMT has no answer; an SDO round trip after it (same bus, in order) shows the drive
        # took it.
        statusword, state = self.read_state()
        if state is not p.State.OPERATION_ENABLED:
            raise Cia402Error(
                f'the drive left operation enabled on NMT start (statusword 0x{statusword:04X})'
            )
        return notes

    def deactivate(self) -> None:
        """Quick stop, then disable voltage (brake engaged by the drive), NMT pre-operational."""
        try:
            self.command(
                p.Command.QUICK_STOP,
                (p.State.QUICK_STOP_ACTIVE, p.State.SWITCH_ON_DISABLED, p.State.FAULT),
            )
            self.command(p.Command.DISABLE_VOLTAGE, (p.State.SWITCH_ON_DISABLED, p.State.FAULT))
        finally:
            self.node.nmt.state = 'PRE-OPERATIONAL'
        self.read_state()  # NMT taken (see activate)

    def read_error(self) -> tuple[int, str]:
        """Return the drive's error code 0x603F over SDO, with its text."""
        code = self._sdo(p.ERROR_CODE).raw
        return code, p.error_text(code)

    # --- cycle (never blocks beyond ``wait_s``) ---------------------------------------------
    def cycle(self, controlword: int, current_a: float, wait_s: float) -> Optional[Feedback]:
        """RPDO1 with the command, SYNC, then TPDO1 of this SYNC (None when it missed ``wait_s``).

        TPDO1 carries no SYNC counter, so after a missed cycle the first TPDO1 to arrive may be
        the late answer to the previous SYNC: then the cycle waits for a second one until the
        deadline and takes the newest (at most one extra wait, in the cycle after a miss).
        """
        rpdo = self._rpdo
        expected = 2 if self._missed_last else 1
        with self._arrived:
            self._arrivals = 0
        self.network.send_message(
            rpdo.cob_id,
            rpdo.pack((controlword, self.scaling.current_to_torque_permille(current_a))),
        )
        self.network.sync.transmit()
        deadline = time.monotonic() + wait_s
        with self._arrived:
            while self._arrivals < expected:
                left = deadline - time.monotonic()
                if left <= 0.0 or not self._arrived.wait(left):
                    break
            got = self._arrivals > 0
        self._missed_last = not got
        return self.feedback if got else None

    def _on_tpdo1(self, pdo_map) -> None:
        """TPDO1 received (bus thread): statusword, position, torque.

        The fault bit sets ``fault``.
        """
        statusword, counts, torque = self._t1.unpack(pdo_map.data)
        s = self.scaling
        self.feedback = Feedback(
            s.counts_to_rad(counts),
            s.torque_permille_to_nm(torque),
            self.current_actual_a,
            statusword,
            self.error_code,
            pdo_map.timestamp,
        )
        self.tpdo1_count += 1
        if statusword & p.SW_FAULT and self.fault is None:
            code = self.error_code
            self.fault = DriveFault(code, p.error_text(code), 'statusword')
        with self._arrived:
            self._arrivals += 1
            self._arrived.notify()

    def _on_tpdo2(self, pdo_map) -> None:
        """TPDO2 received (bus thread): current actual and error code."""
        current, code = self._t2.unpack(pdo_map.data)
        self.current_actual_a = self.scaling.permille_to_current(current)
        self.error_code = code
        if self.fault is not None and self.fault.code == 0 and code:
            self.fault = DriveFault(code, p.error_text(code), self.fault.source)

    def _on_emcy(self, emcy) -> None:
        """EMCY (bus thread): an error register != 0 is a fault.

        Otherwise a warning kept in ``warnings``.
        """
        if emcy.code == 0:
            return
        if emcy.register:
            if self.fault is None or self.fault.code == 0:
                self.fault = DriveFault(emcy.code, p.error_text(emcy.code), 'emcy')
        else:
            self.warnings.append(
                f'EMCY 0x{emcy.code:04X} ({p.error_text(emcy.code)}) without error register'
            )
