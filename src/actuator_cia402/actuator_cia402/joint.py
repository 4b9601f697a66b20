# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The CiA 402 drive behind the joint contract (``actuator_core.joint``), ROS-free.

Lifecycle (each step raises JointError with the reason in one line):
  configure   bus up (socketcan, or the simulated drive's hub), bus health watched, master
              heartbeat produced, then ``Cia402Master.configure`` (reset communication,
              identity, a drive left enabled made safe, limits, watchdog, PDOs read back,
              CST); the drive's heartbeat consumed from then on (a boot-up: it rebooted);
  activate    refused after a reboot or a silent drive heartbeat; ``Cia402Master.enable``:
              the configuration verified, target 0, CST shown, switched on with the brake
              closed, NMT operational; operation is enabled by the first write without the
              brake, and never again after a statusword that ended control (until activate);
  end_control / deactivate / cleanup: ``stop.py`` (braked cycles until the drive has stopped,
              then the stop over SDO; 0x1016 cleared only for a drive seen disabled);
  acknowledge_fault  the one way to reset a drive fault: a person asks (the node's service).
Cycle: ``write`` sends RPDO1 (controlword, target torque) at once, for the next SYNC; ``read``
sends the SYNC (``sync_producer``; with the counter 0x1019 when the drive takes one) or waits
for the bus's SYNC, then for the TPDO1 that answers it (a producer counts them: a late answer
never stands in for the next SYNC's) and TPDO2, and returns the angle (32-bit position
unwrapped, zero offset applied), the torque actual 0x6077 at the joint, and ``fault`` for
every statusword bit that means the drive does not apply the torque it is told
(``torque_fault``), for bus-off, error-passive, a vanished adapter, a reboot of the drive and a
second SYNC producer on the bus.
The master heartbeat is sent only while the cycle runs (or the joint is not active), so a
hung, killed or disconnected master stops the drive through its heartbeat consumer.
"""

from __future__ import annotations

import threading
import time
from typing import Optional

import can
import canopen

from actuator_cia402 import profile as p
from actuator_cia402.answers import AnswerCount
from actuator_cia402.busload import cycle_load
from actuator_cia402.hub import HubBus
from actuator_cia402.master import Cia402Error, Cia402Master
from actuator_cia402.stop import Cia402Stop
from actuator_cia402.supervision import BusHealth, DriveHeartbeat, PositionUnwrap, torque_fault
from actuator_core.joint import Joint, JointError, JointSample

#: NMT state byte of the master's heartbeat: operational.
HEARTBEAT_OPERATIONAL = 0x05
#: How long configure tries to reach the simulated drive's hub [s].
HUB_CONNECT_TIMEOUT_S = 20.0


class Cia402Joint(Cia402Stop, Joint):
    """One CiA 402 drive in CST on a CAN bus; ``cfg`` is a DriverParameters."""

    kind = 'cia402'
    replays_missed = False
    supports_sim_time = False

    def __init__(self, cfg, eds_path: Optional[str] = None):
        """Nothing on the bus yet."""
        self.cfg = cfg
        self.scaling = cfg.scaling
        self.eds = eds_path or cfg.eds_path()
        self.period_ns = int(round(cfg.sync_period_s * 1e9))
        self.wait_s = cfg.tpdo_wait_fraction * cfg.sync_period_s
        self.network: Optional[canopen.Network] = None
        self.master: Optional[Cia402Master] = None
        self.health = BusHealth()
        self.unwrap = PositionUnwrap()
        self.active = False
        self._arrived = threading.Condition()
        self._tpdo1: Optional[tuple] = None
        self._tpdo1_seq = 0  # TPDO1s received
        self._syncs_sent = 0  # SYNCs this master sent (sync_producer)
        self.answers = AnswerCount()  # which TPDO1 answers which of those SYNCs
        self._tpdo2 = (0, 0, p.MODE_CST)
        self._sync_seq = 0
        self._consumed_sync = 0
        self._tpdo1_at_sync = 0
        self._tpdo2_seq = 0
        self.emcy_fault = ''
        self._warnings: list[str] = []  # EMCY warnings not yet taken by the node
        self.warning_count = 0
        self.last_warning = ''
        self.drive_heartbeat: Optional[DriveHeartbeat] = None
        self.foreign_syncs = 0  # SYNCs a producer did not send: a second producer on the bus
        self._no_enable = False  # control ended on the drive's state: no enable until activate
        self._last_stamp_ns = 0
        self.bus_load = cycle_load(cfg.bitrate, cfg.sync_period_s, joints=cfg.joints_on_bus)
        self._last_read_mono = 0.0
        self._cycling = False
        self._enable_since_ns: Optional[int] = None
        self._not_following_since_ns: Optional[int] = None
        self._heartbeat_stop = threading.Event()
        self._heartbeat: Optional[threading.Thread] = None
        self.missed = 0
        self._missed_last = False
        self._missed_in_row = 0
        self._unsynced_in_row = 0  # a SYNC consumer's cycles without the bus's SYNC, in a row
        self._synced = False  # a SYNC consumer has had its first SYNC since activation
        self.cycles = 0
        self.statusword = 0
        self.position_rad = 0.0
        self.init_stop()

    # --- lifecycle --------------------------------------------------------------------------
    def _open_bus(self) -> can.BusABC:
        """Open the adapter: the hub's loopback bus or a python-can interface."""
        cfg = self.cfg
        try:
            if cfg.interface == 'hub':  # the simulated drive's process may still be starting
                return HubBus(cfg.channel, connect_timeout_s=HUB_CONNECT_TIMEOUT_S)
            return can.Bus(interface=cfg.interface, channel=cfg.channel)
        except (OSError, ValueError, can.CanError) as exc:
            hint = (
                'is cia402_sim_drive running?'
                if cfg.interface == 'hub'
                else f'ip link set {cfg.channel} up type can bitrate {cfg.bitrate}'
            )
            raise JointError(
                f'cannot open {cfg.interface} {cfg.channel!r} ({exc}); {hint}'
            ) from None

    def configure(self) -> list[str]:
        """Bus up, heartbeat produced, then the master's configure."""
        cfg = self.cfg
        self.health = BusHealth()
        self.init_stop()
        network = self.network = canopen.Network(self._open_bus())
        network.NOTIFIER_CYCLE = 0.1
        network.connect()
        assert network.notifier is not None  # connect() started it
        network.notifier.add_listener(self.health)
        self._heartbeat_stop.clear()
        self._heartbeat = threading.Thread(
            target=self._produce_heartbeat, daemon=True, name='cia402-heartbeat'
        )
        self._heartbeat.start()
        try:
            master = self.master = Cia402Master(network, cfg.node_id, self.eds, self.scaling, cfg)
            notes = master.configure()
        except (
            Cia402Error,
            canopen.SdoAbortedError,
            canopen.SdoCommunicationError,
            can.CanError,
            OSError,
        ) as exc:
            self.cleanup()
            raise JointError(f'configure: {exc}') from None
        rpdo, t1, t2 = cfg.cob_ids
        network.subscribe(t1, self._on_tpdo1)
        network.subscribe(t2, self._on_tpdo2)
        network.subscribe(0x80, self._on_sync)
        master.node.emcy.add_callback(self._on_emcy)
        watch = self.drive_heartbeat = DriveHeartbeat(
            cfg.drive_heartbeat_period_s, time.monotonic()
        )
        master.node.nmt.add_heartbeat_callback(
            lambda state: watch.on_heartbeat(state, time.monotonic())
        )
        return notes

    def activate(self) -> list[str]:
        """Target 0, CST shown, switched on (brake closed), NMT operational; no fault reset.

        Refused when the drive rebooted or fell silent since configure, when the last stop left
        it powered, or when its configuration no longer reads as written.
        """
        assert self.drive_heartbeat is not None  # configure watches it
        problem = self.drive_heartbeat.problem(time.monotonic()) or self.stop_refusal()
        if problem:
            raise JointError(f'activate: {problem}')
        master = self._configured
        try:
            master.enable()
        except (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError) as exc:
            raise JointError(f'activate: {exc}') from None
        self.unwrap = PositionUnwrap()
        self.emcy_fault = ''
        master.node.emcy.reset()
        self._enable_since_ns = self._not_following_since_ns = None
        self._missed_in_row = self._unsynced_in_row = 0
        with self._arrived:  # every SYNC before this run counts as answered
            self.answers.restart(self._syncs_sent, self._tpdo1_seq)
        self._synced = False
        self._cycling = False  # the heartbeat watches the cycle from its first read on
        self.foreign_syncs, self._no_enable = 0, False
        self.init_stop()
        self.active = True
        return []

    def acknowledge_fault(self) -> str:
        """Reset a drive fault on a person's request (inactive only); returns what was done."""
        if self.active or self.master is None:
            raise JointError('acknowledge_fault: only while configured and inactive')
        try:
            return self.master.acknowledge_fault()
        except (Cia402Error, canopen.SdoAbortedError, canopen.SdoCommunicationError) as exc:
            raise JointError(f'acknowledge_fault: {exc}') from None

    # --- cycle ------------------------------------------------------------------------------
    def write(self, current_a: float, brake: bool) -> None:
        """RPDO1 now: enable operation and the target, or switched on + halt (brake).

        After a statusword that ended control, never 'enable operation' again until activate.
        """
        if brake or self._no_enable:
            controlword = p.Command.SWITCH_ON.value | p.CW_HALT
            self._enable_since_ns, current_a = None, 0.0
        else:
            controlword = p.Command.ENABLE_OPERATION.value
            if self._enable_since_ns is None:
                self._enable_since_ns = time.monotonic_ns()
        codec = self._configured.codecs[0]
        self._send(
            codec.cob_id,
            codec.pack((controlword, self.scaling.current_to_torque_permille(current_a))),
        )

    def _send(self, cob_id: int, data: bytes) -> None:
        """One frame; a failing adapter is a bus fault."""
        try:
            assert self.network is not None  # configure connected it
            self.network.send_message(cob_id, data)
        except (can.CanError, OSError) as exc:
            self.health.on_error(exc)

    def read(self, stamp_ns: int) -> Optional[JointSample]:
        """SYNC (or the bus's), TPDO1 of that SYNC; the sample or the reason control ends."""
        self._last_read_mono = time.monotonic()
        self._last_stamp_ns = stamp_ns
        self._cycling = True
        self.cycles += 1
        if self.cfg.sync_producer:
            with self._arrived:
                self._syncs_sent += 1
                seq = self._tpdo1_seq
            self._send(0x80, self._sync_data(stamp_ns))
            got = self._answered(seq)
        else:  # the SYNC of this cycle, from the bus's producer (it may have come already)
            if not self._wait(
                lambda: self._sync_seq > self._consumed_sync, self.cfg.sync_period_s
            ):
                return self._unsynced(stamp_ns)
            self._synced, self._unsynced_in_row = True, 0
            with self._arrived:
                self._consumed_sync = self._sync_seq
                seq = self._tpdo1_at_sync
            # TPDO1 carries no SYNC counter: after a miss the first to come may answer the SYNC
            # before, so that cycle waits for a second one until the deadline, takes the newest.
            need = 2 if self._missed_last else 1
            got = self._wait(lambda: self._tpdo1_seq >= seq + need, self.wait_s)
            got = got or self._tpdo1_seq > seq
            self._missed_last = not got
        if got:  # taken first: a stop's braked cycles read the drive whatever ended control
            self._missed_in_row = 0
            assert self._tpdo1 is not None  # an answer came
            statusword, counts, torque_permille = self._tpdo1
            self.statusword = statusword
            self.position_rad = (
                self.unwrap.update(counts) * self.scaling.rad_per_count - self.cfg.zero_offset_rad
            )
        problem = self.health.fault or self._bus_problem()
        if problem:
            return JointSample(stamp_ns, self.position_rad, 0.0, problem)
        if not got:  # silence counts in cycles the master ran: its own stalls are not the drive's
            self.missed += 1
            self._missed_in_row += 1
            if self._missed_in_row * self.cfg.sync_period_s > self.cfg.feedback_timeout_s:
                return JointSample(
                    stamp_ns,
                    self.position_rad,
                    0.0,
                    f'no TPDO from the drive in {self._missed_in_row} cycles '
                    '(silent bus or drive): control ended',
                )
            return None
        effort = self.scaling.torque_permille_to_nm(torque_permille) * self.scaling.gear_ratio
        return JointSample(stamp_ns, self.position_rad, effort, self._fault(statusword))

    def _bus_problem(self) -> str:
        """Return a reboot of the drive or a second SYNC producer while active ('' if neither)."""
        if not self.active:
            return ''
        if self.drive_heartbeat is not None and self.drive_heartbeat.boots:
            self._no_enable = True
            return f'{self.drive_heartbeat.problem(time.monotonic())}: control ended'
        if self.foreign_syncs:
            return (
                f'a second SYNC producer on the bus ({self.foreign_syncs} SYNC not sent by this '
                'master; one producer per bus: sync_producer of the other drivers, 0x1005 of '
                'the other nodes): control ended'
            )
        return ''

    def _answered(self, seq: int) -> bool:
        """Wait for the TPDO1 that answers the SYNC just sent (``answers.py``); False: none."""
        n = self._syncs_sent
        self._wait(lambda: self.answers.owed(n, self._tpdo1_seq) <= 0, self.wait_s)
        with self._arrived:
            return self.answers.judge(n, self._tpdo1_seq, seq)

    def _sync_data(self, stamp_ns: int) -> bytes:
        """Return the SYNC's data: its counter, 1 to the overflow value, one step per period."""
        overflow = self._configured.sync_counter_overflow
        if not overflow:
            return b''
        return bytes((stamp_ns // self.period_ns % overflow + 1,))

    def _unsynced(self, stamp_ns: int) -> Optional[JointSample]:
        """Judge a SYNC consumer's cycle without the bus's SYNC: no TPDO is owed, none missed.

        Before the first SYNC the producer (another joint's driver) may still be starting: the
        wait is ``first_sync_timeout_s``; after it, a silent producer ends control like a silent
        drive, after ``feedback_timeout_s``.
        """
        self._unsynced_in_row += 1
        limit_s = self.cfg.feedback_timeout_s if self._synced else self.cfg.first_sync_timeout_s
        if self._unsynced_in_row * self.cfg.sync_period_s <= limit_s:
            return None
        return JointSample(
            stamp_ns,
            self.position_rad,
            0.0,
            f"no SYNC from the bus's producer in {self._unsynced_in_row} cycles"
            + ('' if self._synced else ' since activation')
            + ' (this driver is a SYNC consumer): control ended',
        )

    def _fault(self, statusword: int) -> str:
        """Run the statusword and mode display checks of ``torque_fault``, with the error code.

        'Not enabled although commanded' and 'target ignored' count only once they have lasted
        ``state_timeout_s`` while enable was commanded: a drive takes a few cycles to enable
        (its brake opening), and finishes a disable-operation ramp before it takes a new enable.
        """
        if not self.active:
            return ''
        following = (
            p.decode_state(statusword) is p.State.OPERATION_ENABLED
            and statusword & p.SW_FOLLOWS_TARGET
        )
        now = time.monotonic_ns()
        if self._enable_since_ns is None or following:
            self._not_following_since_ns = None
        elif self._not_following_since_ns is None:
            self._not_following_since_ns = now
        since = self._not_following_since_ns
        settled = since is not None and now - since > self.cfg.state_timeout_s * 1e9
        reason = torque_fault(statusword, settled) or self.emcy_fault
        self._no_enable = self._no_enable or bool(reason)
        if reason and not self._tpdo2[1]:  # TPDO2 of this SYNC brings the error code
            seq = self._tpdo2_seq
            self._wait(lambda: self._tpdo2_seq > seq, self.wait_s)
        current, code, mode = self._tpdo2
        if reason and code:
            reason += f': error code 0x{code:04X} {p.error_text(code)}'
        if not reason and mode != p.MODE_CST:
            reason = f'mode of operation display 0x6061 = {mode}, not CST (10)'
        return reason

    def _wait(self, condition, timeout_s: float) -> bool:
        """Wait for ``condition`` (under the arrival lock) at most ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        with self._arrived:
            while not condition():
                left = deadline - time.monotonic()
                if left <= 0.0 or not self.health.can_send:  # error-passive: answers come
                    return False
                self._arrived.wait(left)
            return True

    def _on_tpdo1(self, can_id, data, timestamp) -> None:
        """TPDO1 (bus thread): statusword, position actual, torque actual."""
        values = self._configured.codecs[1].unpack(bytes(data))
        with self._arrived:
            self._tpdo1 = values
            self._tpdo1_seq += 1
            self._arrived.notify_all()

    def _on_tpdo2(self, can_id, data, timestamp) -> None:
        """TPDO2 (bus thread): current actual, error code, mode display."""
        values = self._configured.codecs[2].unpack(bytes(data))
        with self._arrived:
            self._tpdo2 = values
            self._tpdo2_seq += 1
            self._arrived.notify_all()

    def _on_emcy(self, emcy) -> None:
        """EMCY (bus thread): with an error register a fault, else a warning (logged, counted)."""
        if emcy.code and emcy.register and not self.emcy_fault:
            self.emcy_fault = f'drive EMCY 0x{emcy.code:04X} {p.error_text(emcy.code)}'
        elif emcy.code and not emcy.register:
            text = f'EMCY 0x{emcy.code:04X} ({p.error_text(emcy.code)}) without error register'
            with self._arrived:
                self._warnings.append(text)
                self.warning_count += 1
                self.last_warning = text

    def take_warnings(self) -> list[str]:
        """Return the EMCY warnings since the last call (the node logs each)."""
        with self._arrived:
            taken, self._warnings = self._warnings, []
        return taken

    def _on_sync(self, can_id, data, timestamp) -> None:
        """Count a SYNC of another producer (bus thread); a producer counts it as foreign."""
        if self.cfg.sync_producer:  # this master's own SYNCs do not come back to it
            self.foreign_syncs += 1
            return
        with self._arrived:
            self._sync_seq += 1
            self._tpdo1_at_sync = self._tpdo1_seq
            self._arrived.notify_all()

    def _produce_heartbeat(self) -> None:
        """Master heartbeat while the cycle runs (or while not active)."""
        period, stale = self.cfg.heartbeat_period_s, self.cfg.heartbeat_timeout_s / 2
        while not self._heartbeat_stop.wait(period):
            if self.active and self._cycling and time.monotonic() - self._last_read_mono > stale:
                continue  # the cycle hangs: let the drive's consumer stop it
            if self.silenced:
                continue  # a stop failed: the drive's consumer must stop it
            if self.network is not None:
                self._send(0x700 + self.cfg.master_node_id, bytes([HEARTBEAT_OPERATIONAL]))

    def diagnostics(self) -> dict[str, str]:
        """Drive state, statusword, error code, bus health, TPDO and wrap counts."""
        state = p.decode_state(self.statusword)
        current, code, mode = self._tpdo2
        return {
            'drive_state': state.value if state else 'unknown',
            'statusword': f'0x{self.statusword:04X}',
            'error_code': f'0x{code:04X}',
            'error_text': p.error_text(code) if code else '',
            'current_actual_a': f'{self.scaling.permille_to_current(current):.3f}',
            'bus': self.health.fault or 'ok',
            'cycles': str(self.cycles),
            'missed_tpdo': str(self.missed),
            'position_wraps': str(self.unwrap.wraps),
            'sync_producer': str(self.cfg.sync_producer),
            'identity': self.master.identity if self.master else '',
            'fault_reaction_option': str(self.master.fault_reaction) if self.master else '',
            'emcy_warnings': str(self.warning_count),
            'last_emcy_warning': self.last_warning,
            'foreign_syncs': str(self.foreign_syncs),
            'bus_load_percent': f'{100 * self.bus_load.fraction:.1f}',
            'stop': self.stop_report,
        }
