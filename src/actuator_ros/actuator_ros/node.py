# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""ManagedNode: the lifecycle base of the plant, ESO and controller nodes (rclpy.lifecycle).

States as in ros2_control's hardware lifecycle:
  unconfigured  parameters declared and checked, nothing built;
  configure     parameters read again and checked, the core objects built, topics created,
                nothing published;
  activate      sampling / estimating / commanding starts;
  deactivate    the node stops acting: a drive's gate goes to 0 A with the brake, the
                controller sends one safe-stop command, the observer stops stepping;
  cleanup       back to unconfigured (topics and core objects dropped);
  shutdown      from any state; error processing on an exception in a callback: deactivate and
                clean up, back to unconfigured.
A node that is not active never commands current. ``autostart:=true`` runs configure and
activate at start-up, so ``ros2 run`` alone gives a running node; otherwise ``ros2 lifecycle
set`` (or a lifecycle manager) drives the transitions.
"""

from __future__ import annotations

import traceback

from rcl_interfaces.msg import ParameterDescriptor, ParameterType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from actuator_ros import publisher_hooks
from actuator_ros.log import RateLimitedLog
from actuator_ros.parameters import (
    ParameterError,
    check_unknown_parameters,
    declare_choice,
    declare_common,
    declare_number,
    declare_text,
    only_while_unconfigured,
)
from actuator_ros.process_member import ProcessMember
from actuator_ros.realtime import EXECUTORS, NICE_RANGE, RealtimeSettings


def declare_realtime(node, settings: RealtimeSettings) -> RealtimeSettings:
    """Declare thread_priority, cpu_affinity, executor and nice.

    Applied before rclpy.init, see realtime.
    """
    return RealtimeSettings(
        thread_priority=declare_number(
            node,
            'thread_priority',
            settings.thread_priority,
            0,
            99,
            '',
            'SCHED_FIFO priority of every thread of the process, applied before the '
            'middleware starts (0: normal scheduling)',
        ),
        cpu_affinity=declare_text(
            node,
            'cpu_affinity',
            settings.cpu_affinity,
            'CPUs the process may run on, e.g. "1" or "0,1" (empty: any)',
        ),
        executor=declare_choice(
            node,
            'executor',
            settings.executor,
            EXECUTORS,
            'rclpy executor: events (EventsExecutor, lower latency) or single_threaded',
        ),
        nice=declare_number(
            node,
            'nice',
            settings.nice,
            *NICE_RANGE,
            '',
            'niceness of the process under normal scheduling, applied before the middleware '
            'starts (above 0: the loop gets a contended core first; below 0 needs CAP_SYS_NICE)',
        ),
    )


class ManagedNode(LifecycleNode, ProcessMember):
    """Lifecycle plumbing; subclasses write load_parameters, build, start, stop, drop."""

    def __init__(
        self, node_name: str, settings: RealtimeSettings = RealtimeSettings(), **kwargs
    ) -> None:
        """Declare and check every parameter.

        ParameterError: the process exits 2 with one line.
        """
        super().__init__(node_name, **kwargs)
        self.log = RateLimitedLog(self.get_logger())
        self.configured = False
        self.active = False
        self.finished = False  # ProcessMember: the run is over
        self.error: str | None = None  # ProcessMember: the run failed
        declare_common(self)
        self.set_descriptor(
            'use_sim_time',
            ParameterDescriptor(
                name='use_sim_time',
                type=ParameterType.PARAMETER_BOOL,
                description='true: time from /clock (sim mode, the plant publishes it); '
                'false: the system clock',
            ),
        )
        self.settings = declare_realtime(self, settings)
        self.load_parameters()
        unknown = check_unknown_parameters(self)
        if unknown:
            self.get_logger().warning(
                f'ignoring parameters this node does not have: {", ".join(unknown)}'
            )
        only_while_unconfigured(self)
        # Before rclpy's own checks (undeclared name, type, range, read-only) and the on-set
        # callbacks: every request is logged, refused ones too.
        self.add_pre_set_parameters_callback(self._log_outside_change)
        self._internal_transition = False

    def _log_outside_change(self, params: list) -> list:
        """Log at warning level every parameter change requested from outside; change nothing.

        A pre-set callback: rclpy calls it for set_parameters (the parameter service's, as
        ``ros2 param set`` calls it) before it validates anything, and never for a declaration.
        rclpy goes on with the concatenation of what its pre-set callbacks return, so a second
        one would request every parameter twice. The parameter service does not tell who called.
        """
        self.get_logger().warning(
            'parameter change requested from outside (caller not known to rclpy): '
            + ', '.join(f'{p.name}={p.value!r}' for p in params)
        )
        return params

    def refuse_sim_time_in_realtime(self, mode: str) -> None:
        """Realtime mode runs on the system clock: use_sim_time would stop the watchdog's clock."""
        if mode == 'realtime' and self.get_parameter('use_sim_time').value:
            raise ParameterError(
                "parameter 'use_sim_time' = true refused in realtime mode: ages and the "
                'watchdog would follow /clock, which nobody publishes there'
            )

    def _outside(self, transition: str) -> None:
        """Log at warning level a lifecycle transition this process did not ask for itself."""
        if not self._internal_transition:
            self.get_logger().warning(
                f'lifecycle transition {transition!r} requested from outside (service '
                'change_state; rclpy does not tell the caller)'
            )

    # --- what a node implements ---------------------------------------------------------------
    def load_parameters(self) -> None:
        """Declare (first call) or read (at configure) and check every parameter.

        Raise ParameterError.
        """

    def build(self) -> None:
        """Build the core objects and create the topics; publish nothing."""

    def start(self) -> None:
        """Begin acting (sampling, estimating, commanding)."""

    def stop(self) -> None:
        """Stop acting; leave the joint safe."""

    def drop(self) -> None:
        """Destroy what ``build`` created."""

    # --- transitions ----------------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Parameters read and checked, core built.

        a refusal is logged and the node stays unconfigured.
        """
        self._outside('configure')
        self._drop()  # what a joint fault's error processing left built (JointNode.on_error)
        try:
            self.load_parameters()
            self.build()
        except ParameterError as exc:
            self.get_logger().error(f'configure refused: {exc}')
            return TransitionCallbackReturn.FAILURE
        self.configured = True
        self.get_logger().info('configured')
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Enable the lifecycle publishers, then start acting."""
        self._outside('activate')
        result = super().on_activate(state)
        self.active = True
        self.start()
        self.get_logger().info('active')
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stop acting, then disable the publishers."""
        self._outside('deactivate')
        self._stop()
        self.get_logger().info('inactive')
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Back to unconfigured."""
        self._outside('cleanup')
        self._drop()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState | None) -> TransitionCallbackReturn:
        """From any state: stop and drop (``state`` None: ``release`` at exit)."""
        self._stop()
        self._drop()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Handle an exception in a transition: leave the joint safe, back to unconfigured."""
        self.get_logger().error(
            f'error processing: {traceback.format_exc(limit=1).strip().splitlines()[-1]}'
        )
        self._stop()
        self._drop()
        return TransitionCallbackReturn.SUCCESS

    # --- publishers: through the process's hooks (an in-process recording's tap) ---------------
    def create_lifecycle_publisher(self, msg_type, topic, qos_profile, **kwargs):
        """Return rclpy's lifecycle publisher, passed through actuator_ros.publisher_hooks."""
        publisher = super().create_lifecycle_publisher(msg_type, topic, qos_profile, **kwargs)
        return publisher_hooks.hooked(self, publisher, msg_type)

    def destroy_lifecycle_publisher(self, publisher) -> bool:
        """Destroy a publisher create_lifecycle_publisher returned (wrapped or not)."""
        return super().destroy_lifecycle_publisher(publisher_hooks.inner(publisher))

    def create_publisher(self, msg_type, topic, qos_profile, **kwargs):
        """Return rclpy's publisher, passed through actuator_ros.publisher_hooks."""
        publisher = super().create_publisher(msg_type, topic, qos_profile, **kwargs)
        return publisher_hooks.hooked(self, publisher, msg_type)

    def destroy_publisher(self, publisher) -> bool:
        """Destroy a publisher create_publisher returned (wrapped or not)."""
        return super().destroy_publisher(publisher_hooks.inner(publisher))

    def halt(self) -> None:
        """Stop acting now (at exit, before the last messages are acknowledged); idempotent."""
        self._stop()

    def release(self) -> None:
        """At exit, after the acknowledgements: stop and drop, as the shutdown transition does."""
        self.on_shutdown(None)

    def _stop(self) -> None:
        """stop() once, if active."""
        if self.active:
            self.active = False
            self.stop()

    def _drop(self) -> None:
        """drop() once, if configured."""
        if self.configured:
            self.configured = False
            self.drop()

    def autostart(self) -> bool:
        """Configure and activate when the autostart parameter says so.

        False when a transition failed.
        """
        if not self.get_parameter('autostart').value:
            return True
        self._internal_transition = True
        try:
            self.trigger_configure()
            if not self.configured:
                return False
            self.trigger_activate()
        finally:
            self._internal_transition = False
        return self.active
