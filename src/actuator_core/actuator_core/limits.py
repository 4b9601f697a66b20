# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The one source of every limit and shared constant of the suite (SI units, REP-103).

Every node, tool and test reads these; none repeats a literal. Nominal model: Table 1 of
the paper; theta_1n and theta_2n of eq. (3) are derived from it, never copied.
"""

from __future__ import annotations

# --- nominal model, Table 1 and eq. (3) ------------------------------------------------------
#: J_n: nominal inertia at the motor shaft [kg m^2].
NOMINAL_INERTIA_KG_M2 = 3.34e-5
#: k_tn: nominal motor torque constant [N m/A].
NOMINAL_TORQUE_CONSTANT_NM_A = 0.105
#: k_bn: nominal motor viscous coefficient [N m s/rad].
NOMINAL_VISCOUS_NM_S_RAD = 1.95e-5
#: N: gear reduction ratio [-].
NOMINAL_GEAR_RATIO = 100.0
#: theta_1n = k_tn / (J_n N) [rad/s^2/A], eq. (3).
THETA1N = NOMINAL_TORQUE_CONSTANT_NM_A / (NOMINAL_INERTIA_KG_M2 * NOMINAL_GEAR_RATIO)
#: theta_2n = -k_bn / J_n [1/s], eq. (3).
THETA2N = -NOMINAL_VISCOUS_NM_S_RAD / NOMINAL_INERTIA_KG_M2

# --- sampling ---------------------------------------------------------------------------------
#: Sample time of the loop [s] (section 5.1: 1 ms), and the range a node accepts.
SAMPLE_TIME_S = 1.0e-3
SAMPLE_TIME_RANGE_S = (1.0e-4, 0.1)

# --- current ----------------------------------------------------------------------------------
#: The one motor current limit [A]: the controller clamps to it, the drive gate refuses beyond
#: it, the observer refuses commands beyond it. Range a user may set it in.
CURRENT_LIMIT_A = 20.0
CURRENT_LIMIT_RANGE_A = (0.0, 1.0e3)

# --- safety and divergence --------------------------------------------------------------------
#: |e| beyond this [rad] latches the controller's safe stop (following-error stop).
FOLLOWING_ERROR_LIMIT_RAD = 0.5
#: |e| beyond this [rad] (about 57 degrees) means a run left any sensible operating range:
#: the offline loop stops there and the metrics report the run as diverged.
DIVERGENCE_ERROR_RAD = 1.0
#: Physical ranges of incoming values: a joint angle, velocity or lumped disturbance beyond
#: these is refused as a measurement or estimate (the fast trajectory peaks at 1.4 rad,
#: 8.8 rad/s; the paper's disturbances at about 1e3 rad/s^2).
POSITION_LIMIT_RAD = 100.0
VELOCITY_LIMIT_RAD_S = 100.0
DISTURBANCE_LIMIT_RAD_S2 = 1.0e5
#: d(x2_hat)/d(u) of one observer step is dt * theta_1n (0.031 rad/s/A at 1 kHz); an estimate
#: claiming a gain beyond this [rad/s/A] is refused.
INPUT_CURRENT_GAIN_LIMIT = 10.0

# --- timeouts ---------------------------------------------------------------------------------
#: The drive (plant or driver) applies 0 A when the newest command is older than this [s].
COMMAND_TIMEOUT_S = 0.01
#: The controller safe-stops when its newest measurement or estimate is older than this [s].
MEASUREMENT_TIMEOUT_S = 0.005
ESTIMATE_TIMEOUT_S = 0.005
TIMEOUT_RANGE_S = (1.0e-3, 10.0)

# --- metrics ----------------------------------------------------------------------------------
#: Start of the steady-state window [s]: the references carry (1 - exp(-t)), within 0.7 % of
#: 1 after 5 s; the paper does not state its window (docs/paper-resolutions.md, 18).
STEADY_STATE_START_S = 5.0

# --- encoder and loop delay (simulated joint, offline studies) -----------------------------------
#: Largest encoder resolution accepted [counts per joint revolution] (a 32-bit absolute encoder).
ENCODER_COUNTS_PER_REV_MAX = 2.0**32
#: Largest encoder noise standard deviation accepted [rad] (about 5.7 degrees).
ENCODER_NOISE_STD_MAX_RAD = 0.1
#: Largest command delay an offline run accepts [samples] (the plant applies u(k - D)).
COMMAND_DELAY_MAX_SAMPLES = 10

# --- operating envelope and robustness targets (actuator_studies) ------------------------------
#: Water depth range of the envelope [m], surface to the deepest trench
#: (WorkingCondition.at_depth).
ENVELOPE_DEPTH_M = (0.0, 11000.0)
#: Oil temperature range of the envelope [degC]: deep-sea water to a warm surface deck.
ENVELOPE_TEMPERATURE_C = (-2.0, 30.0)
#: A run counts as saturated, for gain design, beyond this fraction of samples
#: at the current limit.
SATURATED_FRACTION_LIMIT = 0.01
#: Spectral radius a designed gain set must not exceed (the paper's gains: 0.987 without delay).
DESIGN_TARGET_RADIUS = 0.98
