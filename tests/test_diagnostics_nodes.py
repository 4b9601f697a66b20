# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""/diagnostics from the loop's nodes, recorded and read back by the analysis (sim time)."""

from __future__ import annotations

from rosbags.highlevel import AnyReader

from actuator_analysis.analyze import load_run

#: diagnostic_msgs/DiagnosticStatus.STALE
STALE = 3


def _level(status) -> int:
    """Return the level of a DiagnosticStatus (rclpy gives the byte constant as bytes)."""
    return status.level[0] if isinstance(status.level, bytes) else int(status.level)


def _controller_reports(test_node) -> list:
    """Collect the controller's DiagnosticStatus entries from /diagnostics into a list."""
    from diagnostic_msgs.msg import DiagnosticArray

    reports: list = []
    test_node.node.create_subscription(
        DiagnosticArray,
        '/diagnostics',
        lambda m: reports.extend(s for s in m.status if s.name == 'actuator_controller'),
        100,
    )
    return reports


def test_a_sim_run_records_every_nodes_health_and_the_stop_of_its_inputs(
    rclpy_context, ros_process, tmp_path
):
    """Each node's /diagnostics in the bag: OK while the loop runs, STALE once the plant stopped.

    The analysis judges the run by what was reported inside it.

    The loop is the one bringup starts (graph.closed_loop, sim); the other nodes are kept until
    the controller has reported the plant's silence (an event, not a sleep), then stopped, so the
    bag holds that report whatever the host's speed.
    """
    from actuator_bringup.run_description import closed_loop
    from actuator_bringup.runner import scenario_file
    from ros_helpers import TestNode, start_closed_loop

    listener = TestNode(rclpy_context, 'diagnostics_listener')
    live = _controller_reports(listener)
    bag_dir = tmp_path / 'bag'
    procs = start_closed_loop(
        ros_process,
        closed_loop('sim', 2.0, record=True, bag=bag_dir),
        scenario_file('case2_pp_nftsmc_eso'),
    )
    try:
        assert procs['plant'].wait(240) == 0, procs['plant'].describe()
        listener.spin(0.0)
        ended = len(live)  # reports from before the plant's end do not count
        listener.wait_for(
            lambda: any(_level(s) == STALE for s in live[ended:]),
            timeout=10.0,
            what='the controller reporting the stopped plant',
        )
    finally:
        listener.close()
        codes = {key: proc.stop() for key, proc in reversed(list(procs.items()))}
    assert all(code == 0 for code in codes.values()), codes
    reports: dict[str, list] = {}
    with AnyReader([bag_dir]) as reader:
        conns = [c for c in reader.connections if c.topic == '/diagnostics']
        assert conns, [c.topic for c in reader.connections]
        for conn, _, raw in reader.messages(connections=conns):
            for status in reader.deserialize(raw, conn.msgtype).status:
                values = {kv.key: kv.value for kv in status.values}
                reports.setdefault(status.name, []).append((status.level, status.message, values))
    assert {'actuator_plant', 'actuator_controller', 'actuator_eso', 'recorder'} <= set(reports)
    assert any(level == 0 for level, _, _ in reports['actuator_plant']), reports['actuator_plant']
    controller = reports['actuator_controller']
    # While the loop ran: OK at about 1 kHz of joint_states; once the plant stopped: STALE.
    running = [v for level, _, v in controller if level == 0 and 'joint_states rate [Hz]' in v]
    assert running and max(float(v['joint_states rate [Hz]']) for v in running) > 100
    stale = [m for level, m, _ in controller if level == 3]
    assert stale and 'no joint_states for' in stale[-1]
    assert controller[-1][2]['lifecycle_state'] == 'active'
    assert int(reports['actuator_eso'][-1][2]['steps']) >= 1900
    assert all(level != 2 for level, _, _ in reports['recorder'])
    # The analysis reads them, and judges the run by the reports stamped inside it: the
    # controller was OK while the plant sampled; its STALE reports of the plant's end come after
    # the last sample (sim time stopped there) and are counted apart.
    judged = load_run(bag_dir, quiet=True).diagnostics
    summary = judged['actuator_controller']
    assert summary['worst'] == 'OK', summary
    assert summary['after_run']['STALE'] == len(stale)
    # the sim-time joint stamps its reports with its samples' time, so they are judged too
    assert judged['actuator_plant']['worst'] == 'OK', judged['actuator_plant']


def test_the_controller_reports_refusals_by_reason_and_a_latch_as_error(
    rclpy_context, ros_process
):
    """A NaN measurement: WARN naming its reason; a following error: ERROR until cleanup."""
    from ros_helpers import LATCHING_CONTROLLER_ARGS, Harness, run_off
    from ros_helpers import now_ns as _now_ns

    harness = Harness(rclpy_context)
    reports = _controller_reports(harness)
    ros_process(
        'actuator_controller',
        'controller_node',
        LATCHING_CONTROLLER_ARGS,
    )
    try:
        harness.wait_for(
            lambda: harness.node.count_subscribers('joint_states') >= 1, what='the controller'
        )
        harness.wait_for(lambda: reports, what='a first report')
        t = _now_ns(harness)
        harness.send_sample(t, float('nan'))
        harness.wait_for(
            lambda: any('refused inputs (bad_measurement)' in r.message for r in reports),
            what='a report of the refusal',
        )
        assert any(r.level == b'\x01' or r.level == 1 for r in reports)
        start = t + 5_000_000
        run_off(harness, start)
        harness.wait_for(
            lambda: any('latched' in r.message for r in reports), what='a report of the latch'
        )
        latched = [r for r in reports if 'latched' in r.message]
        assert all(r.level in (b'\x02', 2) for r in latched)
        values = {kv.key: kv.value for kv in latched[-1].values}
        assert values['refused bad_measurement'] == '1' and values['status'] == 'LATCHED'
    finally:
        harness.executor.shutdown()
        harness.node.destroy_node()
