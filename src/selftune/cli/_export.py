"""``selftune export``'s arguments."""

from __future__ import annotations

import argparse

from ._parsing import _add_command, _finite_float, _Subparsers


def _add_export(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "export",
        _run_export,
        help="write a result's control law as C99 firmware (selftune_law.h, .c)",
        description=(
            "Write the control law of RESULT.json (from selftune learn, tune or tune"
            " --online) as portable C99 in float32 for a drive's firmware: the law as the"
            " JSON states it, the voltage limit |u_dq| <= U_MAX and anti-windup by"
            " integrator clamping (docs/export.md)."
        ),
    )
    parser.add_argument("result", metavar="RESULT.json", help="a selftune JSON result")
    parser.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="directory for selftune_law.h and selftune_law.c: new, empty, or an earlier"
        " export, replaced as a whole",
    )
    parser.add_argument(
        "--u-max",
        type=_finite_float,
        metavar="V",
        help="the limit on the dq voltage's magnitude, V: V_dc / sqrt(3) with space-vector"
        " PWM (default: from the DC bus the file names, if it names one)",
    )


def _run_export(args: argparse.Namespace) -> int:
    from ..commands import export_command

    return export_command(args.result, args.out, args.u_max)
