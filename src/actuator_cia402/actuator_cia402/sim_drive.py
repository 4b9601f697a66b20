# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A simulated CiA 402 joint drive: a canopen LocalNode on the bus, the simulated joint behind it.

It behaves as a real CST drive does, hazards included, so the master can be tested against
them (the console script ``cia402_sim_drive`` runs it in a process of its own):

- the SYNCs step drive time, as a cyclic synchronous drive's cycle is theirs: with the SYNC
  counter 0x1019 each SYNC says how many periods passed, however late it came; without it the
  drive's period grid is phase-locked to the SYNCs (they fall mid-period), so a SYNC less than
  half a period late neither adds nor drops a period. Either way the master's stamps and the
  drive's samples keep one time base (``drive_clock.DriveClock``). With no SYNC for a few
  periods drive time follows the wall clock (a clock thread steps it). A SYNC latches the
  RPDO received since the last SYNC (0x6040, 0x6071), samples and answers TPDO1/TPDO2. With
  no master the drive keeps its last target torque: only its heartbeat consumer (0x1016)
  stops it, by the abort connection option 0x6007;
- 0x6071 is a stored object: kept across NMT start and across enable (no zeroing);
- the SYNC window 0x1007 discards an RPDO that arrives later than the window after the SYNC;
- quick stop (0x605A), disable operation (0x605C) and the fault reaction (0x605E) ramp the
  torque to 0 at the torque slope 0x6087, then close the brake, which takes its closing time
  (0x2100); the state changes when that is done ('fault reaction active' meanwhile). Disable
  voltage during a ramp cuts it (logged as an event);
- the brake's state is readable: 0x60FD bit 16 (manufacturer-specific) = brake closed;
- injectable: drive faults, EMCY, dropped TPDOs, late TPDOs (sent with the next SYNC's
  answer), a silent drive, STO (operation left without a
  fault, voltage off), a quick-stop input, remote off, 'target ignored' (statusword bit 12 low),
  and bus errors (sent by the hub as error frames);
- polarity 0x607E bit 7 inverts position and torque; position actual 0x6064 wraps as INTEGER32;
- NMT reset communication restores the communication objects (0x1000-0x1FFF) to their saved
  values (``save``: what a drive tool stores; else the EDS's defaults) and sends the boot-up;
  the power state machine and 0x6071 are not reset. A reboot (NMT reset node, or the injection
  'reboot') restores every object to its saved value: the power stage off, the brake closed,
  the master's configuration lost, then the boot-up;
- the heartbeat 0x1017 is produced as configured (canopen's NMT slave);
- ``Quirks`` make it less kind, as real drives are (sim_faults.py): transition 16, no bit 10 in
  quick stop active, a velocity-based quick stop (0x6085), SYNC produced by the drive itself
  while 0x1005 bit 30 is set, a PDO mapping entry that keeps its value whatever is written,
  an encoder counting against the torque.

The joint is ``actuator_plant.sim_joint.SimulatedJoint`` (model, torque loop, holding brake):
the one brake model. Position is quantised through the drive's ``Scaling``.
"""

from __future__ import annotations

import random
import threading
import time
from typing import Callable, cast

import canopen

from actuator_cia402 import profile as p
from actuator_cia402.drive_clock import DriveClock
from actuator_cia402.pdo_codec import PdoCodec
from actuator_cia402.scaling import Scaling
from actuator_cia402.sim_faults import (
    FAULT_CODES,
    FaultPlan,
    Quirks,
    inject_due,
    plant_parameters,
)
from actuator_cia402.sim_states import DriveStateMachine
from actuator_plant.model import PlantParameters
from actuator_plant.sim_joint import SimulatedJoint

#: 0x60FD bit 16 (manufacturer-specific): the holding brake is closed.
DI_BRAKE_CLOSED = 1 << 16
#: 0x1005 bit 30: this node produces the SYNC (CiA 301).
SYNC_PRODUCER_BIT = 1 << 30
INT32 = 2**32


def wrap_int32(value: int) -> int:
    """``value`` as an INTEGER32 counter shows it (two's complement wrap)."""
    return (value + 2**31) % INT32 - 2**31


class SimulatedDrive(DriveStateMachine):
    """CiA 402 drive in CST mode on a CAN bus, with the simulated joint as motor and load."""

    def __init__(
        self,
        eds_path: str,
        node_id: int,
        scaling: Scaling,
        sync_period_s: float,
        plant: PlantParameters | None = None,
        torque_time_constant_s: float = 2.0e-4,
        faults: FaultPlan = FaultPlan(),
        over_current_a: float = 25.0,
        initial_position_rad: float = 0.0,
        encoder_offset_counts: int = 0,
        on_event: Callable[[str], None] | None = None,
        quirks: Quirks = Quirks(),
    ):
        """Build the drive (not yet on a bus: ``attach`` it to a connected network)."""
        self.scaling = scaling
        self.dt_s = sync_period_s
        self.period_ns = int(round(sync_period_s * 1e9))
        self.joint = SimulatedJoint(
            plant or plant_parameters('deep_sea'),
            sync_period_s,
            position_rad=initial_position_rad,
            torque_time_constant_s=torque_time_constant_s,
        )
        self.joint.read(0)  # the first read only samples: from now on each read integrates
        self.faults = faults
        self.quirks = quirks
        self.over_current_a = over_current_a
        self.encoder_offset_counts = encoder_offset_counts
        self.rng = random.Random(faults.seed)
        self.node = canopen.LocalNode(node_id, eds_path)
        self.od = self.node.object_dictionary
        self.on_event = on_event or (lambda text: None)
        self.events: list[str] = []
        self.lock = threading.RLock()
        self.state = p.State.SWITCH_ON_DISABLED
        self.last_controlword = 0
        self.target_permille = 0  # 0x6071, a stored object
        self.error_code = 0
        self.error_register = 0
        self.brake_closed = True
        self._brake_closing_at: float | None = None  # drive time the brake will be closed
        self.ramp_permille = 0.0  # the torque the drive applies while it ramps down
        self._stopping: p.State | None = None  # state reached once ramp and brake are done
        self._decelerating = False  # a velocity-based quick stop is under way
        self._stop_velocity = 0.0  # its velocity reference [rad/s at the joint]
        self.saved: dict[int, dict[int, bytes]] = {}  # the drive tool's stored settings
        # the SYNC this drive produces (0x1005 bit 30)
        self._sync_task: canopen.network.PeriodicMessageTask | None = None
        self.reboots = 0
        self._cut_ramps = 0
        self.sto = self.remote_off = self.target_ignored = self.silent = False
        self.syncs = 0  # periods of drive time
        self.origin: int | None = None  # period of the first SYNC: time 0 of the fault plan
        self.sync_frames = 0
        self.tpdos_dropped = 0
        self.tpdos_late = 0
        self._late_sends: list[Callable[[], None]] = []  # a late answer, sent with the next
        self.rpdos_discarded = 0
        self._rpdo_data: dict[int, int] | None = None  # the RPDO's objects by index
        self._last_sync_mono = 0.0
        self._pdo_ready = False
        self._injected: set = set()
        self._heartbeat_seen: float | None = None
        self._heartbeat_lost = False
        self._heartbeat_producer = 0
        self.network: canopen.Network | None = None
        self.clock = DriveClock(self.period_ns, time.monotonic_ns())  # drive time's grid
        self._clock_stop = threading.Event()
        self._cache: dict[tuple[int, int], int] = {}

    # --- bus --------------------------------------------------------------------------------
    def attach(self, network: canopen.Network) -> 'SimulatedDrive':
        """Join a connected network, send the boot-up and start the drive's clock."""
        self.network = network
        network.add_node(self.node)
        network.unsubscribe(self.node.sdo.rx_cobid, self.node.sdo.on_request)
        network.subscribe(self.node.sdo.rx_cobid, self._on_sdo)
        network.unsubscribe(0, self.node.nmt.on_command)
        network.subscribe(0, self._on_nmt)
        network.subscribe(0x80, self._on_sync)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        # LocalNode has no hook before it stores an SDO write: its method is wrapped.
        self._set_data = self.node.set_data
        self.node.set_data = self._set_data_unless_fixed  # type: ignore[method-assign]
        if self.quirks.sync_producer:
            cob_id = self._default(p.SYNC_COB_ID)
            self.save(p.SYNC_COB_ID, 0, (cob_id | SYNC_PRODUCER_BIT).to_bytes(4, 'little'))
        self._boot()
        threading.Thread(target=self._clock, name=f'drive-{self.node.id}', daemon=True).start()
        return self

    @property
    def _net(self) -> canopen.Network:
        """The network the drive joined (``attach``)."""
        assert self.network is not None, 'the drive is not attached to a network'
        return self.network

    def stop(self) -> None:
        """Stop the drive's clock and its SYNC production."""
        self._clock_stop.set()
        self._produce_sync(False)

    def save(self, index: int, subindex: int, data: bytes) -> None:
        """Store a setting as a drive tool does: kept across reset communication and reboot."""
        with self.lock:
            self.saved.setdefault(index, {})[subindex] = bytes(data)
            self.node.data_store.setdefault(index, {})[subindex] = bytes(data)
            self._cache.clear()

    def _boot(self) -> None:
        """Boot-up message, then NMT pre-operational (CiA 301); SYNC produced if 0x1005 says so."""
        self.node.nmt.send_command(0x82)  # state 'initialising': sends the boot-up
        self.node.nmt.send_command(0x80)
        self._produce_sync(bool(self._cfg(p.SYNC_COB_ID) & SYNC_PRODUCER_BIT))

    def _restore(self, below: int) -> None:
        """Objects with an index below ``below`` back to their saved values (else the EDS's)."""
        for index in [i for i in self.node.data_store if i < below]:
            del self.node.data_store[index]
        for index, subs in self.saved.items():
            if index < below:
                self.node.data_store[index] = dict(subs)
        self._cache.clear()

    def reboot(self) -> None:
        """Power cycle: every object saved or default, power stage off, brake closed, boot-up."""
        with self.lock:
            self.reboots += 1
            self._restore(0x10000)
            self.state = p.State.SWITCH_ON_DISABLED
            self._stopping, self._decelerating = None, False
            self.ramp_permille, self.target_permille, self.last_controlword = 0.0, 0, 0
            self.error_code = self.error_register = 0
            self.brake_closed, self._brake_closing_at = True, None
            self.sto = self.remote_off = self.target_ignored = False
            if self._heartbeat_producer:
                self._net.unsubscribe(0x700 + self._heartbeat_producer, self._on_heartbeat)
            self._heartbeat_producer, self._heartbeat_seen, self._heartbeat_lost = 0, None, False
            self._pdo_ready, self._rpdo_data = False, None
            self.node.nmt.stop_heartbeat()
            self._event('rebooted: configuration lost, power stage off, brake closed')
            self._boot()

    def _produce_sync(self, on: bool) -> None:
        """Start or stop this drive's own SYNC (every 0x1006 us, else every period)."""
        if on and self._sync_task is None and self.network is not None:
            period_us = self._cfg(p.COMMUNICATION_CYCLE_US) or int(round(self.dt_s * 1e6))
            self._sync_task = self.network.send_periodic(0x80, b'', period_us * 1e-6)
            self._event('producing SYNC (0x1005 bit 30)')
        elif not on and self._sync_task is not None:
            self._sync_task.stop()
            self._sync_task = None
            self._event('SYNC production stopped (0x1005 bit 30 cleared)')

    @property
    def producing_sync(self) -> bool:
        """Whether this drive sends SYNC itself."""
        return self._sync_task is not None

    def _set_data_unless_fixed(self, index, subindex, data, check_writable=False) -> None:
        """SDO write, except to the mapping entry the drive keeps (``Quirks``): answered only."""
        if (index, subindex) == self.quirks.fixed_mapping_entry:
            return
        self._set_data(index, subindex, data, check_writable)

    def leave_enabled(self, target_permille: int) -> None:
        """Put the drive where a crashed master left it: operational, enabled, a target."""
        with self.lock:
            self.node.nmt.send_command(0x01)
            self._take_pdo_config()
            self.target_permille = target_permille
            self.node.data_store.setdefault(p.MODES_OF_OPERATION, {})[0] = bytes([p.MODE_CST])
            self._cache.clear()
            self.state = p.State.OPERATION_ENABLED
            self.brake_closed, self._brake_closing_at = False, None
            self._event(f'left enabled with 0x6071 = {target_permille} per mille')

    def _event(self, text: str) -> None:
        """Keep and report one event of the drive."""
        line = f'drive {self.node.id} t={self.syncs * self.dt_s:.3f} s: {text}'
        self.events.append(line)
        self.on_event(line)

    def _variable(self, index: int, subindex: int = 0) -> canopen.objectdictionary.ODVariable:
        """Return the EDS's entry of an object (the sub-object of an array or a record)."""
        obj = self.od[index]
        if not isinstance(obj, canopen.objectdictionary.ODVariable):
            obj = obj[subindex]
        return obj

    def _default(self, index: int, subindex: int = 0) -> int:
        """Return the EDS's default of an integer object."""
        default = self._variable(index, subindex).default
        assert default is not None, f'0x{index:04X} sub {subindex}: no default in the EDS'
        return default

    def _cfg(self, index: int, subindex: int = 0) -> int:
        """Value of a configuration object (stored, else the EDS default), cached until written."""
        key = (index, subindex)
        value = self._cache.get(key)
        if value is None:
            obj = self._variable(index, subindex)
            try:
                raw = self.node.data_store[index][subindex]
            except KeyError:
                raw = obj.encode_raw(self._default(index, subindex))
            # the configuration objects are integers (UNSIGNEDn, INTEGERn)
            value = self._cache[key] = cast(int, obj.decode_raw(raw))
        return value

    def _on_sdo(self, can_id, data, timestamp) -> None:
        """SDO request: answered unless the drive is silent."""
        if not self.silent:
            self.node.sdo.on_request(can_id, data, timestamp)

    def _on_nmt(self, can_id, data, timestamp) -> None:
        """NMT: reset node reboots, reset communication restores 0x1000-0x1FFF, start maps."""
        if self.silent or data[1] not in (0, self.node.id):
            return
        with self.lock:
            if data[0] == 0x81:
                self.reboot()
                return
            if data[0] == 0x82:
                self._produce_sync(False)
                self._restore(0x2000)
                self._heartbeat_seen, self._heartbeat_lost = None, False
                self._pdo_ready = False
                self._event('NMT reset communication: communication objects restored')
                self._boot()
                return
            self.node.nmt.on_command(can_id, data, timestamp)
            if self.node.nmt.state == 'OPERATIONAL':
                self._last_sync_mono = 0.0  # the window counts from the first SYNC
                self._take_pdo_config()
            else:
                self._pdo_ready = False

    def _take_pdo_config(self) -> None:
        """Read the PDO configuration the master wrote and compile the cycle's codecs."""
        self.node.rpdo.read()
        self.node.tpdo.read()
        rpdo = self.node.rpdo[1]
        if self._on_rpdo not in rpdo.callbacks:
            rpdo.add_callback(self._on_rpdo)
        self._rpdo_codec = PdoCodec.compile(rpdo)
        self._rpdo_indices = [v.index for v in rpdo.map]
        self._tpdo_codecs = [
            (m, PdoCodec.compile(m), [v.index for v in m.map])
            for m in (self.node.tpdo[1], self.node.tpdo[2])
            if m.enabled
        ]
        self._pdo_ready = True

    def _on_rpdo(self, pdo_map) -> None:
        """RPDO: kept for the next SYNC unless it came after the SYNC window."""
        window_s = self._cfg(p.SYNC_WINDOW_US) * 1e-6
        since_sync_s = time.monotonic() - self._last_sync_mono
        if window_s and self._last_sync_mono and since_sync_s > window_s:
            self.rpdos_discarded += 1
            if self.rpdos_discarded == 1:
                self._event('RPDO after the SYNC window discarded')
            return
        if self._rpdo_codec is None:  # not byte-aligned: canopen decodes it (as a TPDO's send)
            values = tuple(var.raw for var in pdo_map.map)
        else:
            values = self._rpdo_codec.unpack(bytes(pdo_map.data))
        self._rpdo_data = dict(zip(self._rpdo_indices, values))

    def _on_heartbeat(self, can_id, data, timestamp) -> None:
        """Note a heartbeat of the monitored producer (0x1016 sub 1)."""
        self._heartbeat_seen = time.monotonic()
        self._heartbeat_lost = False

    # --- object dictionary ------------------------------------------------------------------
    def _on_read(self, index: int, subindex: int, od) -> int | None:
        """Live values of the process objects for SDO reads."""
        with self.lock:
            return self._process_values().get(index)

    def _process_values(self) -> dict[int, int]:
        """Return the process objects' values now, as an SDO read or a TPDO gives them."""
        return {
            p.STATUSWORD: self.statusword,
            p.MODES_OF_OPERATION_DISPLAY: self._cfg(p.MODES_OF_OPERATION),
            p.POSITION_ACTUAL: self.position_counts,
            p.TORQUE_ACTUAL: self.torque_permille,
            p.CURRENT_ACTUAL: self.scaling.current_to_permille(self.current_a),
            p.ERROR_CODE: self.error_code,
            p.ERROR_REGISTER: self.error_register,
            p.TARGET_TORQUE: self.target_permille,
            p.DIGITAL_INPUTS: DI_BRAKE_CLOSED if self.brake_closed else 0,
        }

    def _on_write(self, index: int, subindex: int, od, data: bytes) -> None:
        """SDO writes that act at once: controlword, target torque, heartbeat consumer, SYNC."""
        with self.lock:
            self._cache.pop((index, subindex), None)
            self.node.data_store.setdefault(index, {})[subindex] = bytes(data)
            if index == p.CONTROLWORD:
                self.apply_controlword(od.decode_raw(data))
            elif index == p.TARGET_TORQUE:
                self.target_permille = od.decode_raw(data)
            elif index == p.SYNC_COB_ID:
                self._produce_sync(bool(od.decode_raw(data) & SYNC_PRODUCER_BIT))
            elif index == p.HEARTBEAT_CONSUMER and subindex == 1:
                value = od.decode_raw(data)
                if self._heartbeat_producer:
                    self._net.unsubscribe(0x700 + self._heartbeat_producer, self._on_heartbeat)
                self._heartbeat_producer = (value >> 16) & 0x7F
                if self._heartbeat_producer:
                    self._net.subscribe(0x700 + self._heartbeat_producer, self._on_heartbeat)
                self._heartbeat_seen, self._heartbeat_lost = None, False

    @property
    def current_a(self) -> float:
        """Motor current actual [A]: the torque loop's mean over the last period."""
        return float(self.joint.applied_a)

    @property
    def _sign(self) -> int:
        """-1 when polarity 0x607E bit 7 inverts position and torque."""
        return -1 if self._cfg(p.POLARITY) & 0x80 else 1

    @property
    def position_counts(self) -> int:
        """Position actual 0x6064: the joint angle in encoder counts, INTEGER32 (wraps)."""
        counts = round(float(self.joint.plant.position_rad) / self.scaling.rad_per_count)
        sign = self._sign * self.quirks.encoder_sign
        return wrap_int32(sign * counts + self.encoder_offset_counts)

    @property
    def torque_permille(self) -> int:
        """Torque actual 0x6077 [per mille of rated torque]: k_t i / T_rated."""
        return self._sign * self.scaling.current_to_torque_permille(self.current_a)

    # --- the cycle --------------------------------------------------------------------------
    def _clock(self) -> None:
        """Step the periods no SYNC stepped (drive time follows the wall clock).

        While SYNCs come, the SYNCs step drive time and this waits: the drive's cycle is theirs.
        """
        while not self._clock_stop.wait(max(0.002, 2 * self.dt_s)):
            with self.lock:
                now_ns = time.monotonic_ns()
                if self.clock.free_running(now_ns):
                    self._idle(self.clock.idle_periods(now_ns, self.syncs, margin=1))

    def _idle(self, periods: int) -> None:
        """Step ``periods`` of drive time without a cycle."""
        for _ in range(periods):
            self._advance(cycle=False)

    def _on_sync(self, can_id, data, timestamp) -> None:
        """SYNC: the periods before it pass (drive_clock says how many), then one drive cycle."""
        if self.silent:
            return
        now_ns = time.monotonic_ns()
        with self.lock:
            self.sync_frames += 1
            if self.origin is None:  # the faults' clock starts with the first SYNC
                self.origin = self.syncs
            overflow = self._cfg(p.SYNC_COUNTER_OVERFLOW)
            counter = data[0] if overflow and len(data) >= 1 else None
            self._idle(self.clock.on_sync(now_ns, counter, overflow, self.syncs))
            self._advance(cycle=self._pdo_ready)
            self.clock.cycle_done(self.syncs)
            self._last_sync_mono = time.monotonic()

    def _applied_target(self) -> int:
        """Target torque [per mille] within 0x6072 and 0x6073, in the motor's sense (0x607E)."""
        limit = min(
            self._cfg(p.MAX_TORQUE),
            self.scaling.current_to_torque_permille(
                self._cfg(p.MAX_CURRENT) * self.scaling.rated_current_a / 1000.0
            ),
        )
        return max(-limit, min(limit, self._sign * self.target_permille))

    def _advance(self, cycle: bool) -> None:
        """One period of drive time; ``cycle``: a SYNC (RPDO latched, TPDOs sent)."""
        t_s = self.syncs * self.dt_s
        self.syncs += 1
        if self.origin is not None:
            inject_due(self, (self.syncs - 1 - self.origin) * self.dt_s)
        if self.silent:
            return
        if cycle and self._rpdo_data is not None:
            data, self._rpdo_data = self._rpdo_data, None
            if not self.remote_off:
                if p.TARGET_TORQUE in data:
                    self.target_permille = data[p.TARGET_TORQUE]
                if p.CONTROLWORD in data:
                    self.apply_controlword(data[p.CONTROLWORD])
        self._supervise_heartbeat()
        current = self._power_stage(t_s)
        if cycle and self._pdo_ready:  # a reboot in this period took the PDOs away
            self._send_tpdos()
        self.joint.write(current, self.brake_closed)
        self.joint.read(self.syncs * self.period_ns)
        if abs(self.joint._flowing_a) > self.over_current_a and self.error_code == 0:
            self._raise_fault(FAULT_CODES['over_current'])

    def _send_tpdos(self) -> None:
        """TPDO1/TPDO2 with the objects the master mapped; a late answer goes before them."""
        late, self._late_sends = self._late_sends, []
        for send in late:
            send()
        if self.faults.drop_tpdo_fraction and self.rng.random() < self.faults.drop_tpdo_fraction:
            self.tpdos_dropped += 1
            return
        live = self._process_values()
        sends = [
            self._tpdo_send(pdo_map, codec, indices, [live[i] for i in indices])
            for pdo_map, codec, indices in self._tpdo_codecs
        ]
        if self.faults.late_tpdo_fraction and self.rng.random() < self.faults.late_tpdo_fraction:
            self.tpdos_late += 1
            self._late_sends = sends  # answered with the next SYNC's, just before them
            return
        for send in sends:
            send()

    def _tpdo_send(self, pdo_map, codec, indices, values) -> Callable[[], None]:
        """Return the sending of one TPDO with these values."""
        if codec is not None:
            frame = codec.pack(values)
            return lambda: self._net.send_message(codec.cob_id, frame)

        def transmit() -> None:
            for index, value in zip(indices, values):
                pdo_map[index].raw = value
            pdo_map.transmit()

        return transmit
