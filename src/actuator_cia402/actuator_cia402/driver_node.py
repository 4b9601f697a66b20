# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""CiA 402 driver node: the joint node (actuator_ros.joint_node) holding a Cia402Joint.

The sampling loop (one SYNC per sample), the command window, the one-publisher guard, the gate
and its brake policy, soft limits, the sample log, diagnostics and the lifecycle are the joint
node's, shared with the simulated plant. This node adds the drive's parameters
(``config.DriverParameters``; its SYNC period and current limit are the joint node's
``sample_time_s`` and ``current_limit_a``) and one service:

  ~/acknowledge_fault (std_srvs/Trigger)  the only fault reset: a person calls it, once the
      cause is found, while the node is inactive (configure reports a drive in fault; activate
      is refused until then). Never automatic.

A drive fault, a statusword that means 'not applying the torque', a bus error, a silent or
rebooted drive or a second SYNC producer ends control at once (the drive stopped through braked
cycles, then over SDO) and takes the node through error processing to unconfigured. The
drive's /diagnostics values (state, current actual, EMCY warnings, bus load, how the last stop
went) are the joint's (``Cia402Joint.diagnostics``).
"""

from __future__ import annotations

import os

from std_srvs.srv import Trigger

from actuator_cia402.busload import check_bus_load, cycle_load
from actuator_cia402.config import DriverParameters, check_real_drive
from actuator_cia402.joint import Cia402Joint
from actuator_core.joint import JointError
from actuator_ros.joint_node import JointNode
from actuator_ros.parameters import ParameterError, declare_spec_parameters
from actuator_ros.runner import run_node

NODE_NAME = 'actuator_cia402_driver'
#: Fields of DriverParameters that are the joint node's common settings.
FROM_JOINT_SETTINGS = ('sync_period_s', 'current_limit_a')


class Cia402DriverNode(JointNode):
    """The CiA 402 drive behind the joint_states / current_command contract."""

    summary = 'CiA 402 drive'

    def __init__(self, settings=None, **node_kwargs) -> None:
        """Declare and check every parameter (a refusal exits 2); nothing on the bus yet."""
        super().__init__(NODE_NAME, settings, **node_kwargs)

    def load_joint_parameters(self) -> None:
        """Declare the drive's parameters and check the bus load (the EDS: at configure)."""
        self.drive_cfg: DriverParameters = declare_spec_parameters(
            self,
            DriverParameters,
            exclude=FROM_JOINT_SETTINGS,
            sync_period_s=self.cfg.sample_time_s,
            current_limit_a=self.cfg.current_limit_a,
        )
        cfg = self.drive_cfg
        note = check_bus_load(
            cfg.bitrate, cfg.sync_period_s, limit=cfg.bus_load_limit, joints=cfg.joints_on_bus
        )
        if note:
            self.get_logger().warning(note)
        self.bus_load = cycle_load(cfg.bitrate, cfg.sync_period_s, joints=cfg.joints_on_bus)

    def make_joint(self) -> Cia402Joint:
        """Build the drive on its bus (connected at configure).

        A real drive needs its EDS named, its brake status object, its quick stop deceleration
        and the joint's soft position limits set (the defaults are the simulated ones).
        """
        cfg = self.drive_cfg
        try:
            self.eds = cfg.eds_path()
            check_real_drive(cfg, (self.cfg.position_min_rad, self.cfg.position_max_rad))
        except ValueError as exc:
            raise ParameterError(str(exc)) from None
        if not os.path.isfile(self.eds):
            raise ParameterError(
                f"parameter 'eds_file' = {self.eds!r} refused: no such file (the drive's EDS)"
            )
        self.get_logger().info(
            f'node {cfg.node_id} on {cfg.interface}:{cfg.channel} at {cfg.bitrate / 1000:g} '
            f'kbit/s, SYNC {1.0 / cfg.sync_period_s:g} Hz '
            f'({"producer" if cfg.sync_producer else "consumer"}), bus load '
            f'{self.bus_load.text()}'
            f'{f" for {cfg.joints_on_bus} joints" if cfg.joints_on_bus > 1 else ""}'
            f'{", simulated drive" if cfg.simulated_drive else ""}'
        )
        return Cia402Joint(cfg, self.eds)

    def build_extras(self) -> None:
        """Create the fault acknowledgement service."""
        self.acknowledge_srv = self.create_service(
            Trigger, '~/acknowledge_fault', self.on_acknowledge_fault
        )

    def drop_extras(self) -> None:
        """Destroy the service."""
        self.destroy_service(self.acknowledge_srv)

    def on_acknowledge_fault(self, request, response):
        """Reset a drive fault on a person's request (inactive only)."""
        if self.active:
            response.success, response.message = False, 'deactivate first: the node is active'
            return response
        # the service lives while the node is configured (build_extras to drop_extras)
        assert isinstance(self.joint, Cia402Joint)
        try:
            response.message = self.joint.acknowledge_fault()
            response.success = True
        except JointError as exc:
            response.success, response.message = False, str(exc)
        self.get_logger().warning(f'acknowledge_fault: {response.message}')
        return response


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_cia402 cia402_driver``.

    ``kill -USR1 <pid>`` dumps every thread's stack (run_node registers it).
    """
    return run_node(
        'cia402_driver',
        'CiA 402 (CANopen) joint drive driver, lifecycle node.',
        Cia402DriverNode,
        NODE_NAME,
        argv,
    )


if __name__ == '__main__':
    raise SystemExit(main())
