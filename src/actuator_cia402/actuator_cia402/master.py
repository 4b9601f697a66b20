# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The CiA 402 master's SDO side for one drive: configure, enable, stop, fault acknowledgement.

ROS-free; called by ``Cia402Joint`` (joint.py) in its lifecycle transitions, never in the cycle.
Every object it reads or writes, and why: docs/cia402.md#every-object-the-driver-reads-or-writes.

  configure   NMT reset communication and boot-up; device type, identity 0x1018 against the
              EDS; a drive left enabled is stopped (quick stop, ramp, brake, disable voltage);
              SYNC COB-ID 0x1005 = 0x80 without bit 30 (the drive produces no SYNC: one
              producer per bus); 0x6071 = 0; rated current/torque, encoder resolution, factor
              group 0x6091/0x6092 and polarity 0x607E checked; limits 0x6072/0x6073/0x6080,
              option codes 0x605A = 2 (no transition 16)/0x605C, torque slope 0x6087 and
              quick stop deceleration 0x6085 written and read back; 0x605E read; SYNC counter
              0x1019 (a SYNC producer, when the EDS has it), SYNC period 0x1006, window 0x1007,
              interpolation period 0x60C2; PDO mapping written and read back; heartbeat consumer
              0x1016, abort connection 0x6007 and the drive's heartbeat 0x1017; mode 0x6060.
              Every value written is kept and read back again at enable (``verify``).
  enable      the configuration verified (a drive that rebooted has lost it); 0x6071 = 0, mode
              display 0x6061 polled; shutdown, switch on (brake still closed); NMT
              operational. Operation is enabled by the first valid command, in the cycle.
  stop        quick stop; wait for the drive's end state (0x605A = 2: 'switch on disabled' by
              itself; never statusword bit 10) and the brake's 'closed'; then disable voltage
              whatever failed before; a drive that keeps its voltage gets NMT stop.
  acknowledge fault reset (rising edge of controlword bit 7), only when a person asks.
"""

from __future__ import annotations

import math
import time
from typing import Optional

import canopen

from actuator_cia402 import pdo_setup
from actuator_cia402 import profile as p
from actuator_cia402.scaling import Scaling
from actuator_cia402.supervision import DISABLED_STATES, describe


class Cia402Error(RuntimeError):
    """A drive did not do what the master asked (one line: what, and what the drive said)."""


#: Option codes this master sets (CiA 402-2): quick stop = the quick stop ramp, then 'switch
#: on disabled' by the drive itself (2: no transition 16, so an 'enable operation' in flight
#: cannot undo a quick stop the drive made on its own input; 5-8 would stay in 'quick stop
#: active' and allow it); disable operation = ramp, then disable; abort connection
#: (heartbeat lost) = quick stop.
QUICK_STOP_OPTION = 2
DISABLE_OPERATION_OPTION = 1
ABORT_CONNECTION_QUICK_STOP = 3
#: The SYNC COB-ID every node listens on, no node producing it but this master (0x1005).
SYNC_COB_ID = 0x80
#: A quick stop ends in one of these states (a disable-operation reaction under way ends in
#: 'switched on').
STOP_ENDS = (*DISABLED_STATES, p.State.SWITCHED_ON, p.State.READY_TO_SWITCH_ON)


class Cia402Master:
    """SDO configuration and state transitions of one drive in cyclic synchronous torque."""

    def __init__(
        self, network: canopen.Network, node_id: int, eds_path: str, scaling: Scaling, cfg
    ):
        """Attach a RemoteNode from the drive's EDS; ``cfg`` is a DriverParameters."""
        self.network = network
        self.node = canopen.RemoteNode(node_id, eds_path)
        network.add_node(self.node)
        self.node.sdo.RESPONSE_TIMEOUT = cfg.sdo_timeout_s
        self.cfg = cfg
        self.scaling = scaling
        self.codecs: tuple = ()
        self.identity = ''
        self.fault_reaction = 0
        self.sync_counter_overflow = 0  # 0x1019 as configured: 0, SYNCs carry no counter
        self.brake_index, self.brake_mask = cfg.brake_status
        #: Every object configure wrote: (index, subindex) -> (value, what); ``verify`` reads
        #: them back at enable.
        self.configured: dict[tuple[int, int], tuple[int, str]] = {}
        self.disabled = False  # the last stop saw the drive disabled (or in fault)

    def _sdo(self, index: int, subindex: Optional[int] = None):
        """Return the SDO variable of an object (blocking transfers: transitions only)."""
        return self.node.sdo[index] if subindex is None else self.node.sdo[index][subindex]

    def _write_verified(
        self, index: int, subindex: Optional[int], value: int, what: str, kept: bool = True
    ) -> None:
        """Write an object and read it back; Cia402Error when the drive keeps another value.

        ``kept``: a configuration object, read back again at enable (a process object is not).
        """
        var = self._sdo(index, subindex)
        var.raw = value
        back = var.raw
        if back != value:
            raise Cia402Error(f'{what} 0x{index:04X} reads {back} after writing {value}')
        if kept:
            self.configured[(index, subindex or 0)] = (value, what)

    def verify(self) -> None:
        """Read back every object configure wrote; Cia402Error on the first that changed."""
        for (index, subindex), (value, what) in self.configured.items():
            back = self._sdo(index, subindex if self._is_record(index) else None).raw
            if back != value:
                raise Cia402Error(
                    f"the drive's configuration changed since configure: {what} 0x{index:04X}"
                    f':{subindex} reads {back}, configured {value} (rebooted or changed by a '
                    'tool?): configure again'
                )

    def _is_record(self, index: int) -> bool:
        """Whether an object has subindices (a record or an array)."""
        return not isinstance(
            self.node.object_dictionary[index], canopen.objectdictionary.ODVariable
        )

    # --- configure --------------------------------------------------------------------------
    def reset_communication(self) -> None:
        """NMT reset communication; wait for the boot-up (communication objects at defaults)."""
        booted = []
        self.node.nmt.add_heartbeat_callback(
            lambda state: booted.append(state) if state == 0 else None
        )
        self.node.nmt.state = 'RESET COMMUNICATION'
        deadline = time.monotonic() + self.cfg.state_timeout_s
        while not booted:
            if time.monotonic() > deadline:
                raise Cia402Error(
                    f'node {self.node.id} sent no boot-up within {self.cfg.state_timeout_s:g} s '
                    'of NMT reset communication: check node_id, bitrate, wiring and termination'
                )
            time.sleep(0.002)
        self.node.nmt._callbacks.clear()

    def check_identity(self) -> str:
        """Device type 402 with CST; identity 0x1018 equal to the EDS's vendor and product."""
        try:
            device_type = self._sdo(p.DEVICE_TYPE).raw
        except canopen.SdoCommunicationError as exc:
            raise Cia402Error(f'node {self.node.id} does not answer SDO ({exc})') from None
        if device_type & 0xFFFF != p.DEVICE_PROFILE_402:
            raise Cia402Error(
                f'node {self.node.id} is not a CiA 402 drive: device type 0x{device_type:08X}'
            )
        info = self.node.object_dictionary.device_information
        vendor, product = self._sdo(p.IDENTITY, 1).raw, self._sdo(p.IDENTITY, 2).raw
        if (vendor, product) != (info.vendor_number, info.product_number):
            raise Cia402Error(
                f'identity 0x1018 of node {self.node.id} is vendor 0x{vendor:08X} product '
                f'0x{product:08X}; the EDS {info.product_name!r} is for vendor'
                f' 0x{info.vendor_number or 0:08X} product '
                f'0x{info.product_number or 0:08X}: name the EDS of this drive'
            )
        if not self._sdo(p.SUPPORTED_DRIVE_MODES).raw & p.SUPPORTED_CST_BIT:
            raise Cia402Error(f'node {self.node.id} does not support cyclic synchronous torque')
        revision, serial = self._sdo(p.IDENTITY, 3).raw, self._sdo(p.IDENTITY, 4).raw
        return (
            f'vendor 0x{vendor:08X} product 0x{product:08X} rev 0x{revision:08X} serial {serial}'
        )

    def make_safe(self) -> list[str]:
        """Stop a drive found enabled (a crashed master); report a fault, never reset it."""
        statusword, state = self.read_state()
        notes = []
        if state in (p.State.OPERATION_ENABLED, p.State.QUICK_STOP_ACTIVE):
            notes.append(
                f'drive was left {state.value} (statusword 0x{statusword:04X}, 0x6071 = '
                f'{self._sdo(p.TARGET_TORQUE).raw} per mille): quick stop, brake, '
                'disable voltage'
            )
            self.stop()
        elif state in (p.State.SWITCHED_ON, p.State.READY_TO_SWITCH_ON):
            self._sdo(p.CONTROLWORD).raw = p.Command.DISABLE_VOLTAGE.value
        elif state in (p.State.FAULT, p.State.FAULT_REACTION_ACTIVE):
            code = self._sdo(p.ERROR_CODE).raw
            notes.append(
                f'drive is in fault 0x{code:04X} ({p.error_text(code)}): find the '
                'cause, then acknowledge it (acknowledge_fault); no automatic reset'
            )
        return notes

    def configure(self) -> list[str]:
        """Every step of the module docstring's configure; returns notes (raises Cia402Error)."""
        cfg, s = self.cfg, self.scaling
        self.configured = {}
        self.reset_communication()
        self.identity = self.check_identity()
        notes = self._stop_ramps()  # first: a drive found enabled stops on these
        notes += self.make_safe()
        notes += self._one_sync_producer()
        self._write_verified(p.TARGET_TORQUE, None, 0, 'target torque', kept=False)
        self._check_equal(
            p.RATED_CURRENT, None, round(s.rated_current_a * 1000), 'rated current', 'mA'
        )
        self._check_equal(
            p.RATED_TORQUE, None, round(s.rated_torque_nm * 1000), 'rated torque', 'mN m'
        )
        increments = self._sdo(p.ENCODER_RESOLUTION, 1).raw / max(
            1, self._sdo(p.ENCODER_RESOLUTION, 2).raw
        )
        if increments != s.encoder_counts_per_rev:
            raise Cia402Error(
                f'encoder resolution 0x608F is {increments:g} counts/rev, '
                f'configured encoder_counts_per_rev = {s.encoder_counts_per_rev}'
            )
        for index, what in ((p.GEAR_RATIO, 'gear ratio'), (p.FEED_CONSTANT, 'feed constant')):
            a, b = self._sdo(index, 1).raw, self._sdo(index, 2).raw
            if a != b:
                raise Cia402Error(
                    f'{what} 0x{index:04X} is {a}:{b}; this driver needs 1:1 (position actual in '
                    'motor encoder counts; gear_ratio is applied here)'
                )
        polarity = self._sdo(p.POLARITY).raw
        if polarity != cfg.polarity:
            raise Cia402Error(
                f'polarity 0x607E of the drive is 0x{polarity:02X}, configured '
                f'polarity = 0x{cfg.polarity:02X}: check the drive tool'
            )
        limit_permille = s.current_to_torque_permille(cfg.current_limit_a)
        self._write_verified(p.MAX_TORQUE, None, limit_permille, 'max torque')
        self._write_verified(
            p.MAX_CURRENT, None, s.current_to_permille(cfg.current_limit_a), 'max current'
        )
        rpm = math.ceil(cfg.velocity_limit_rad_s * s.gear_ratio * 60.0 / (2.0 * math.pi))
        self._write_verified(p.MAX_MOTOR_SPEED, None, rpm, 'max motor speed')
        self._write_verified(
            p.DISABLE_OPERATION_OPTION, None, DISABLE_OPERATION_OPTION, 'disable operation option'
        )
        self.fault_reaction = self._sdo(p.FAULT_REACTION_OPTION).raw  # the drive tool's
        period_us = int(round(cfg.sync_period_s * 1e6))
        if cfg.sync_producer and p.SYNC_COUNTER_OVERFLOW in self.node.object_dictionary:
            notes += self._configure_sync_counter()
        self._write_verified(p.COMMUNICATION_CYCLE_US, None, period_us, 'communication cycle')
        self._write_verified(
            p.SYNC_WINDOW_US, None, int(round(cfg.sync_window_fraction * period_us)), 'SYNC window'
        )
        exponent = -6 if period_us % 1000 else -3
        value = period_us if exponent == -6 else period_us // 1000
        if value > 255:
            raise Cia402Error(f'interpolation period {period_us} us does not fit 0x60C2')
        self._write_verified(p.INTERPOLATION_PERIOD, 1, value, 'interpolation period')
        self._write_verified(p.INTERPOLATION_PERIOD, 2, exponent, 'interpolation index')
        self._map_pdos()
        timeout_ms = int(round(cfg.heartbeat_timeout_s * 1000))
        self._write_verified(
            p.HEARTBEAT_CONSUMER, 1, (cfg.master_node_id << 16) | timeout_ms, 'heartbeat consumer'
        )
        self._write_verified(
            p.ABORT_CONNECTION_OPTION, None, ABORT_CONNECTION_QUICK_STOP, 'abort connection option'
        )
        self._write_verified(
            p.HEARTBEAT_PRODUCER_MS,
            None,
            int(round(cfg.drive_heartbeat_period_s * 1000)),
            'producer heartbeat time',
        )
        self._write_verified(p.MODES_OF_OPERATION, None, p.MODE_CST, 'modes of operation')
        return notes

    def _stop_ramps(self) -> list[str]:
        """Write and read back the stop objects: 0x605A, torque slope 0x6087, 0x6085."""
        cfg, notes = self.cfg, []
        self._write_verified(p.QUICK_STOP_OPTION, None, QUICK_STOP_OPTION, 'quick stop option')
        self._write_verified(p.TORQUE_SLOPE, None, cfg.torque_slope_permille_s, 'torque slope')
        if p.QUICK_STOP_DECELERATION in self.node.object_dictionary:
            self._write_verified(
                p.QUICK_STOP_DECELERATION,
                None,
                cfg.quick_stop_deceleration_rpm_s,
                'quick stop deceleration',
            )
        else:
            notes.append(
                f'the EDS of node {self.node.id} has no 0x6085: its quick stop decelerates as '
                'the drive tool set it'
            )
        return notes

    def _configure_sync_counter(self) -> list[str]:
        """Send SYNCs with a counter (0x1019): the drive tells a late SYNC from a skipped one.

        CiA 301 has 0x1019 written while 0x1006 is 0; a drive that refuses it gets SYNCs
        without a counter (returned as a note).
        """
        try:
            self._write_verified(p.COMMUNICATION_CYCLE_US, None, 0, 'communication cycle')
            self._write_verified(
                p.SYNC_COUNTER_OVERFLOW, None, p.SYNC_COUNTER_MAX, 'SYNC counter overflow'
            )
        except (canopen.SdoAbortedError, Cia402Error) as exc:
            return [f'node {self.node.id} takes no SYNC counter (0x1019: {exc}): plain SYNCs']
        self.sync_counter_overflow = p.SYNC_COUNTER_MAX
        return []

    def _check_equal(
        self, index: int, subindex: Optional[int], expected: int, what: str, unit: str
    ) -> None:
        """Refuse a drive whose object differs from the configured value by more than 1 %."""
        actual = self._sdo(index, subindex).raw
        if abs(actual - expected) > 0.01 * abs(expected):
            raise Cia402Error(
                f'{what} 0x{index:04X} of the drive is {actual} {unit}, '
                f'configured {expected} {unit}'
            )

    def _map_pdos(self) -> None:
        """RPDO1, TPDO1, TPDO2 synchronous, the others disabled; every entry read back."""
        self.codecs = pdo_setup.write_mapping(self.node, self.cfg.cob_ids)
        if None in self.codecs:
            raise Cia402Error('the EDS gives a PDO layout that is not byte aligned')
        wanted = pdo_setup.expected_objects(self.node, self.cfg.cob_ids)
        miss = pdo_setup.read_back(lambda index, sub: self._sdo(index, sub).raw, wanted)
        if miss:
            raise Cia402Error(f'node {self.node.id}: {miss}')
        for index, sub, value, what in wanted:
            if not what.endswith('COB-ID'):  # the COB-ID's RTR bit is the drive's
                self.configured[(index, sub)] = (value, what)

    def _one_sync_producer(self) -> list[str]:
        """0x1005 = 0x80 without bit 30: the drive listens to SYNC and produces none itself."""
        value = self._sdo(p.SYNC_COB_ID).raw
        if value != SYNC_COB_ID:
            self._write_verified(p.SYNC_COB_ID, None, SYNC_COB_ID, 'SYNC COB-ID')
            producing = ' (it produced SYNC itself: bit 30)' if value & 1 << 30 else ''
            return [
                f'node {self.node.id} had SYNC COB-ID 0x1005 = 0x{value:08X}{producing}: set to '
                f'0x{SYNC_COB_ID:08X}, one SYNC producer per bus'
            ]
        self.configured[(p.SYNC_COB_ID, 0)] = (value, 'SYNC COB-ID')
        return []

    # --- state machine over SDO (transitions only) ------------------------------------------
    def read_state(self) -> tuple[int, Optional[p.State]]:
        """Statusword 0x6041 over SDO and its decoded state."""
        statusword = self._sdo(p.STATUSWORD).raw
        return statusword, p.decode_state(statusword)

    def command(
        self, command: p.Command, wanted: tuple, timeout_s: Optional[float] = None, done=None
    ) -> int:
        """Write a controlword command; wait until the state is in ``wanted`` (and ``done``)."""
        timeout_s = self.cfg.state_timeout_s if timeout_s is None else timeout_s
        self._sdo(p.CONTROLWORD).raw = command.value
        deadline = time.monotonic() + timeout_s
        while True:
            statusword, state = self.read_state()
            if state in wanted and (done is None or done(statusword)):
                return statusword
            if time.monotonic() > deadline:
                names = ' or '.join(f"'{s.value}'" for s in wanted)
                raise Cia402Error(
                    f'{command.name.lower()}: the drive did not reach {names} within '
                    f'{timeout_s:g} s (statusword 0x{statusword:04X} = '
                    f'{state.value if state else "undefined"})'
                )
            time.sleep(0.002)

    def enable(self) -> None:
        """Verify the configuration; 0x6071 = 0, CST shown, shutdown, switch on, NMT start."""
        self.verify()
        self.disabled = False
        statusword, state = self.read_state()
        if state in (p.State.FAULT, p.State.FAULT_REACTION_ACTIVE):
            code = self._sdo(p.ERROR_CODE).raw
            raise Cia402Error(
                f'drive in fault 0x{code:04X} ({p.error_text(code)}): acknowledge '
                'it (acknowledge_fault) after finding the cause'
            )
        self._write_verified(p.TARGET_TORQUE, None, 0, 'target torque', kept=False)
        deadline = time.monotonic() + self.cfg.state_timeout_s
        while (shown := self._sdo(p.MODES_OF_OPERATION_DISPLAY).raw) != p.MODE_CST:
            if time.monotonic() > deadline:
                raise Cia402Error(
                    f'mode display 0x6061 shows {shown}, not CST (10), '
                    f'{self.cfg.state_timeout_s:g} s after 0x6060 = 10'
                )
            time.sleep(0.002)
        self.command(p.Command.SHUTDOWN, (p.State.READY_TO_SWITCH_ON,))
        self.command(p.Command.SWITCH_ON, (p.State.SWITCHED_ON,))
        self.node.nmt.state = 'OPERATIONAL'
        statusword, state = self.read_state()  # SDO after NMT, in order: NMT taken
        if state is not p.State.SWITCHED_ON:
            raise Cia402Error(f'the drive left switched on at NMT start (0x{statusword:04X})')

    def brake_closed(self) -> Optional[bool]:
        """Read the brake status bit (None when the drive cannot tell: brake_status_index 0)."""
        if not self.brake_index:
            return None
        return bool(self._sdo(self.brake_index).raw & self.brake_mask)

    def stop(self) -> list[str]:
        """Quick stop, the drive's end state, the brake, then disable voltage; returns notes.

        Whatever failed before, disable voltage follows; a drive that still shows its voltage
        after that gets NMT stop, and ``disabled`` stays False (its heartbeat consumer must
        stay armed).
        """
        notes = []
        self.disabled = False
        try:
            statusword, state = self.read_state()
            if state in (p.State.OPERATION_ENABLED, p.State.QUICK_STOP_ACTIVE):
                self.command(
                    p.Command.QUICK_STOP,
                    (*STOP_ENDS, p.State.QUICK_STOP_ACTIVE),
                    done=self._stop_ended,
                )
            notes += self._await_brake()
        except (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError) as exc:
            notes.append(f'quick stop: {exc}; disable voltage follows')
        try:
            statusword, state = self.read_state()
            if state not in DISABLED_STATES:
                self.command(p.Command.DISABLE_VOLTAGE, DISABLED_STATES)
            self.disabled = True
        except (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError) as exc:
            self.node.nmt.state = 'STOPPED'
            notes.append(
                f'disable voltage: {exc}; NMT stop sent to node {self.node.id}, its heartbeat '
                'consumer left armed'
            )
        return notes

    def _stop_ended(self, statusword: int) -> bool:
        """Tell whether a quick stop has ended (never from statusword bit 10).

        Out of quick stop active, or in it with the brake closed (an option code that stays).
        """
        if p.decode_state(statusword) is not p.State.QUICK_STOP_ACTIVE:
            return True
        return bool(self.brake_closed())

    def _await_brake(self) -> list[str]:
        """Wait up to brake_closing_s for the brake's 'closed'; notes when it cannot be told."""
        deadline = time.monotonic() + self.cfg.brake_closing_s
        closed = self.brake_closed()
        while closed is False and time.monotonic() < deadline:
            time.sleep(0.002)
            closed = self.brake_closed()
        if closed is None:
            time.sleep(self.cfg.brake_closing_s)
            return [
                f'brake not verified (no brake status object): waited '
                f'{self.cfg.brake_closing_s:g} s'
            ]
        if not closed:
            return [
                f'brake not closed {self.cfg.brake_closing_s:g} s after the ramp: '
                'voltage disabled anyway'
            ]
        return []

    def read_process(self) -> tuple[int, int, int]:
        """Statusword, current actual [per mille] and error code over SDO (after a stop)."""
        return (
            self._sdo(p.STATUSWORD).raw,
            self._sdo(p.CURRENT_ACTUAL).raw,
            self._sdo(p.ERROR_CODE).raw,
        )

    def describe(self) -> str:
        """One line on the drive as it answers over SDO now (state, current, brake)."""
        statusword, current, _ = self.read_process()
        return describe(statusword, self.scaling.permille_to_current(current), self.brake_closed())

    def acknowledge_fault(self) -> str:
        """Fault reset (rising edge of bit 7) on a person's request; returns what was reset."""
        statusword, state = self.read_state()
        if state not in (p.State.FAULT, p.State.FAULT_REACTION_ACTIVE):
            return f'no fault to acknowledge (drive {state.value if state else "undefined"})'
        code = self._sdo(p.ERROR_CODE).raw
        self._sdo(p.CONTROLWORD).raw = 0
        self.command(p.Command.FAULT_RESET, (p.State.SWITCH_ON_DISABLED,))
        self._sdo(p.CONTROLWORD).raw = p.Command.DISABLE_VOLTAGE.value
        return f'fault 0x{code:04X} ({p.error_text(code)}) acknowledged'

    def read_error(self) -> tuple[int, str]:
        """Read the drive's error code 0x603F over SDO, with its text."""
        code = self._sdo(p.ERROR_CODE).raw
        return code, p.error_text(code)
