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
#: A real joint's cycle that starts later than this share of a period after its instant is
#: skipped: the drive samples when the SYNC reaches it, and a SYNC this late would be taken
#: for the next instant (a SYNC-locked drive tolerates jitter under half a period).
CYCLE_LATENESS_MAX_FRACTION = 0.4

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
#: Joint velocity a measurement or estimate may imply [rad/s]: 2.3 times the fast trajectory's
#: peak of 8.8 rad/s (880 rad/s, 8400 rpm at the motor through N = 100; the printed SMC-ESO
#: gains, which only bang between the limits, reach 13.6). A measurement whose change from the
#: last accepted one implies more is refused, and so is an estimate's x2_hat beyond it, before
#: and after the correction of a substituted current.
VELOCITY_LIMIT_RAD_S = 20.0
#: The joint's soft speed limit judges the angle's change over this window [s], not over one
#: sample: feedback that lags for some samples and then catches up in one (a drive's TPDOs
#: delayed on a loaded bus: 10-30 samples seen through the simulated drive's hub) implies
#: (lag + 1) times the true speed in that sample, 66-143 rad/s at 5 rad/s, and ended control
#: of a joint that never exceeded 9 rad/s. A real overspeed is judged at most one window late.
SOFT_VELOCITY_WINDOW_S = 0.02
#: Loop health on the joint side (docs/safety.md#loop-health): the share of the samples of the last
#: window [s] whose applied command answered one of the two newest samples (the window the
#: command binding accepts). Below the share, /diagnostics warns (or control ends, parameter
#: stop_on_stale_loop). Measured with bringup on a 2-core VM (stop 34 note): under SCHED_FIFO
#: 84 % of commands within 2 samples; at normal scheduling 2 % within 1 sample.
FRESH_COMMAND_WINDOW_S = 1.0
FRESH_COMMAND_SHARE_MIN = 0.5
#: A degraded loop is healthy again at this much above the share (no flicker at the edge).
FRESH_COMMAND_HYSTERESIS = 0.1
#: theta_1n * I_max: the acceleration the current limit can command [rad/s^2] (629).
CURRENT_ACCELERATION_RAD_S2 = THETA1N * CURRENT_LIMIT_A
#: The identification run's reference (actuator_controller.excitation): its largest acceleration
#: [rad/s^2] by default, a quarter of what the current limit commands with the nominal model
#: (157 rad/s^2, about 5 A on a Table 1 joint, 10 A on one with half its theta1), and the speed
#: its sweeps and multi-sine stay below [rad/s], half the velocity limit.
EXCITATION_ACCELERATION_RAD_S2 = 0.25 * CURRENT_ACCELERATION_RAD_S2
EXCITATION_VELOCITY_RAD_S = 0.5 * VELOCITY_LIMIT_RAD_S
#: |x3_hat| beyond this [rad/s^2] is refused: 4 times what the current limit can compensate
#: (2515 rad/s^2); a lumped disturbance the law cannot cancel even at 20 A is not an estimate
#: to act on (the paper's disturbances stay below 1e3 rad/s^2, the deep-sea case's ESO below
#: 400).
DISTURBANCE_LIMIT_RAD_S2 = 4.0 * CURRENT_ACCELERATION_RAD_S2
#: Change of the implied joint velocity per second a measurement may show [rad/s^2]: what the
#: current limit and the largest accepted disturbance can do together (3144). A 20 mrad glitch
#: in one 1 ms sample changes the implied velocity by 20 rad/s, 2e4 rad/s^2: refused.
ACCELERATION_LIMIT_RAD_S2 = CURRENT_ACCELERATION_RAD_S2 + DISTURBANCE_LIMIT_RAD_S2
#: A step of the measurement that persists over this many consecutive samples is a real
#: discontinuity (a re-homed encoder), no glitch: it becomes the new baseline and the
#: receivers restart as after a jump of the time base.
PLAUSIBILITY_CONFIRM_SAMPLES = 3
#: d(x2_hat)/d(u) of one observer step is dt * theta_1n (0.031 rad/s/A at 1 kHz); an estimate
#: claiming more than twice the nominal theta_1n times the receiver's sample time is refused
#: (``input_current_gain_limit``).
INPUT_CURRENT_GAIN_THETA1_FACTOR = 2.0


def input_current_gain_limit(dt_s: float) -> float:
    """Largest d(x2_hat)/d(u) an estimate may claim at sample time ``dt_s`` [rad/s/A]."""
    return INPUT_CURRENT_GAIN_THETA1_FACTOR * THETA1N * dt_s


# --- timeouts ---------------------------------------------------------------------------------
#: The drive (plant or driver) applies 0 A when the newest command is older than this [s].
COMMAND_TIMEOUT_S = 0.01
#: After the command timeout the drive coasts at 0 A for this long [s] before it engages the
#: holding brake: a short gap (a stalled controller) is no reason to brake a moving joint.
BRAKE_DELAY_S = 0.05
BRAKE_DELAY_RANGE_S = (0.0, 10.0)
#: The controller answers 0 A when its newest measurement or estimate is older than this [s].
#: Until then the drive holds the last command, which its own gate bounds at COMMAND_TIMEOUT_S.
#: 7 ms, not shorter: a 0 A answer to a host hiccup costs the joint the holding current for the
#: rest of the gap, and the law's catch-up reaches the current limit (tests/test_recovery.py,
#: host stalls of 1-6 ms in both nodes: 2-6 samples at the limit per 2 s at 5 ms, none at 7 ms).
MEASUREMENT_TIMEOUT_S = 0.007
ESTIMATE_TIMEOUT_S = 0.007
TIMEOUT_RANGE_S = (1.0e-3, 10.0)
#: The controller's graded answer to a stale input (docs/safety.md#recovery-policy): up to
#: the measurement/estimate timeout it sends nothing and the drive holds the last command;
#: then 0 A without the brake; once the input is older than this [s], 0 A with the brake
#: (safe_stop). Equal to the drive's command timeout: a joint that has not been commanded
#: for that long is braked by its own gate too, and any gap beyond it ends in the resync.
BRAKE_AFTER_S = COMMAND_TIMEOUT_S
#: Realtime: a stamp later than the receiver's clock plus this [s] is refused. The joint stamps
#: each sample at its instant, before it is sent, so on one host a genuine stamp is never
#: ahead; 2 ms covers clock granularity and scheduling. Raise it (parameter
#: future_stamp_tolerance_s) only for nodes on hosts with offset clocks.
FUTURE_STAMP_TOLERANCE_S = 2.0e-3
FUTURE_STAMP_TOLERANCE_RANGE_S = (0.0, 10.0)
#: Rate of a diagnostic topic (plant/truth, controller/state) [Hz]; 0: every sample.
DIAGNOSTICS_RATE_RANGE_HZ = (0.0, 1.0e4)
#: Largest stamp any node accepts [ns]: one hour before builtin_interfaces/Time's int32
#: seconds overflow (2^31 - 1 s), so a stamp plus the few samples a node adds stays writable.
STAMP_MAX_NS = (2**31 - 1 - 3600) * 1_000_000_000

# --- commanded trajectories (actuator_controller.trajectory, goal_rules) ---------------------
#: A goal is refused when its planned x1d needs a nominal current (x1d'' - theta_2n x1d') /
#: theta_1n beyond this share of the current limit anywhere (eq. (3) without the disturbance):
#: the rest is kept for the lumped disturbance the law cancels and for its feedback.
GOAL_CURRENT_SHARE = 0.5
#: ... or when its planned x1d comes closer than this [rad] to the joint's soft position limits
#: (where the joint brakes): a tracking error cannot carry the joint onto them.
GOAL_POSITION_MARGIN_RAD = 0.01
#: ... or when its planned |x1d'| exceeds this share of the joint's soft velocity limit.
GOAL_VELOCITY_SHARE = 0.9
#: Default bound on |x1d''| of a stop (a cancel, an aborted goal) [rad/s^2]: half of what the
#: current limit can command at the nominal model (314), so the stop leaves the other half for
#: the disturbance and the feedback, and no sample of a stop needs the limit.
STOP_DECELERATION_RAD_S2 = 0.5 * CURRENT_ACCELERATION_RAD_S2

# --- metrics ----------------------------------------------------------------------------------
#: Start of the steady-state window [s]: the references carry (1 - exp(-t)), within 0.7 % of
#: 1 after 5 s; the paper does not state its window (docs/paper-resolutions.md, 18).
STEADY_STATE_START_S = 5.0
#: A goal of a commanded run has settled once |e| stays within this [rad] (its settling time,
#: actuator_analysis.goals): 1.4x the paper's worst steady-state error of PP-NFTSMC-ESO (Table 6).
GOAL_SETTLING_BAND_RAD = 1.0e-3

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
#: A run counts as saturated, for gain design, beyond this fraction of samples
#: at the current limit.
SATURATED_FRACTION_LIMIT = 0.01
#: Spectral radius a designed gain set must not exceed (the paper's gains: 0.987 without delay).
DESIGN_TARGET_RADIUS = 0.98
