# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""``bag_identify``: the joint's model from recorded runs, with intervals, fit and parameter file.

ros2 run actuator_analysis bag_identify BAG [BAG ...] [--params FILE] [--json FILE] [--out DIR]

Reads the angle and the current the joint held (``identify_data``), fits theta1, theta2 and a
friction model with 95 % intervals (``identify``), judges the model on held-out data
(``identify_heldout``) and writes the parameter file the observer and the controller load
(``--params``; ``actuator_core.identified``). Data that cannot identify the model is refused
with its reason and exit status 2, as is an unreadable bag or a bag without the topics.
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
from pathlib import Path
from typing import Optional, Sequence

import yaml
from tabulate import tabulate

from actuator_bag.errors import BagError, run_cli
from actuator_bag.msgdefs import DefinitionSource, definition_roots
from actuator_bag.outputs import check_output_file, check_output_folder
from actuator_core import limits
from actuator_core.identified import IdentifiedJoint, parameters_document

from . import identify as idf
from .cli import add_msg_path, write_figures, write_json
from .identify_data import load_bag, split_records
from .identify_joint import Identification, identify

#: Held-out velocity r^2 from which a fit is called good (WPILib SysId's rule of thumb).
GOOD_FIT_R2 = 0.9
#: What --out draws.
FIGURE_FILES = ('identify_held_out.png', 'identify_friction.png')


class IdentificationRefused(BagError):
    """The input cannot identify the joint (bad data, unreadable bag): exit status 2."""

    exit_code = 2


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface of bag_identify."""
    parser = argparse.ArgumentParser(
        prog='bag_identify',
        description="Identify the joint's model from recorded runs (angle and the current it "
        'held): theta1 = k_t/(J N), theta2 and friction per inertia with 95 %% intervals, a '
        'held-out fit, and a parameter file for the observer and the controller. '
        + idf.IDENTIFIABLE,
    )
    parser.add_argument('bags', nargs='+', type=Path, metavar='BAG', help='bag folders or .mcap')
    parser.add_argument(
        '--params',
        type=Path,
        help='write the parameter file (the nominal model of the ESO and the controller, and '
        'the identified model for design_gains --joint) here',
    )
    parser.add_argument('--json', type=Path, help='write every estimate and figure as JSON here')
    parser.add_argument('--out', type=Path, help='draw the held-out fit and friction figures here')
    parser.add_argument(
        '--joint-name', default='', help='the joint in joint_states (default: the first)'
    )
    parser.add_argument(
        '--torque-per-amp',
        type=float,
        metavar='NM_PER_A',
        help='k_t N the joint computed its effort with (CiA 402 driver: torque_constant_nm_a x '
        'gear_ratio); without plant/truth, the current is joint_states effort / this',
    )
    parser.add_argument(
        '--current-limit',
        type=float,
        default=limits.CURRENT_LIMIT_A,
        metavar='A',
        help='without controller/state: a current this large counts as at the limit '
        '(default %(default)s A)',
    )
    parser.add_argument(
        '--cutoff',
        type=float,
        default=idf.FILTER_CUTOFF_HZ,
        metavar='HZ',
        help='zero-phase low-pass before differentiating (default %(default)s Hz)',
    )
    add_msg_path(parser)
    parser.add_argument('-q', '--quiet', action='store_true', help='print the estimates only')
    return parser


def _check_numbers(args: argparse.Namespace) -> None:
    """Refuse non-finite or non-positive numeric options."""
    for name in ('torque_per_amp', 'current_limit', 'cutoff'):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise IdentificationRefused(f'--{name.replace("_", "-")} must be finite and > 0')


def identified_joint(result: Identification) -> IdentifiedJoint:
    """Return the parameter file's description of the chosen model."""
    values = {name: result.value(name) for name in idf.PARAMETERS[result.model]}
    low1, high1 = result.interval('theta1')
    low2, high2 = result.interval('theta2')
    return IdentifiedJoint(
        friction_model=result.model,
        theta1_low=low1,
        theta1_high=high1,
        theta2_low=low2,
        theta2_high=high2,
        held_out_velocity_r2=result.held_out.velocity_r2,
        sample_time_s=result.figures['sample_time_s'],
        **values,
    )


def verdict(result: Identification) -> str:
    """Good or poor, by the held-out velocity r^2."""
    r2 = result.held_out.velocity_r2
    if r2 >= GOOD_FIT_R2:
        return f'good (held-out velocity r^2 {r2:.4f} >= {GOOD_FIT_R2})'
    return (
        f'POOR (held-out velocity r^2 {r2:.4f} < {GOOD_FIT_R2}): the model does not describe '
        'this run; a joint whose parameters drift, a load that varies, or a current source '
        'that is not the current held'
    )


def report(result: Identification, sources: dict[str, str]) -> str:
    """Return the text report: data, estimates against Table 1, model choice, held-out fit."""
    d, h = result.figures, result.held_out
    rows = []
    for name, est in result.chosen.as_dict().items():
        versus = ''
        if name == 'theta1':
            change = 100 * (est['value'] / limits.THETA1N - 1)
            versus = f"{change:+.1f} % from Table 1's theta1n {limits.THETA1N:.4g}"
        elif name == 'theta2':
            versus = f"Table 1's theta2n {limits.THETA2N:.4g} is the motor's alone"
        rows.append(
            (
                name,
                f'{est["value"]:.5g}',
                f'[{est["low"]:.5g}, {est["high"]:.5g}]',
                est['unit'],
                versus,
            )
        )
    table = tabulate(
        rows,
        headers=('parameter', 'estimate', '95 % interval', 'unit', 'nominal'),
        disable_numparse=True,
    )
    models = ', '.join(
        f'{name} BIC {fit.bic:.0f}{"" if idf.supported(fit) else " (extra term not significant)"}'
        for name, fit in result.fits.items()
    )
    lines = [
        f'data: {d["usable_s"]:.1f} s usable in {d["records"]} record(s); '
        f'{d["training_samples"]} training samples in {d["training_blocks"]} blocks, '
        f'{d["held_out_samples"]} held out in {d["held_out_blocks"]} blocks of {idf.BLOCK_S:g} s; '
        f'acceleration RMS {d["acceleration_rms_rad_s2"]:.1f} rad/s^2, current at its limit in '
        f'{100 * d["at_limit_fraction"]:.2f} % of the samples',
        'current: ' + '; '.join(f'{bag}: {src}' for bag, src in sources.items()),
        f'friction model: {result.model} (lowest BIC of the supported: {models})',
        table,
        f'held-out fit (each block simulated from its measured start): velocity r^2 '
        f'{h.velocity_r2:.4f}, RMS {h.velocity_rms_rad_s:.3g} rad/s; angle r^2 '
        f'{h.position_r2:.4f}, RMS {h.position_rms_rad:.3g} rad',
        f'fit: {verdict(result)}',
        f'note: {idf.IDENTIFIABLE}',
        *(f'note: {n}' for n in result.notes),
    ]
    return '\n'.join(lines)


def write_parameters(path: Path, result: Identification, bags: Sequence[Path]) -> None:
    """Write the parameter file, with a header saying where it came from and how to load it."""
    joint = identified_joint(result)
    low, high = result.interval('theta1')
    header = [
        f'Identified by bag_identify from {", ".join(str(b) for b in bags)} '
        f'({dt.datetime.now(dt.timezone.utc):%Y-%m-%dT%H:%M:%SZ}).',
        f'theta1 = {joint.theta1:.6g} rad/s^2/A (95 %: {low:.6g} to {high:.6g}), '
        f'{100 * (joint.theta1 / limits.THETA1N - 1):+.1f} % from Table 1; theta2 = '
        f'{joint.theta2:.6g} 1/s; friction model {joint.friction_model}; fit {verdict(result)}.',
        idf.IDENTIFIABLE + '.',
        "Load after the scenario's file: bringup --params-file FILE (launch: params_file:=FILE);",
        'design gains for this joint: design_gains --joint FILE --out DIR.',
    ]
    text = ''.join(f'# {line}\n' for line in header)
    text += yaml.safe_dump(parameters_document(joint), sort_keys=False)
    try:
        path.write_text(text, encoding='utf-8')
    except OSError as err:
        raise BagError(f'cannot write {path}: {err.strerror}') from None


def _main(argv: Optional[Sequence[str]]) -> int:
    """Read, identify, print, write."""
    args = build_parser().parse_args(argv)
    _check_numbers(args)
    for option in ('params', 'json'):
        if getattr(args, option):
            check_output_file(f'--{option}', getattr(args, option), args.bags)
    if args.out:
        check_output_folder('--out', args.out, args.bags, FIGURE_FILES)
    source = DefinitionSource(definition_roots(args.msg_path))
    records, sources, notes = [], {}, []
    try:
        for bag in args.bags:
            samples = load_bag(
                bag, source, args.joint_name, args.torque_per_amp, args.current_limit
            )
            records += split_records(samples)
            sources[str(bag)] = samples.source
            notes += [f'{bag}: {n}' for n in samples.notes]
        result = identify(records, args.cutoff)
    except idf.RefusedData as err:
        raise IdentificationRefused(f'refused: {err}') from None
    except BagError as err:
        raise IdentificationRefused(str(err)) from None
    result.notes += notes
    if args.quiet:
        print(
            tabulate(
                [
                    (k, v['value'], v['low'], v['high'], v['unit'])
                    for k, v in result.chosen.as_dict().items()
                ],
                headers=('parameter', 'estimate', '95 % low', '95 % high', 'unit'),
            )
        )
    else:
        print(report(result, sources))
    if args.params:
        write_parameters(args.params, result, args.bags)
        print(f'parameters: {args.params} (bringup --params-file {args.params})')
    if args.json:
        write_json(
            args.json,
            {'bags': [str(b) for b in args.bags], 'current_sources': sources, **result.as_dict()},
        )
    if args.out:
        from .identify_figures import draw_identification

        write_figures(lambda: draw_identification(result, args.out), args.out)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``bag_identify``."""
    return run_cli('bag_identify', _main, argv)


if __name__ == '__main__':
    raise SystemExit(main())
