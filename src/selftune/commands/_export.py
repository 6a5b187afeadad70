"""``selftune export``: a JSON result's control law as C99 firmware for the drive."""

from __future__ import annotations

import math
import os
from datetime import UTC, datetime

from ..core._atomic import check_output_directory

#: What ``selftune export`` writes (the header, then the source; see :mod:`..report`).
EXPORT_WHAT = "selftune export output"


def export_command(result_path: str, out: str, u_max: float | None) -> int:
    """``selftune export``: write ``selftune_law.h`` and ``selftune_law.c`` into ``out``.

    The voltage limit is ``u_max``, or, without it, ``V_dc / sqrt(3)`` of the DC bus the
    file names (``selftune tune --online``'s drive); one of the two is needed.

    Parameters
    ----------
    result_path : str
        The JSON of ``selftune learn``, ``tune`` or ``tune --online`` (or ``solve`` with a
        schedule over speed: its tables over ``omega_e``).
    out : str
        The output directory: absent, empty, or a previous export (its two files are
        replaced as one set); checked before anything is read.
    u_max : float or None
        ``SELFTUNE_U_MAX``, the limit on ``|u_dq|``, V.

    Raises
    ------
    SelftuneError
        One line, if the file has no law the firmware can run, no limit is known, or
        ``out`` cannot take the files.
    """
    from .. import __version__
    from ..config import load_law_result
    from ..errors import InputError
    from ..model import SpeedCurrentSchedule
    from ..report import FIRMWARE_FILES, firmware, write_firmware

    check_output_directory(out, FIRMWARE_FILES, EXPORT_WHAT)
    result = load_law_result(result_path)
    source = os.path.basename(result_path)
    limit = u_max
    origin = "--u-max"
    if limit is None:
        if result.dc_voltage is None:
            raise InputError(
                f"--u-max: {result_path} names no DC-bus voltage; give the limit on |u_dq| "
                "in V (V_dc / sqrt(3) with space-vector PWM)"
            )
        limit = result.dc_voltage / math.sqrt(3.0)
        origin = f"the file's DC bus {result.dc_voltage:g} V / sqrt(3)"
    date = datetime.now(UTC).strftime("%Y-%m-%d")
    files = firmware(result, limit, source=source, version=__version__, date=date)
    paths = write_firmware(files, out)
    schedule = result.schedule
    law = result.law if schedule is None else schedule.first_law
    what = f"the law of {result_path} ({result.key})"
    if isinstance(schedule, SpeedCurrentSchedule):
        (low, high), (first, last) = schedule.covered
        what = (
            f"the schedule over speed and current of {result_path}: "
            f"{schedule.current.size} currents, i_q* {first:g} to {last:g} A, times "
            f"{schedule.electrical_speed.size} speeds, omega_e {low:g} to {high:g} rad/s "
            "(bilinear, clamped outside)"
        )
    elif schedule is not None:
        low, high = schedule.covered
        what = (
            f"the schedule of {result_path}: {schedule.grid.size} {schedule.points}, "
            f"{schedule.symbol} {low:g} to {high:g} {schedule.unit} (clamped outside)"
        )
    print(
        f"{what}: d = {law.history} past voltage(s), {law.r} integrator(s), h = "
        + ("not stated" if result.h is None else f"{result.h:g} s")
    )
    print(f"voltage limit SELFTUNE_U_MAX = {limit:.9g} V ({origin}); anti-windup: clamping")
    print(f"wrote {', '.join(path.name for path in paths)} to {out}/")
    return 0
