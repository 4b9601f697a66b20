# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""The Foxglove layout of a closed-loop run, built with foxglove-sdk's layout types.

It shows the run as the paper's figures do: position with the reference, the desired angle x1d
a goal or a built-in trajectory asks for (Figs. 5a/6a), and its velocity beside the estimate; the
tracking error inside the prescribed-performance bounds (Figs. 5b/6b, eqs. (8)-(12)); the
commanded current beside the plant's applied current (Fig. 8); the ESO's velocity and
disturbance estimates against the plant's truth (Fig. 7, eqs. (14)-(16)); the controller status
and every node's /diagnostics; what became of each commanded trajectory (controller/goal_events:
0 refused, 1 accepted, 2 started, 3 succeeded, 4 aborted, 5 canceled). Every series is timed
by its header stamp, so the same layout
works live (live_view) and on a recorded bag (sim-time or wall-clock stamps alike).

    python -m actuator_live_view.live_layout [OUT.json]   # writes the shipped file

The shipped file is share/actuator_live_view/foxglove/closed_loop_layout.json; a test checks
that it equals what this module builds and that every path names a field of the installed messages.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import foxglove.layouts as fl

#: The shipped layout, relative to the package source folder.
LAYOUT_FILE = Path('foxglove') / 'closed_loop_layout.json'
#: (panel title, y-axis label, [(message path, legend label), ...]).
PLOTS = (
    (
        'Position',
        'joint angle [rad]',
        [
            ('/controller/state.reference_position_rad', 'desired x1d'),
            ('/controller/state.measured_position_rad', 'measured'),
        ],
    ),
    (
        'Tracking error and PPF bounds',
        'e [rad]',
        [
            ('/controller/state.error_rad', 'error'),
            ('/controller/state.lower_bound_rad', 'lower bound'),
            ('/controller/state.upper_bound_rad', 'upper bound'),
        ],
    ),
    (
        'Current',
        'u [A]',
        [
            ('/current_command.current_a', 'commanded'),
            ('/plant/truth.current_a', 'applied (plant)'),
            ('/controller/state.current_unlimited_a', 'law before the limit'),
        ],
    ),
    (
        'Velocity: desired, estimate, truth',
        'rad/s',
        [
            ('/controller/state.reference_velocity_rad_s', "desired x1d'"),
            ('/eso/estimate.velocity_rad_s', 'ESO'),
            ('/plant/truth.velocity_rad_s', 'truth'),
        ],
    ),
    (
        'Disturbance: estimate vs truth',
        'rad/s^2',
        [
            ('/eso/estimate.disturbance_rad_s2', 'ESO'),
            ('/plant/truth.disturbance_rad_s2', 'truth'),
        ],
    ),
)
STATUS_PATH = '/controller/state.status'
GOAL_EVENT_PATH = '/controller/goal_events.event'


def _plot(title: str, unit: str, series) -> fl.PlotPanel:
    """One time plot of header-stamped series."""
    return fl.PlotPanel(
        title=title,
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value=path, label=label, timestamp_method='headerStamp')
                for path, label in series
            ],
            y_axis_label=unit,
            show_legend=True,
            legend_display='floating',
            is_synced=True,
        ),
    )


def build_layout() -> fl.Layout:
    """Build it: plots on the left (two columns), status and diagnostics on the right."""
    plots = [_plot(*p) for p in PLOTS]
    status = fl.StateTransitionsPanel(
        title='Controller status (actuator_core.status: 0 OK, 1 WAITING, ... 8 INACTIVE)',
        config=fl.StateTransitionsConfig(
            paths=[
                fl.StateTransitionsSeries(
                    value=STATUS_PATH, label='status', timestamp_method='headerStamp'
                ),
                fl.StateTransitionsSeries(
                    value=GOAL_EVENT_PATH, label='goal event', timestamp_method='headerStamp'
                ),
            ],
            is_synced=True,
        ),
    )
    diagnostics = fl.DiagnosticsSummaryPanel(
        title='Node health (/diagnostics)',
        config=fl.DiagnosticsSummaryConfig(topic_to_render='/diagnostics', sort_by_level=True),
    )

    def column(panels) -> fl.SplitContainer:
        return fl.SplitContainer(
            direction='column', items=[fl.SplitItem(content=p) for p in panels]
        )

    return fl.Layout(
        content=fl.SplitContainer(
            direction='row',
            items=[
                fl.SplitItem(proportion=2, content=column(plots[:3])),
                fl.SplitItem(proportion=2, content=column(plots[3:])),
                fl.SplitItem(proportion=1.5, content=column([status, diagnostics])),
            ],
        )
    )


def layout_json() -> str:
    """Return the layout as the shipped file holds it (indented, one trailing newline)."""
    return json.dumps(json.loads(build_layout().to_json()), indent=2, sort_keys=True) + '\n'


def message_paths() -> list[str]:
    """Every ``/topic.field`` the layout reads."""
    return [path for _, _, series in PLOTS for path, _ in series] + [STATUS_PATH, GOAL_EVENT_PATH]


def main(argv=None) -> int:
    """Write the layout JSON to the given file (default: the source tree's shipped one)."""
    args = sys.argv[1:] if argv is None else list(argv)
    out = Path(args[0]) if args else Path(__file__).resolve().parents[1] / LAYOUT_FILE
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(layout_json())
    print(f'wrote {out}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
