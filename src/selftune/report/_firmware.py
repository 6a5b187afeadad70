"""A drive's control law as firmware: portable C99 in float32 (``selftune export``).

:func:`firmware` writes the law of a JSON result (:class:`~selftune.config.LawResult`)
as a header, ``selftune_law.h``, and a source file, ``selftune_law.c``: no dynamic memory,
no library call but ``sqrtf``, float32 throughout. The source computes the law as the
JSON states it (:mod:`selftune.core._control_law`)::

    u_k = U w_k - K [x_k - X w_k; u_(k-d) - U w_k; ...; u_(k-1) - U w_k] - K_i z_k
    z_(k+1) = z_k + h (C x_k + F w_k)

with ``x = i_dq``, then the voltage limit and its anti-windup of
:mod:`selftune.core._voltage_limit` (the rule the simulated drives run): a command
longer than ``SELFTUNE_U_MAX`` is scaled onto that circle, its angle kept; at such a
sample the integrators hold (clamping). The past voltages the law feeds back are the
ones it returned (limited).

Every number is printed with ``%.9g`` of its float32 value, which reads back to the same
float32. The functions (fixed by the interface)::

    void selftune_init(selftune_state *s);
    void selftune_step(selftune_state *s, const float i_dq[2], const float w[q],
                       float omega_e, float u_dq[2]);

with ``q`` the law's reference channels: 2 for a surface motor's ``[p speed phi_pm, T*]``,
3 for an interior one's ``[p speed phi_pm, i_d*, i_q*]``.

``omega_e`` (electrical speed, rad/s) is the argument of a schedule over speed
(:class:`~selftune.model.SpeedSchedule`, a JSON's ``schedule``): the source then holds
``K``, ``K_i``, ``U`` and ``X`` as tables over the grid ``OMEGA_E`` and interpolates each
entry linearly between the two neighbours of ``omega_e``, clamped to the table's first or
last law outside the grid (a firmware cannot refuse a speed; the design covered only the
grid's range). Without a schedule ``omega_e`` is unused.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import LawResult
from ..core import ControlLaw, positive_finite
from ..core._atomic import output_directory, write_text
from ..errors import InputError
from ..model import CurrentSchedule, SpeedCurrentSchedule, motor_from_parameters
from ._firmware_tables import (
    Scheduled,
    c_float,
    c_matrix,
    grid_macros,
    schedule_call,
    schedule_key,
    schedule_tables,
)

__all__ = ["ANTI_WINDUP", "FIRMWARE_FILES", "Firmware", "firmware", "write_firmware"]

#: The files of ``selftune export``'s output set: the header, then the source.
FIRMWARE_FILES = ("selftune_law.h", "selftune_law.c")

#: The anti-windup the firmware implements, as its header states it.
ANTI_WINDUP = (
    "integrator clamping (conditional integration): at a sample where the voltage limit "
    "scales the command, the integrators hold (z_(k+1) = z_k)"
)


@dataclass(frozen=True)
class Firmware:
    """The two files of an exported law.

    Attributes
    ----------
    header : str
        ``selftune_law.h``: the constants, the state and the two functions' declarations.
    source : str
        ``selftune_law.c``: the gains and the two functions.
    """

    header: str
    source: str

    @property
    def files(self) -> dict[str, str]:
        """File name -> text, in the order of :data:`FIRMWARE_FILES`."""
        return dict(zip(FIRMWARE_FILES, (self.header, self.source), strict=True))


def _law(result: LawResult) -> ControlLaw:
    """The law whose structure the firmware runs: the schedule's where there is one."""
    return result.law if result.schedule is None else result.schedule.first_law


def _key(result: LawResult) -> str:
    """Where the file holds the law exported."""
    return result.key if result.schedule is None else schedule_key(result.schedule)


def _check(result: LawResult, source: str) -> ControlLaw:
    """The law, if the firmware's interface can run it."""
    law = _law(result)
    if result.scheduled and result.schedule is None:
        raise InputError(f"{source}: schedule: the file names a schedule but states none")
    if isinstance(result.schedule, CurrentSchedule | SpeedCurrentSchedule) and law.q != 3:
        raise InputError(
            f"{source}: {_key(result)}: the firmware looks i_q* up in w[2] of the current "
            f"references [p speed phi_pm, i_d*, i_q*]; this law has {law.q} reference channels"
        )
    if (law.n, law.m) != (2, 2):
        raise InputError(
            f"{source}: {_key(result)}: the firmware takes i_dq (2 currents) and gives u_dq (2"
            f" voltages); this law has (n, m) = {(law.n, law.m)}"
        )
    return law


def _motor_text(result: LawResult) -> str:
    if result.motor is None:
        return "not stated in the file (a selftune learn result names the log, not a motor)"
    return f"{motor_from_parameters(result.motor).describe()} (nameplate)"


def _banner(result: LawResult, u_max_text: str, source: str, version: str, date: str) -> str:
    law = _law(result)
    h = "not stated in the file" if result.h is None else f"{result.h:.9g} s"
    if result.input_delay is None:
        delay = (
            f"not stated in the file; the law feeds back the {law.history} voltage(s) "
            "computed before, as one designed for that many samples of delay does"
        )
    else:
        delay = (
            f"{result.input_delay} sample(s): the voltage computed at sample k is applied "
            f"over sample k + {result.input_delay}"
        )
    state = " ".join(law.state)
    paragraphs = [
        f"Generated by selftune {version} from {source} ({_key(result)}) on {date}; do not "
        "edit: export the result again.",
        "",
        f"Sampling period h: {h}.",
        f"Computation delay assumed: {delay}.",
        f"Motor: {_motor_text(result)}.",
        "",
        "The law, as the file states it (float32):",
        "  u_k = U w_k - K [x_k - X w_k; u_(k-d) - U w_k; ...; u_(k-1) - U w_k]",
        "        - K_i z_k",
        "  z_(k+1) = z_k + h (C x_k + F w_k)",
        f"x = i_dq = [i_d, i_q], the currents measured at sample k, A; {_reference_text(law)},"
        " as in the file, held over the sample; u = u_dq = [u_d, u_q], V; "
        f"{_omega_text(result)} The order of the state, K's columns then K_i's (u1[k-1]: "
        "u_d computed at sample k - 1; z: the integrators, A s):",
        f"  {state}",
        "",
        f"Voltage limit: |u_dq| <= SELFTUNE_U_MAX = {u_max_text}, the linear modulation "
        "range (V_dc / sqrt(3) with space-vector PWM): a longer command is scaled onto "
        "that circle, its angle kept. The limited voltage is returned and is the one fed "
        "back as a past input.",
        f"Anti-windup: {ANTI_WINDUP}.",
        "",
        "Use: selftune_init once, then selftune_step once per sample with the currents "
        "sampled at that instant; apply the voltage it returns as the drive the law was "
        "made for does (the delay above). Portable C99, float32, no dynamic "
        "memory, no library call but sqrtf.",
    ]
    wrapped = [
        line
        for paragraph in paragraphs
        for line in (
            [paragraph] if paragraph.startswith("  ") else textwrap.wrap(paragraph, 76) or [""]
        )
    ]
    return "/*\n" + "\n".join(f" * {line}".rstrip() for line in wrapped) + "\n */\n"


def _reference_text(law: ControlLaw) -> str:
    """What the banner says ``w`` is."""
    if law.q == 3:
        return "w = [p speed phi_pm, i_d*, i_q*], V, A and A (an interior motor's currents)"
    if law.q == 2:
        return "w = [p speed phi_pm, T*], V and N m"
    return f"w = the file's {law.q} reference channels"


def _dot(matrix: str, vector: str, q: int) -> str:
    """``matrix[i][0] * vector[0] + ...``: row i of a matrix times a vector of q."""
    return " + ".join(f"{matrix}[i][{j}] * {vector}[{j}]" for j in range(q))


def _omega_text(result: LawResult) -> str:
    """What the banner says of omega_e (and of a schedule over the current)."""
    schedule = result.schedule
    if schedule is None:
        return "omega_e, the electrical speed, rad/s, is unused (no schedule over speed)."
    clamped = (
        "each entry interpolated linearly between the two neighbours; below the first "
        "the first law, above the last the last (clamped: the schedule was designed and "
        "checked within that range only)."
    )
    if isinstance(schedule, SpeedCurrentSchedule):
        (low, high), (first, last) = schedule.covered
        return (
            f"omega_e, the electrical speed, rad/s, and i_q* = w[2], A, select the law: K, "
            f"K_i, U and X are tables over {schedule.current.size} q-axis current references "
            f"from {first:.9g} to {last:.9g} A (IQ_REF) times {schedule.electrical_speed.size} "
            f"speeds from {low:.9g} to {high:.9g} rad/s (OMEGA_E), each entry interpolated "
            "bilinearly between the four neighbours; outside either grid its first or last "
            "point's laws (clamped: the schedule was designed and checked within those "
            "ranges only)."
        )
    low, high = schedule.covered
    if isinstance(schedule, CurrentSchedule):
        return (
            "omega_e, the electrical speed, rad/s, is unused (no schedule over speed); "
            f"i_q* = w[2], A, selects the law: K, K_i, U and X are tables over "
            f"{schedule.grid.size} q-axis current references from {low:.9g} to {high:.9g} A "
            f"(IQ_REF), {clamped}"
        )
    return (
        f"omega_e, the electrical speed, rad/s, selects the law: K, K_i, U and X are "
        f"tables over {schedule.grid.size} speeds from {low:.9g} to {high:.9g} rad/s "
        f"(OMEGA_E), {clamped}"
    )


def _header(result: LawResult, u_max: float, source: str, version: str, date: str) -> str:
    law = _law(result)
    u_max_c = c_float(u_max, "--u-max")
    u_max_text = f"{float(np.float32(u_max)):.9g} V"
    h_c = c_float(result.h, "h") if result.h is not None else None
    members: list[str] = []
    if law.history:
        members.append(
            "    float past[SELFTUNE_HISTORY][2]; /* u_(k-d) .. u_(k-1), the voltages "
            "returned, oldest first, V */"
        )
    if law.r:
        members += [
            "    float z[SELFTUNE_INTEGRATORS]; /* the integrators, A s */",
        ]
    if not members:
        members.append("    char unused; /* the law keeps no state */")
    delay = "" if result.input_delay is None else (
        f"#define SELFTUNE_DELAY {result.input_delay} "
        "/* samples from computing a voltage to applying it (assumed) */\n"
    )  # fmt: skip
    period = "" if h_c is None else f"#define SELFTUNE_H {h_c} /* sampling period, s */\n"
    return (
        f"/* selftune_law.h: the digital current controller of {source}. */\n"
        + _banner(result, u_max_text, source, version, date)
        + "\n#ifndef SELFTUNE_LAW_H\n#define SELFTUNE_LAW_H\n\n"
        + period
        + delay
        + f"#define SELFTUNE_U_MAX {u_max_c} /* the limit on |u_dq|, V */\n"
        + f"#define SELFTUNE_HISTORY {law.history} /* d: past voltages fed back */\n"
        + f"#define SELFTUNE_INTEGRATORS {law.r} /* integrator states */\n"
        + ("" if result.schedule is None else grid_macros(result.schedule))
        + "\n/* Everything the law remembers between samples; set by selftune_init. */\n"
        + "struct selftune_state {\n"
        + "\n".join(members)
        + "\n};\ntypedef struct selftune_state selftune_state;\n\n"
        + "/* Set the state to rest: past voltages and integrators zero. */\n"
        + "void selftune_init(selftune_state *s);\n\n"
        + "/* One sample: i_dq the measured currents, A; w the reference as in the JSON\n"
        + "   (see above); omega_e the electrical speed, rad/s; u_dq the voltage to\n"
        + "   apply, V (|u_dq| <= SELFTUNE_U_MAX). */\n"
        + f"void selftune_step(selftune_state *s, const float i_dq[2], const float w[{law.q}],\n"
        + "                   float omega_e, float u_dq[2]);\n\n"
        + "#endif /* SELFTUNE_LAW_H */\n"
    )


def _init_body(law: ControlLaw) -> list[str]:
    if not law.history and not law.r:
        return ["    s->unused = 0;"]
    body = ["    int i;" if not law.history else "    int i, j;", ""]
    if law.history:
        body += [
            "    for (j = 0; j < SELFTUNE_HISTORY; ++j) {",
            "        for (i = 0; i < 2; ++i) {",
            "            s->past[j][i] = 0.0f;",
            "        }",
            "    }",
        ]
    if law.r:
        body += [
            "    for (i = 0; i < SELFTUNE_INTEGRATORS; ++i) {",
            "        s->z[i] = 0.0f;",
            "    }",
        ]
    return body


def _step_body(law: ControlLaw, schedule: Scheduled | None) -> list[str]:
    columns = law.K.shape[1]
    if schedule is not None:
        tables = f"U[2][{law.q}], X[2][{law.q}], K[2][{columns}]" + (
            "" if law.K_i is None else ", K_I[2][SELFTUNE_INTEGRATORS]"
        )
        call = schedule_call(schedule)
        unused = [] if "omega_e" in call else ["    (void)omega_e; /* no schedule over speed */"]
        speed = [
            f"    float {tables};",
            "    int i, j;",
            "",
            *unused,
            f"    /* the law at {call}: the tables interpolated (clamped at the ends) */",
            f"    selftune_schedule({call}, U, X, K" + (", K_I);" if law.K_i is not None else ");"),
        ]
    else:
        speed = ["    int i, j;", "", "    (void)omega_e; /* no schedule over speed */"]
    body = [
        f"    float u_e[2], deviation[{columns}], u[2], magnitude;",
        *speed,
        *(["    (void)s; /* the law keeps no state */"] if not (law.history or law.r) else []),
        "    /* u_e = U w; the deviations [x - X w; u_(k-d) - u_e; ...; u_(k-1) - u_e] */",
        "    for (i = 0; i < 2; ++i) {",
        f"        u_e[i] = {_dot('U', 'w', law.q)};",
        f"        deviation[i] = i_dq[i] - ({_dot('X', 'w', law.q)});",
        "    }",
    ]
    if law.history:
        body += [
            "    for (j = 0; j < SELFTUNE_HISTORY; ++j) {",
            "        for (i = 0; i < 2; ++i) {",
            "            deviation[2 + 2 * j + i] = s->past[j][i] - u_e[i];",
            "        }",
            "    }",
        ]
    body += [
        "    /* u = u_e - K deviation - K_i z */",
        "    for (i = 0; i < 2; ++i) {",
        "        u[i] = u_e[i];",
        f"        for (j = 0; j < {columns}; ++j) {{",
        "            u[i] -= K[i][j] * deviation[j];",
        "        }",
    ]
    if law.r:
        body += [
            "        for (j = 0; j < SELFTUNE_INTEGRATORS; ++j) {",
            "            u[i] -= K_I[i][j] * s->z[j];",
            "        }",
        ]
    body += [
        "    }",
        "    /* the voltage limit: a longer command scaled onto |u| = SELFTUNE_U_MAX */",
        "    magnitude = sqrtf(u[0] * u[0] + u[1] * u[1]);",
        "    if (!(magnitude <= SELFTUNE_U_MAX)) {",
        "        float scale = SELFTUNE_U_MAX / magnitude;",
        "",
        "        u[0] *= scale;",
        "        u[1] *= scale;",
    ]
    if law.r:
        body += [
            "    } else {",
            "        /* anti-windup: z += h (C x + F w) only where the limit did not act */",
            "        for (i = 0; i < SELFTUNE_INTEGRATORS; ++i) {",
            "            s->z[i] += SELFTUNE_H * (C[i][0] * i_dq[0] + C[i][1] * i_dq[1]",
            f"                                     + {_dot('F', 'w', law.q)});",
            "        }",
        ]
    body.append("    }")
    if law.history:
        body += [
            "    /* the voltages computed before, oldest first: drop u_(k-d), add u_k */",
            "    for (j = 0; j + 1 < SELFTUNE_HISTORY; ++j) {",
            "        s->past[j][0] = s->past[j + 1][0];",
            "        s->past[j][1] = s->past[j + 1][1];",
            "    }",
            "    s->past[SELFTUNE_HISTORY - 1][0] = u[0];",
            "    s->past[SELFTUNE_HISTORY - 1][1] = u[1];",
        ]
    body += ["    u_dq[0] = u[0];", "    u_dq[1] = u[1];"]
    return body


def _source(law: ControlLaw, key: str, schedule: Scheduled | None) -> str:
    state = ", ".join(law.state[: law.K.shape[1]])
    parts = [
        "/* selftune_law.c: the control law of selftune_law.h (generated; see there). */\n",
        '#include <math.h>\n\n#include "selftune_law.h"\n\n',
    ]
    if schedule is None:
        parts += [
            c_matrix("U", law.U, f"{key}.U", "U: feedforward map, u_e = U w (V per unit of w)"),
            "\n",
            c_matrix("X", law.X, f"{key}.X", "X: steady-state map, x_e = X w (A per unit of w)"),
            "\n",
            c_matrix("K", law.K, f"{key}.K", f"K: feedback on the deviations of [{state}]"),
        ]
        if law.K_i is not None:
            parts += [
                "\n",
                c_matrix("K_I", law.K_i, f"{key}.K_i", "K_i: integral gain, V/(A s)"),
            ]
    else:
        parts += schedule_tables(schedule, state)
    if law.K_i is not None and law.C is not None and law.F is not None:
        parts += [
            "\n",
            c_matrix("C", law.C, f"{key}.C", "C: the regulated error e = C x + F w"),
            "\n",
            c_matrix("F", law.F, f"{key}.F", "F: the regulated error's reference part"),
        ]
    parts += [
        "\nvoid selftune_init(selftune_state *s)\n{\n",
        "\n".join(_init_body(law)),
        "\n}\n\n",
        f"void selftune_step(selftune_state *s, const float i_dq[2], const float w[{law.q}],\n",
        "                   float omega_e, float u_dq[2])\n{\n",
        "\n".join(_step_body(law, schedule)),
        "\n}\n",
    ]
    return "".join(parts)


def firmware(result: LawResult, u_max: float, *, source: str, version: str, date: str) -> Firmware:
    """The law of ``result`` as C99 firmware with the voltage limit ``u_max``.

    Parameters
    ----------
    result : LawResult
        The law and what its file says of the drive (:func:`selftune.config.load_law_result`).
    u_max : float
        ``SELFTUNE_U_MAX``, the limit on ``|u_dq|``, V.
    source : str
        The JSON file's name, for the banner.
    version : str
        selftune's version, for the banner.
    date : str
        The date of the export, for the banner.

    Returns
    -------
    Firmware

    Raises
    ------
    InputError
        One line, if the law has a schedule over speed, does not fit the interface
        (n = m = 2), has integral action without h, or a number is no finite float32.
    """
    law = _check(result, source)
    limit = positive_finite(u_max, "--u-max")
    return Firmware(
        header=_header(result, limit, source, version, date),
        source=_source(law, result.key, result.schedule),
    )


def write_firmware(files: Firmware, out: str | os.PathLike[str]) -> Sequence[Path]:
    """Write the two files into ``out`` as one set (a previous export there is replaced).

    Parameters
    ----------
    files : Firmware
        The files.
    out : str or os.PathLike
        The directory: absent, empty, or a previous export.

    Returns
    -------
    list of Path
        The paths written, in the order of :data:`FIRMWARE_FILES`.
    """
    with output_directory(out, FIRMWARE_FILES, "selftune export output") as temporary:
        for name, text in files.files.items():
            write_text(temporary / name, text)
    return [Path(out) / name for name in FIRMWARE_FILES]
