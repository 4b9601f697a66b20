# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Simulated joint node: the joint node (actuator_ros.joint_node) holding a SimulatedJoint.

It publishes only what a position sensor gives (joint_states: the angle, and the effort the
drive applied), plus the ground truth a simulation has (plant/truth: velocity, the lumped
disturbance and its parts, the drifting parameters, the brake). Everything else, the timing,
the command gate, the checks and the lifecycle, is the joint node's, shared with the CiA 402
driver. Parameters: the joint node's common ones and the model's (``PlantParameters``), the
working condition, the initial angle and the encoder (``encoder.*``: quantisation and noise of the
angle joint_states reports, off by default).
"""

from __future__ import annotations

from dataclasses import replace

from actuator_core import limits
from actuator_msgs.msg import PlantTruth
from actuator_plant.encoder import Encoder, EncoderParameters
from actuator_plant.model import (
    CONDITION_CHOICES,
    DEFAULT_CONDITION,
    DEFAULT_DEPTH_M,
    PLANT_NODE_NAME,
    PlantParameters,
    working_condition,
)
from actuator_plant.sim_joint import SimulatedJoint
from actuator_ros.joint_node import JointNode
from actuator_ros.parameters import declare_choice, declare_number, declare_spec_parameters
from actuator_ros.qos import control_qos
from actuator_ros.runner import run_node
from actuator_ros.wire_io import codec

NODE_NAME = PLANT_NODE_NAME
#: Largest encoder seed a node parameter takes (a ROS integer parameter is 64-bit signed).
ENCODER_SEED_MAX = 2**62


class PlantNode(JointNode):
    """The simulated joint behind the sensor/command topic contract."""

    summary = 'simulated joint'

    def __init__(self, settings=None, **node_kwargs) -> None:
        """Declare and check every parameter; nothing is built before configure."""
        super().__init__(NODE_NAME, settings, **node_kwargs)

    def load_joint_parameters(self) -> None:
        """Working condition, the model's constants and the initial angle."""
        condition = declare_choice(
            self,
            'working_condition',
            DEFAULT_CONDITION,
            CONDITION_CHOICES,
            'deep_sea: 10 MPa, 2 degC; lab: 0 MPa, 25 degC; depth: depth_m and '
            'condition.temperature_c; custom: condition.pressure_pa and condition.temperature_c',
        )
        depth = declare_number(
            self,
            'depth_m',
            DEFAULT_DEPTH_M,
            0.0,
            11000.0,
            'm',
            'water depth for working_condition depth',
        )
        params = declare_spec_parameters(self, PlantParameters)
        self.params = replace(
            params, condition=working_condition(condition, depth, params.condition)
        )
        self.condition_name = condition
        self.truth_rate_hz = declare_number(
            self,
            'truth_rate_hz',
            0.0,
            *limits.DIAGNOSTICS_RATE_RANGE_HZ,
            'Hz',
            'rate of plant/truth (every n-th sample); 0: every sample, as the bag analysis needs',
        )
        encoder = declare_spec_parameters(
            self, EncoderParameters, prefix='encoder.', exclude=('seed',)
        )
        seed = declare_number(
            self,
            'encoder.seed',
            0,
            0,
            ENCODER_SEED_MAX,
            '',
            'seed of the encoder noise generator',
        )
        self.encoder_params = replace(encoder, seed=seed)
        self.initial_position_rad = declare_number(
            self,
            'initial_position_rad',
            0.0,
            -limits.POSITION_LIMIT_RAD,
            limits.POSITION_LIMIT_RAD,
            'rad',
            'joint angle at sample 0',
        )

    def make_joint(self) -> SimulatedJoint:
        """Build the model at rest at the initial angle."""
        encoder = self.encoder_params
        return SimulatedJoint(
            self.params,
            self.cfg.sample_time_s,
            position_rad=self.initial_position_rad,
            encoder=Encoder.from_parameters(encoder) if encoder.active else None,
        )

    @property
    def _sim_joint(self) -> SimulatedJoint:
        """The simulated joint of the configured node (``make_joint`` built it)."""
        joint = self._joint
        assert isinstance(joint, SimulatedJoint)
        return joint

    def build_extras(self) -> None:
        """plant/truth, and the start-up line with the oil's viscosity."""
        self.truth_pub = self.create_lifecycle_publisher(
            PlantTruth, 'plant/truth', control_qos(self.mode)
        )
        constants = self._sim_joint.plant.constants
        self.encode_truth = codec(PlantTruth).encode
        self.truth_constants = {  # the oil's condition, the same every sample
            'header.frame_id': '',
            'pressure_pa': float(self.params.condition.pressure_pa),
            'temperature_degc': float(self.params.condition.temperature_c),
            'viscosity_pa_s': float(constants.viscosity_pa_s),
        }
        rate = self.truth_rate_hz
        self.truth_every = max(1, round(1.0 / (rate * self.cfg.sample_time_s))) if rate else 1
        c = self.params.condition
        self.get_logger().info(
            f'{self.mode} mode, {self.condition_name}: P = {c.pressure_pa / 1e6:.2f} MPa, T = '
            f'{c.temperature_c:.1f} degC, mu = {constants.viscosity_pa_s * 1e3:.1f} mPa s; '
            f'current limit {self.cfg.current_limit_a} A'
        )

    def drop_extras(self) -> None:
        """Destroy plant/truth."""
        self.destroy_lifecycle_publisher(self.truth_pub)

    def publish_extras(self, stamp_ns: int) -> None:
        """Ground truth at t_k with the current applied over the preceding sample.

        Computed and sent only when someone subscribes (1 us to ask; the parts and the message
        cost tens of microseconds a sample).
        """
        if self.sample_index % self.truth_every or not self.truth_pub.get_subscription_count():
            return
        joint = self._sim_joint
        plant, parts = joint.plant, joint.truth()
        f = parts.forces
        self.truth_pub.publish(
            self.encode_truth(
                {
                    **self.truth_constants,
                    'header.stamp': stamp_ns,
                    'position_rad': float(plant.position_rad),
                    'velocity_rad_s': float(plant.velocity_rad_s),
                    'acceleration_rad_s2': float(parts.acceleration_rad_s2),
                    'current_a': float(joint.applied_a),
                    'disturbance_rad_s2': float(parts.disturbance_rad_s2),
                    'parametric_rad_s2': float(parts.parametric_rad_s2),
                    'stirring_rad_s2': float(parts.stirring_rad_s2),
                    'external_rad_s2': float(parts.external_rad_s2),
                    'seal_rad_s2': float(parts.seal_rad_s2),
                    'stirring_torque_nm': float(f.stirring_torque_nm),
                    'external_torque_nm': float(f.external_torque_nm),
                    'seal_torque_nm': float(f.seal_torque_nm),
                    'inertia_kg_m2': float(f.inertia_kg_m2),
                    'torque_constant_nm_a': float(f.torque_constant_nm_a),
                    'viscous_coefficient_nm_s_rad': float(f.viscous_coefficient_nm_s_rad),
                    'brake_engaged': bool(joint.brake),
                }
            )
        )


def main(argv=None) -> int:
    """Entry point of ``ros2 run actuator_plant plant_node``."""
    return run_node(
        'plant_node',
        'Simulated deep-sea oil-filled joint (sensor: angle only).',
        PlantNode,
        NODE_NAME,
        argv,
    )


if __name__ == '__main__':
    raise SystemExit(main())
