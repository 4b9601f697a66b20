# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""A simulated CiA 402 joint drive: a canopen LocalNode on the bus, this project's joint behind it.

The drive answers SDO and NMT like a real one, runs the CiA 402 power state machine
(profile.TRANSITIONS), and in cyclic synchronous torque mode (0x6060 = 10) steps once per
SYNC, as a synchronous drive does (CiA 301: a synchronous RPDO takes effect at the next SYNC):

  0. when the SYNC comes late (the master overran and skipped cycles), the skipped periods pass
     first with the command held by the gate (0 A and brake once it timed out): the joint's
     time goes on as the wall clock's, as for a real drive and as the plant node does;
  1. latch the RPDO received since the last SYNC (controlword 0x6040, target torque 0x6071)
     and offer the target to its own CommandGate (0 A and brake when not enabled, on quick
     stop or when RPDOs stop for command_timeout_s: the drive's RPDO watchdog);
  2. sample the joint at t_k: encoder counts 0x6064 (quantised), torque 0x6077, current 0x6078,
     statusword 0x6041, error code 0x603F, and send TPDO1/TPDO2;
  3. integrate the joint model (actuator_plant.model.JointPlant, deep sea or lab) over
     [t_k, t_k+1) with the current of a first-order torque loop following the target
     (time constant tau: i(t) = i* + (i(t_k) - i*) exp(-(t - t_k)/tau), mean over the sample held),
     or hold the joint still while the holding brake is engaged.

Faults to inject (FaultPlan): an over-current or following-error fault (fault state, EMCY,
0x603F), extra EMCY frames without a fault, dropped TPDOs, and a silent bus (the drive stops
answering anything: a cut cable). A real over-current (|i| > over_current_a) faults too.
"""

from __future__ import annotations

import math
import random
import threading
import time
from dataclasses import dataclass

import canopen

from actuator_core import limits
from actuator_core.gate import CommandGate
from actuator_plant.model import JointPlant, PlantParameters, WorkingCondition
from actuator_cia402 import profile as p
from actuator_cia402.pdo_codec import PdoCodec
from actuator_cia402.scaling import Scaling

#: Error register 0x1001 bits (CiA 301): generic error, current.
ERROR_REGISTER_GENERIC = 0x01
ERROR_REGISTER_CURRENT = 0x02
FAULT_CODES = {'over_current': 0x2310, 'following_error': 0x8611}
#: Longest gap a late SYNC is caught up over [periods]; beyond it the joint model's time is lost.
MAX_CATCH_UP_PERIODS = 1000


@dataclass(frozen=True)
class FaultPlan:
    """Faults to inject, at drive time t [s] counted in SYNCs since NMT operational.

    Negative = never.
    """

    fault_kind: str = 'none'  # 'none', 'over_current' or 'following_error'
    fault_at_s: float = -1.0
    emcy_code: int = 0xFF00  # extra EMCY frame (error register 0: a warning, no fault)
    emcy_at_s: float = -1.0
    drop_tpdo_fraction: float = 0.0  # share of SYNCs answered without TPDOs
    silent_at_s: float = -1.0  # from then on the drive is silent (no TPDO, SDO, heartbeat)
    seed: int = 1

    def __post_init__(self) -> None:
        """Refuse an unknown fault kind or a fraction outside [0, 1]."""
        if self.fault_kind not in ('none', *FAULT_CODES):
            raise ValueError(
                f'fault_kind must be none, {", ".join(FAULT_CODES)}; got {self.fault_kind!r}'
            )
        if not 0.0 <= self.drop_tpdo_fraction <= 1.0:
            raise ValueError(
                f'drop_tpdo_fraction must be in [0, 1], got {self.drop_tpdo_fraction}'
            )


def plant_parameters(working_condition: str) -> PlantParameters:
    """Return the joint model of the paper in ``working_condition``.

    'deep_sea': 10 MPa, 2 degC; 'lab': 0 MPa, 25 degC.
    """
    conditions = {'deep_sea': WorkingCondition.deep_sea, 'lab': WorkingCondition.lab}
    if working_condition not in conditions:
        raise ValueError(f'working_condition must be deep_sea or lab, got {working_condition!r}')
    return PlantParameters(condition=conditions[working_condition]())


def torque_loop(
    current_a: float, target_a: float, dt_s: float, tau_s: float
) -> tuple[float, float]:
    """First-order torque loop over one period: (mean current, end current).

    i = i* + (i0 - i*) exp(-t/tau).
    """
    if tau_s <= 0.0:
        return target_a, target_a
    decay = math.exp(-dt_s / tau_s)
    mean = target_a + (current_a - target_a) * (tau_s / dt_s) * (1.0 - decay)
    return mean, target_a + (current_a - target_a) * decay


class SimulatedDrive:
    """CiA 402 drive in CST mode on a (virtual) CAN bus, with the joint model as motor and load."""

    def __init__(
        self,
        eds_path: str,
        node_id: int,
        scaling: Scaling,
        sync_period_s: float,
        channel: str,
        interface: str = 'virtual',
        plant: PlantParameters | None = None,
        torque_time_constant_s: float = 2.0e-4,
        faults: FaultPlan = FaultPlan(),
        current_limit_a: float = limits.CURRENT_LIMIT_A,
        command_timeout_s: float = limits.COMMAND_TIMEOUT_S,
        over_current_a: float = 1.25 * limits.CURRENT_LIMIT_A,
        initial_position_rad: float = 0.0,
    ):
        """Build the drive (not yet on the bus: call start())."""
        if not torque_time_constant_s >= 0.0:
            raise ValueError(f'torque_time_constant_s must be >= 0, got {torque_time_constant_s}')
        self.scaling = scaling
        self.dt_s = sync_period_s
        self.period_ns = int(round(sync_period_s * 1e9))
        self.plant = JointPlant(
            plant or plant_parameters('deep_sea'), sync_period_s, position_rad=initial_position_rad
        )
        self.tau_s = torque_time_constant_s
        self.faults = faults
        self.over_current_a = over_current_a
        self.gate = CommandGate(current_limit_a, command_timeout_s)
        self.rng = random.Random(faults.seed)
        self.node = canopen.LocalNode(node_id, eds_path)
        self.network = canopen.Network()
        self.network.NOTIFIER_CYCLE = 0.1  # stop() returns within 0.1 s
        self.channel, self.interface = channel, interface
        self.lock = threading.RLock()
        self.state = p.State.NOT_READY_TO_SWITCH_ON
        self.mode = 0
        self.last_controlword = 0
        self.error_code = 0
        self.error_register = 0
        self.current_a = 0.0  # actual motor current (torque loop output)
        self.target_current_a = 0.0
        self.brake = True
        self.syncs = 0  # SYNCs stepped in NMT operational
        self.tpdos_dropped = 0
        self.emcy_sent = 0
        self.silent = False
        self._rpdo_new = False
        self._pdo_ready = False
        self._fault_injected = False
        self._emcy_injected = False
        self._sync_t0_ns: int | None = (
            None  # wall time of drive time 0 (set on the first SYNC in operational)
        )
        self.idle_periods = 0  # periods integrated without a SYNC (the master was late)
        self.last_tpdo_counts = 0  # position actual in the newest TPDO1

    # --- bus --------------------------------------------------------------------------------
    def start(self) -> 'SimulatedDrive':
        """Join the bus.

        Boot (boot-up message, NMT pre-operational) and reach 'switch on disabled'.
        """
        self.network.connect(
            interface=self.interface, channel=self.channel, receive_own_messages=False
        )
        self.network.add_node(self.node)
        # Route SDO and NMT through this drive, so a silent drive answers nothing.
        self.network.unsubscribe(self.node.sdo.rx_cobid, self.node.sdo.on_request)
        self.network.subscribe(self.node.sdo.rx_cobid, self._on_sdo)
        self.network.unsubscribe(0, self.node.nmt.on_command)
        self.network.subscribe(0, self._on_nmt)
        self.network.subscribe(0x80, self._on_sync)
        self.node.add_read_callback(self._on_read)
        self.node.add_write_callback(self._on_write)
        self.node.nmt.send_command(0x80)  # boot-up -> pre-operational
        self.state = p.State.SWITCH_ON_DISABLED  # not ready -> switch on disabled (transition 1)
        return self

    def stop(self) -> None:
        """Leave the bus."""
        self.network.disconnect()

    def _on_sdo(self, can_id, data, timestamp) -> None:
        """SDO request: answered unless the drive is silent."""
        if not self.silent:
            self.node.sdo.on_request(can_id, data, timestamp)

    def _on_nmt(self, can_id, data, timestamp) -> None:
        """NMT command.

        On entering operational the drive takes the PDO configuration the master wrote.
        """
        if self.silent:
            return
        self.node.nmt.on_command(can_id, data, timestamp)
        if self.node.nmt.state == 'OPERATIONAL' and not self._pdo_ready:
            self._sync_t0_ns = None
            self.node.rpdo.read()
            self.node.tpdo.read()
            self._rpdo_map = self.node.rpdo[1]
            if self._on_rpdo not in self._rpdo_map.callbacks:
                self._rpdo_map.add_callback(self._on_rpdo)
            self._rpdo_cw, self._rpdo_torque = (
                self._rpdo_map[p.CONTROLWORD],
                self._rpdo_map[p.TARGET_TORQUE],
            )
            self._tpdo1, self._tpdo2 = self.node.tpdo[1], self.node.tpdo[2]
            self._tpdo_codecs = [
                (m, PdoCodec.compile(m), [v.index for v in m.map])
                for m in (self._tpdo1, self._tpdo2)
            ]
            self._pdo_ready = True
        elif self.node.nmt.state != 'OPERATIONAL':
            self._pdo_ready = False

    def _on_rpdo(self, pdo_map) -> None:
        """RPDO received: taken at the next SYNC (synchronous transmission type)."""
        self._rpdo_new = True

    # --- object dictionary ------------------------------------------------------------------
    def _on_read(self, index: int, subindex: int, od) -> int | None:
        """Live values of the process objects for SDO reads.

        0x6041, 0x6061, 0x6064, 0x6077, 0x6078, 0x603F, 0x1001.
        """
        with self.lock:
            live = {
                p.STATUSWORD: self.statusword,
                p.MODES_OF_OPERATION_DISPLAY: self.mode,
                p.POSITION_ACTUAL: self.position_counts,
                p.TORQUE_ACTUAL: self.torque_permille,
                p.CURRENT_ACTUAL: self.scaling.current_to_permille(self.current_a),
                p.ERROR_CODE: self.error_code,
                p.ERROR_REGISTER: self.error_register,
            }
            return live.get(index)

    def _on_write(self, index: int, subindex: int, od, data: bytes) -> None:
        """SDO writes that act at once.

        Controlword 0x6040 (state machine), modes of operation 0x6060.
        """
        with self.lock:
            if index == p.CONTROLWORD:
                self.apply_controlword(od.decode_raw(data))
            elif index == p.MODES_OF_OPERATION:
                self.mode = od.decode_raw(data)

    @property
    def statusword(self) -> int:
        """Statusword 0x6041 of the present state."""
        return p.encode_statusword(self.state)

    @property
    def position_counts(self) -> int:
        """Position actual 0x6064: the joint angle quantised to encoder counts."""
        return self.scaling.rad_to_counts(float(self.plant.position_rad))

    @property
    def torque_permille(self) -> int:
        """Torque actual 0x6077 [per mille of rated torque]: k_tn i / T_rated."""
        return self.scaling.current_to_torque_permille(self.current_a)

    # --- state machine ----------------------------------------------------------------------
    def apply_controlword(self, controlword: int) -> None:
        """One controlword 0x6040: CiA 402 transition; fault reset on the rising edge of bit 7."""
        command = p.decode_command(controlword)
        rising_reset = (
            bool(controlword & p.CW_FAULT_RESET) and not self.last_controlword & p.CW_FAULT_RESET
        )
        self.last_controlword = controlword
        if command is p.Command.FAULT_RESET:
            if rising_reset and self.state is p.State.FAULT:
                self._clear_fault()
            return
        if (
            command is p.Command.ENABLE_OPERATION
            and self.state is p.State.SWITCHED_ON
            and self.mode != p.MODE_CST
        ):
            return  # this drive runs CST only
        before = self.state
        self.state = p.next_state(self.state, command)
        if self.state is p.State.OPERATION_ENABLED and before is not p.State.OPERATION_ENABLED:
            self.gate.activate()
        elif self.state is not p.State.OPERATION_ENABLED and before is p.State.OPERATION_ENABLED:
            self.gate.deactivate()
            self.brake, self.target_current_a = True, 0.0

    def _raise_fault(self, code: int) -> None:
        """Fault reaction: 0 A, brake, state fault, 0x603F and 0x1001 set, EMCY sent."""
        self.gate.deactivate()
        self.brake, self.target_current_a = True, 0.0
        self.state = p.State.FAULT
        self.error_code = code
        self.error_register = ERROR_REGISTER_GENERIC | (
            ERROR_REGISTER_CURRENT if code >> 12 == 0x2 else 0
        )
        self._send_emcy(code, self.error_register)

    def _clear_fault(self) -> None:
        """Fault reset (transition 15).

        'switch on disabled', error code cleared, EMCY 'error reset'.
        """
        self.state = p.State.SWITCH_ON_DISABLED
        self.error_code = 0
        self.error_register = 0
        self._send_emcy(0x0000, 0)

    def _send_emcy(self, code: int, register: int) -> None:
        """EMCY frame (CiA 301: code, error register, 5 vendor bytes)."""
        if not self.silent:
            self.node.emcy.send(code, register)
            self.emcy_sent += 1

    # --- the cycle --------------------------------------------------------------------------
    def _on_sync(self, can_id, data, timestamp) -> None:
        """SYNC.

        The periods a late SYNC skipped pass first (time goes on for the joint), then one drive
        cycle.
        """
        if self.silent or not self._pdo_ready:
            return
        now = time.monotonic_ns()
        with self.lock:
            if self._sync_t0_ns is None:  # first SYNC in operational: drive time meets wall time
                self._sync_t0_ns = now - self.syncs * self.period_ns
            due = (now - self._sync_t0_ns + self.period_ns // 2) // self.period_ns
            for _ in range(min(MAX_CATCH_UP_PERIODS, due - self.syncs)):
                self._advance(cycle=False)
            self._advance(cycle=True)

    def step(self) -> None:
        """One drive cycle as on a SYNC.

        Latch the RPDO, faults, sample and send TPDOs, integrate one period.
        """
        self._advance(cycle=True)

    def _advance(self, cycle: bool) -> None:
        """One sync period of drive time.

        ``cycle``: with the RPDO latched and TPDOs sent (a SYNC), else idle.
        """
        t_s = self.syncs * self.dt_s
        now_ns = self.syncs * self.period_ns
        self.syncs += 1
        f = self.faults
        if 0.0 <= f.silent_at_s <= t_s:
            self.silent = True
            return
        if cycle and self._rpdo_new:
            self._rpdo_new = False
            self.apply_controlword(self._rpdo_cw.raw)
            current = self.scaling.torque_permille_to_current(self._rpdo_torque.raw)
            self.gate.offer(current, now_ns, False, now_ns)
        if f.fault_kind != 'none' and 0.0 <= f.fault_at_s <= t_s and not self._fault_injected:
            self._fault_injected = True
            self._raise_fault(FAULT_CODES[f.fault_kind])
        if 0.0 <= f.emcy_at_s <= t_s and not self._emcy_injected:
            self._emcy_injected = True
            self._send_emcy(f.emcy_code, 0)
        if (
            self.state is p.State.QUICK_STOP_ACTIVE
        ):  # option code 2: stopped (brake) -> switch on disabled
            self.state = p.State.SWITCH_ON_DISABLED
        held = self.gate.hold(now_ns)
        self.target_current_a, self.brake = held.current_a, held.brake
        if cycle:
            self._send_tpdos()
        else:
            self.idle_periods += 1
        self._integrate()
        if abs(self.current_a) > self.over_current_a and self.state is not p.State.FAULT:
            self._raise_fault(FAULT_CODES['over_current'])

    def _send_tpdos(self) -> None:
        """TPDO1/TPDO2 with the objects the master mapped.

        Statusword, position, torque; current, error code.
        """
        if f_drop := self.faults.drop_tpdo_fraction:
            if self.rng.random() < f_drop:
                self.tpdos_dropped += 1
                return
        self.last_tpdo_counts = self.position_counts
        live = {
            p.STATUSWORD: self.statusword,
            p.POSITION_ACTUAL: self.last_tpdo_counts,
            p.TORQUE_ACTUAL: self.torque_permille,
            p.CURRENT_ACTUAL: self.scaling.current_to_permille(self.current_a),
            p.ERROR_CODE: self.error_code,
            p.MODES_OF_OPERATION_DISPLAY: self.mode,
        }
        for pdo_map, codec, indices in self._tpdo_codecs:
            values = [live[i] for i in indices]
            if codec is not None:
                self.network.send_message(codec.cob_id, codec.pack(values))
            else:  # a mapping the codec does not compile: canopen's accessors
                for index, value in zip(indices, values):
                    pdo_map[index].raw = value
                pdo_map.transmit()

    def _integrate(self) -> None:
        """Joint over one sync period.

        The torque loop's mean current held (or the brake holding the joint).
        """
        target = self.target_current_a
        if self.brake:
            self.current_a = 0.0
            self.plant.velocity_rad_s = 0.0
            self.plant.sample_index += 1
            return
        mean, self.current_a = torque_loop(self.current_a, target, self.dt_s, self.tau_s)
        self.plant.step(mean)
