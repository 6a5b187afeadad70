"""A corpus of hostile inputs for the command line: every one ends cleanly.

Each case is a ``selftune`` command line with the files it reads, made in its own
directory. A user error must give exit code 2 and exactly one stderr line
``selftune: error: ...`` naming what is wrong, and leave the directory exactly as it
was (no partial or stale output); a valid input must succeed with nothing on stderr
and with the right numbers (checked against closed forms or the model-based optimum,
so a silent wrong answer fails). No case may print a traceback or hang.

The cases are generated: many malformed or extreme values for every key of MOTOR.toml
and CONFIG.toml, malformed CSV and NPZ files, clock offsets, special files (FIFOs,
``/dev/zero``, ``/dev/urandom``, directories, symbolic links to devices), zip bombs,
oversized files, bad output paths, argparse misuse, interrupts. Most run in-process
through :func:`selftune.cli.main`; those that could hang or exhaust memory run in a
subprocess with a timeout and a memory limit (``resource.setrlimit``), concurrently.
The sweep of bad configuration values is table-driven at the file readers
(:func:`~selftune.config.load_motor_config`, :func:`~selftune.config.load_learn_config`:
each value refused with a one-line error naming the file and the key), with one value
per key taken through the command line (its route: exit 2, that one line, nothing
left); the valid values of the sweep run through the command line, their numbers checked.

Run: ``python -m pytest tests/test_hostile.py -q -p no:cacheprovider`` (add
``-m "slow or not slow"`` for the subprocess cases, the interrupts and the successful
tune, marked slow).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import signal
import struct
import subprocess
import sys
import time
import zipfile
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import selftune
from selftune import commands
from selftune.bench import _report as bench_report
from selftune.cli import main
from selftune.config import load_learn_config, load_motor_config
from selftune.errors import DataFileError, InputError
from selftune.learn import Trajectory, save_trajectory, solve_regression
from selftune.learn.data._io import trajectory_dimensions
from selftune.learn.learners._regression import Regression
from selftune.sim import held, uniform

#: Memory and time allowed to a case run in a subprocess.
MEMORY_LIMIT = 1 << 30
TIMEOUT = 30.0

MOTOR = selftune.SPMSM.paper()
PROBLEM = MOTOR.regulation_problem(10.0)
OPTIMUM = selftune.solve_optimal_regulation(PROBLEM, 1e3 * np.eye(2), np.eye(2))

Files = Callable[[Path], None]


def _nothing(_: Path) -> None:
    pass


@dataclass(frozen=True)
class Case:
    """One command line and the files it reads; ``{d}`` in ``argv`` is its directory.

    Attributes
    ----------
    name : str
        The test id.
    argv : tuple of str
        The arguments of ``selftune``.
    files : callable
        Makes the inputs in the case's directory.
    ok : bool
        Whether the command must succeed (else: exit 2, one line).
    names : tuple of str
        What the error line must contain (``{d}`` is the directory).
    outputs : tuple of str
        The files a success adds to the directory (nothing else may appear).
    check : callable, optional
        Checks a success's numbers: ``check(directory, stdout)``.
    isolated : bool
        Run in a subprocess, with a timeout and a memory limit.
    either : bool
        A valid input that the computation may still refuse (data that do not fit it):
        success (checked) or a clean error naming ``names``.
    code : int
        The exit code of the error (2; 130 after an interrupt).
    """

    name: str
    argv: tuple[str, ...]
    files: Files = _nothing
    ok: bool = False
    names: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    check: Callable[[Path, str], None] | None = None
    isolated: bool = False
    either: bool = False
    code: int = field(default=2)


# -- the files ----------------------------------------------------------------------------

MOTOR_TABLES: dict[str, dict[str, str]] = {
    "motor": {"R_s": "0.439", "L_s": "0.0601", "phi_pm": "0.46", "p": "2"},
    "operating_point": {"speed": "10.0", "torque": "10.0"},
    "cost": {"Q": "[[1000.0, 0.0], [0.0, 1000.0]]", "R": "[[1.0, 0.0], [0.0, 1.0]]"},
    "learning": {},
}
LEARN_TABLES: dict[str, dict[str, str]] = {
    "cost": {"Q": "[[1000.0, 0.0], [0.0, 1000.0]]", "R": "[[1.0, 0.0], [0.0, 1.0]]"},
    "policy": {"K0": "[[62.83, 0.0], [0.0, 62.83]]"},
    "regulation": {
        "C": "[[1.0, 0.0], [0.0, 1.0]]",
        "E": "[[0.0, 0.0], [0.0, 0.0]]",
        "F": f"[[0.0, 0.0], [0.0, {float(PROBLEM.F[1, 1])!r}]]",
    },
    "learning": {},
}


def toml(tables: dict[str, dict[str, str]], **changes: str) -> str:
    """The tables as TOML text, with ``key=value`` changes (a key in any table)."""
    text = []
    for table, keys in tables.items():
        text.append(f"[{table}]")
        merged = dict(keys)
        for key, value in changes.items():
            if key in keys or _table_of(tables, key) == table:
                merged[key] = value
        text += [f"{key} = {value}" for key, value in merged.items()]
    return "\n".join(text) + "\n"


def _table_of(tables: dict[str, dict[str, str]], key: str) -> str:
    owners = (
        {"J": "motor"}
        | {k: "learning" for k in LEARNING_KEYS}
        | {k: "learning" for k in ("interval", "max_iterations", "tolerance")}
    )
    for table, keys in tables.items():
        if key in keys:
            return table
    return owners[key]


LEARNING_KEYS = (
    "h",
    "episode_length",
    "K0",
    "exploration",
    "input_hold",
    "interval",
    "max_iterations",
)


def writer(name: str, content: str | bytes) -> Files:
    def write(directory: Path) -> None:
        path = directory / name
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")

    return write


def both(*makers: Files) -> Files:
    def make(directory: Path) -> None:
        for maker in makers:
            maker(directory)

    return make


def paper_data() -> Trajectory:
    """Noise-free data of the paper's motor, as in the README (500 samples of 10 us)."""
    w = MOTOR.exogenous(10.0, 10.0)
    return selftune.simulate(
        PROBLEM.A,
        PROBLEM.B,
        D=PROBLEM.D,
        K=20 * np.pi * np.eye(2),
        exploration=uniform(1.0),
        exogenous=held(lambda t: w + np.column_stack([np.sin(1e3 * t), 0.1 * np.cos(3e3 * t)])),
        h=1e-5,
        num_samples=500,
        input_hold=2,
        seed=0,
    )


DATA = paper_data()


def csv_text(offset: float = 0.0, scale: float = 1.0, dtype: str = "f8") -> str:
    """The paper's data as CSV, the times ``t + offset`` (rounded to ``dtype``), every
    signal scaled by ``scale`` (the plant is linear: the same K and U)."""
    assert DATA.w is not None
    t, x, w = DATA.t, DATA.x * scale, DATA.w * scale
    u = np.vstack([DATA.u, DATA.u[-1:]]) * scale
    if w.shape[0] < t.shape[0]:
        w = np.vstack([w, w[-1:]])
    times = (t + offset).astype(dtype).astype(float)
    table = np.column_stack([times, x, u, w])
    return "t,x1,x2,u1,u2,w1,w2\n" + "".join(
        ",".join(map(repr, row)) + "\n" for row in table.tolist()
    )


def time_rule(offset: float, dtype: str = "f8") -> bool:
    """Whether times ``t + offset`` in ``dtype`` resolve the 10 us steps (the rule, from its
    definition: spacing at the largest time at most 1e-9 of the smallest step)."""
    t = (np.arange(501) * 1e-5 + offset).astype(dtype)
    spacing = float(np.spacing(np.max(np.abs(t))))
    return spacing <= 1e-9 * float(np.min(np.diff(t.astype(float))))


def npz_bytes(**arrays: Any) -> bytes:
    buffer = BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def paper_npz(**changes: Any) -> bytes:
    data = DATA
    arrays: dict[str, Any] = {"t": data.t, "x": data.x, "u": data.u, "w": data.w}
    arrays.update(changes)
    return npz_bytes(**{k: v for k, v in arrays.items() if v is not None})


def fifo(name: str) -> Files:
    return lambda directory: os.mkfifo(directory / name)


def symlink(name: str, target: str) -> Files:
    return lambda directory: os.symlink(target, directory / name)


def sparse(name: str, size: int, head: bytes = b"") -> Files:
    def make(directory: Path) -> None:
        with open(directory / name, "wb") as stream:
            stream.write(head)
            stream.truncate(size)

    return make


def readonly(name: str, content: str = "old") -> Files:
    def make(directory: Path) -> None:
        (directory / name).write_text(content)
        (directory / name).chmod(0o444)

    return make


def subdirectory(name: str, *entries: str) -> Files:
    def make(directory: Path) -> None:
        (directory / name).mkdir()
        for entry in entries:
            (directory / name / entry).write_text("x")

    return make


MOTOR_FILE = writer("motor.toml", toml(MOTOR_TABLES))
CONFIG_FILE = writer("config.toml", toml(LEARN_TABLES))
DATA_FILE = writer("data.csv", csv_text())


# -- checks of successes: closed forms and the model-based optimum ------------------------


def scalar_riccati(R_s: float, L_s: float, q: float, r: float) -> float:
    """K of Q = q I, R = r I: P = s I with -2 gamma s - s^2 / (r L_s^2) + q = 0."""
    gamma = R_s / L_s
    s = r * L_s**2 * (-gamma + np.sqrt(gamma**2 + q / (r * L_s**2)))
    return float(s / (r * L_s))


def solve_json(
    R_s: float = 0.439,
    L_s: float = 0.0601,
    phi_pm: float = 0.46,
    p: int = 2,
    speed: float = 10.0,
    torque: float = 10.0,
    q: float = 1e3,
    r: float = 1.0,
) -> Callable[[Path, str], None]:
    """Check solve's JSON (out.json or stdout) against eq. (3) and the scalar Riccati."""

    def check(directory: Path, stdout: str) -> None:
        path = directory / "out.json"
        data = json.loads(path.read_text() if path.exists() else stdout)
        motor = selftune.SPMSM(R_s=R_s, L_s=L_s, phi_pm=phi_pm, p=p)
        x_e, u_e = motor.equilibrium(speed, torque)
        for name, exact in (("x_e", x_e), ("u_e", u_e)):
            scale = max(1.0, float(np.max(np.abs(exact))))
            np.testing.assert_allclose(data[name], exact, rtol=1e-8, atol=1e-9 * scale)
        gain = scalar_riccati(R_s, L_s, q, r)
        np.testing.assert_allclose(np.diag(data["K"]), [gain, gain], rtol=1e-7)

    return check


def learned_optimum_for(**matrices: str) -> Callable[[Path, str], None]:
    """learn's JSON holds the model-based optimum of the paper's plant with the
    configuration's C, E, F (the data are noise-free), to the usual accuracy."""
    known = {"C": PROBLEM.C, "E": PROBLEM.E, "F": PROBLEM.F}
    known.update({k: np.array(json.loads(v)) for k, v in matrices.items() if k in known})
    problem = selftune.RegulationProblem(A=PROBLEM.A, B=PROBLEM.B, D=PROBLEM.D, **known)
    optimum = selftune.solve_optimal_regulation(problem, 1e3 * np.eye(2), np.eye(2))

    def check(directory: Path, stdout: str) -> None:
        data = json.loads((directory / "out.json").read_text())
        for name in ("K", "U"):
            learned, truth = np.array(data[name]), getattr(optimum, name)
            assert np.linalg.norm(learned - truth) < 1e-4 * np.linalg.norm(truth), name

    return check


learned_optimum = learned_optimum_for()


def tuned_optimum(directory: Path, stdout: str) -> None:
    match = re.search(r"\|\|K - K\*\|\| / \|\|K\*\|\| = (\S+),", stdout)
    assert match and float(match.group(1)) < 1e-4, stdout


# -- the corpus ---------------------------------------------------------------------------

SCALAR_VALUES = [
    "nan",
    "inf",
    "-inf",
    "0",
    "-1",
    "-0.0",
    "1e300",
    "-1e300",
    "1e-300",
    "5e-324",
    "1.7976931348623157e308",
    "'10'",
    "true",
    "[1.0]",
    "{}",
    "1979-05-27",
    "1" + "0" * 400,
]
MATRIX_VALUES = [
    "[[nan, 0.0], [0.0, 1.0]]",
    "[[inf, 0.0], [0.0, 1.0]]",
    "[[1e300, 0.0], [0.0, 1e300]]",
    "[[1e-300, 0.0], [0.0, 1e-300]]",
    "[[1.0, 2.0], [2.0, 1.0]]",
    "[[1.0, 0.5], [0.0, 1.0]]",
    "[[1.0, 0.0]]",
    "[[1.0, 0.0], [0.0]]",
    "[[1.0, 'a'], [0.0, 1.0]]",
    "[]",
    "[[]]",
    "[[1e13, 0.0], [0.0, 1.0]]",
    "1.0",
    "[[1" + "0" * 400 + ", 0.0], [0.0, 1.0]]",
]
#: Values among those that are valid, per key.
VALID = {
    "speed": {"0", "-1", "-0.0", "1e-300", "5e-324"},
    "torque": {"0", "-1", "-0.0", "1e-300", "5e-324"},
    **{key: {"[[1.0, 2.0], [2.0, 1.0]]", "[[1.0, 0.5], [0.0, 1.0]]"} for key in "K0 C E F".split()},
    "tolerance": {"1e-300", "5e-324"},
}


#: The keys of each file the sweep covers, and which of them hold matrices.
MOTOR_KEYS = (*MOTOR_TABLES["motor"], "J", "speed", "torque", "Q", "R", *LEARNING_KEYS)
MOTOR_MATRICES = ("Q", "R", "K0")
CONFIG_KEYS = ("Q", "R", "K0", "C", "E", "F", "interval", "max_iterations", "tolerance")
CONFIG_MATRICES = ("Q", "R", "K0", "C", "E", "F")


def swept(key: str, matrices: tuple[str, ...]) -> list[tuple[int, str, bool]]:
    """``(index, value, valid)`` of every malformed or extreme value of ``key``'s kind."""
    values = MATRIX_VALUES if key in matrices else SCALAR_VALUES
    return [(index, value, value in VALID.get(key, set())) for index, value in enumerate(values)]


def refused(key: str, matrices: tuple[str, ...]) -> list[tuple[int, str]]:
    """``(index, value)`` of the swept values ``key`` must refuse."""
    return [(index, value) for index, value, valid in swept(key, matrices) if not valid]


def config_key_named(key: str, value: str) -> str:
    """What a refusal of ``key = value`` in CONFIG.toml names: a one-row C is a valid C,
    then F (2x2) has the wrong shape."""
    return (
        "[regulation] F"
        if key == "C" and value == "[[1.0, 0.0]]"
        else f"[{_table_of(LEARN_TABLES, key)}] {key}"
    )


def motor_value_cases() -> Iterator[Case]:
    """MOTOR.toml through ``solve``: every valid value of the sweep (checked against the
    closed forms), and one refused value per key (the route of its error to the command
    line; :func:`test_the_motor_reader_refuses_every_bad_value` sweeps them all)."""
    for key in MOTOR_KEYS:
        table = _table_of(MOTOR_TABLES, key)
        bad = refused(key, MOTOR_MATRICES)[0]
        for index, value, valid in swept(key, MOTOR_MATRICES):
            if not valid and (index, value) != bad:
                continue
            speed = {"speed": float(value)} if valid and key == "speed" else {}
            torque = {"torque": float(value)} if valid and key == "torque" else {}
            yield Case(
                f"motor-{key}-{index}",
                ("solve", "--motor", "{d}/motor.toml", "--json", "{d}/out.json"),
                writer("motor.toml", toml(MOTOR_TABLES, **{key: value})),
                ok=valid,
                names=("{d}/motor.toml", f"[{table}] {key}"),
                outputs=("out.json",),
                check=solve_json(**speed, **torque) if valid else None,  # type: ignore[arg-type]
            )


def learn_value_cases() -> Iterator[Case]:
    """CONFIG.toml through ``learn``: every valid value of the sweep (learned right), and
    one refused value per key (the route of its error to the command line;
    :func:`test_the_learning_reader_refuses_every_bad_value` sweeps them all)."""
    for key in CONFIG_KEYS:
        bad = refused(key, CONFIG_MATRICES)[0]
        for index, value, valid in swept(key, CONFIG_MATRICES):
            if not valid and (index, value) != bad:
                continue
            # A valid config the data may not fit (another K0 or E): learned right, or a
            # clean error naming the data.
            either = valid and key in ("K0", "E")
            yield Case(
                f"config-{key}-{index}",
                ("learn", "{d}/data.csv", "--config", "{d}/config.toml", "--json", "{d}/out.json"),
                both(DATA_FILE, writer("config.toml", toml(LEARN_TABLES, **{key: value}))),
                ok=valid and not either,
                either=either,
                names=("{d}/data.csv",)
                if either
                else ("{d}/config.toml", config_key_named(key, value)),
                outputs=("out.json",),
                check=learned_optimum_for(**{key: value}) if valid else None,
            )


def corner_cases() -> Iterator[Case]:
    """The corners of the plausible ranges: solved right, or refused naming the key."""
    corners = {
        "R_s": (1e-6, 1e3),
        "L_s": (1e-7, 10.0),
        "phi_pm": (1e-5, 10.0),
        "p": (1, 100),
        "speed": (-1e5, 1e5),
        "torque": (-1e6, 1e6),
    }
    rng = np.random.default_rng(7)
    for index in range(40):
        values: dict[str, Any] = {k: v[rng.integers(2)] for k, v in corners.items()}
        if index % 3 == 0:
            values["speed"] = float(rng.uniform(-30.0, 30.0))
        motor, electrical = values["R_s"] ** 2 / values["L_s"], values["p"] * values["speed"]
        too_stiff = motor > 5e6
        too_fast = electrical**2 * values["L_s"] > 5e6
        text = toml(MOTOR_TABLES, **{k: repr(v) for k, v in values.items()})
        yield Case(
            f"corner-{index}",
            ("solve", "--motor", "{d}/motor.toml", "--json", "{d}/out.json"),
            writer("motor.toml", text),
            ok=not (too_stiff or too_fast),
            names=("{d}/motor.toml", "[motor] R_s" if too_stiff else "[operating_point] speed"),
            outputs=("out.json",),
            check=solve_json(**values),
        )


def structure_cases() -> Iterator[Case]:
    """Malformed TOML and tables."""
    solve = ("solve", "--motor", "{d}/motor.toml")
    base = toml(MOTOR_TABLES)
    texts = {
        "unknown-table": (base + "[costs]\nQ = 1\n", "costs: unknown table"),
        "unknown-key": (base.replace("L_s =", "Ls ="), "[motor] Ls: unknown key"),
        "key-outside": ("x = 1\n" + base, "x: a key outside any table"),
        "duplicate-key": (base.replace("p = 2", "p = 2\np = 3"), "not a valid TOML file"),
        "syntax": (base.replace("speed = 10.0", "speed = 10.0.0"), "not a valid TOML file"),
        "table-as-value": ("cost = 1\n" + base.split("[cost]")[0], "cost: must be a table"),
        "missing-motor": ("[cost]\n", "[motor]: missing table"),
        "empty": ("", "[motor]: missing table"),
        "missing-key": (base.replace("L_s = 0.0601\n", ""), "[motor] L_s: missing"),
        "deep": ("a = " + "[" * 5000 + "]" * 5000 + "\n", "nested too deeply"),
        "long-key": (base + "k" * 100000 + " = 1\n", "unknown key"),
        "nul": (base + "\0\n", "not a valid TOML file"),
        "newline-key": (base + '"a\\nb" = 1\n', "unknown key"),
        "learning-unknown": (base + "anything = 1\n", "[learning] anything"),
        "too-fast": (base.replace("speed = 10.0", "speed = 9000.0"), "speed"),
        "too-stiff": (base.replace("R_s = 0.439", "R_s = 600.0"), "[motor] R_s"),
        "weights-apart": (
            base.replace("R = [[1.0, 0.0], [0.0, 1.0]]", "R = [[1e-5, 0.0], [0.0, 1e-5]]").replace(
                "Q = [[1000.0, 0.0], [0.0, 1000.0]]", "Q = [[1e12, 0.0], [0.0, 1e12]]"
            ),
            "[cost] Q",
        ),
    }
    for name, (text, part) in texts.items():
        yield Case(f"toml-{name}", solve, writer("motor.toml", text), names=("{d}", part))
    raw = {
        "latin1": (base.encode() + b"# \xe9\n", "not UTF-8"),
        "utf16": (base.encode("utf-16"), "not a TOML file"),
        "binary": (bytes(range(256)), "not a TOML file"),
        "big": (b"# " + b"x" * (1 << 20) + b"\n" + base.encode(), "1048576 bytes"),
    }
    for name, (content, part) in raw.items():
        yield Case(f"toml-{name}", solve, writer("motor.toml", content), names=("{d}", part))
    check = solve_json()
    for name, content in {
        "bom": b"\xef\xbb\xbf" + base.encode(),
        "crlf": base.replace("\n", "\r\n").encode(),
        "whole-float-p": base.replace("p = 2", "p = 2.0").encode(),
    }.items():
        yield Case(
            f"toml-{name}",
            (*solve, "--json", "{d}/out.json"),
            writer("motor.toml", content),
            ok=True,
            outputs=("out.json",),
            check=check,
        )
    # [learning] rules across keys, checked by tune before it simulates anything
    tune = ("tune", "--motor", "{d}/motor.toml")
    for index, (changes, part) in enumerate(
        [
            ({"input_hold": "1000"}, "[learning] input_hold"),
            ({"input_hold": "1e6"}, "[learning] input_hold"),
            ({"interval": "600"}, "[learning] interval"),
            ({"h": "1e-8"}, "[learning] episode_length"),
            ({"episode_length": "100.0"}, "[learning] episode_length"),
            ({"episode_length": "1e-5"}, "[learning] episode_length"),
            ({"K0": "[[-100.0, 0.0], [0.0, -100.0]]"}, "K0 may not stabilize"),
            ({"K0": "[[-1e6, 0.0], [0.0, -1e6]]"}, "unstable"),
        ]
    ):
        yield Case(
            f"tune-learning-{index}",
            tune,
            writer("motor.toml", toml(MOTOR_TABLES, **changes)),
            names=("{d}/motor.toml", part),
        )
    yield Case(
        "tune-ok",
        (*tune, "--json", "{d}/out.json"),
        MOTOR_FILE,
        ok=True,
        outputs=("out.json",),
        check=tuned_optimum,
    )


def csv_cases() -> Iterator[Case]:
    """Malformed, extreme and offset CSV logs (``learn``)."""
    learn = ("learn", "{d}/data.csv", "--config", "{d}/config.toml", "--json", "{d}/out.json")
    good = csv_text()
    header, first, second, *rest = good.splitlines(keepends=True)
    broken = {
        "empty": "",
        "header-only": header,
        "one-row": header + first,
        "nan": header + first.replace(",", ",nan,", 1),
        "inf": header + first + second.replace(",", ",1e999,", 1),
        "beyond": header + first + second.replace(",", ",1e60,", 1),
        "text": header + first + second.replace(",", ",abc,", 1),
        "fields": header + first + "0.1,2\n",
        "decreasing": header + second + first + "".join(rest),
        "repeated": header + first + first + "".join(rest),
        "bad-header": good.replace("t,x1", "time,x1", 1),
        "channels": "t," + ",".join(f"x{i}" for i in range(1, 12)) + ",u1,u2\n0" + ",0" * 13,
        "binary": bytes(range(256)) * 4,
        "latin1": good.encode() + b"0,\xe9\n",
        "long-header": "t," + "x1" * 40000 + "\n",
        "blank-line": header + first + "\n" + second,
    }
    for name, text in broken.items():
        content = text if isinstance(text, bytes) else text.encode()
        yield Case(
            f"csv-{name}",
            learn,
            both(CONFIG_FILE, writer("data.csv", content)),
            names=("{d}/data.csv",),
        )
    for name, content in {
        "bom": b"\xef\xbb\xbf" + good.encode(),
        "crlf": good.replace("\n", "\r\n").encode(),
    }.items():
        yield Case(
            f"csv-{name}",
            learn,
            both(CONFIG_FILE, writer("data.csv", content)),
            ok=True,
            outputs=("out.json",),
            check=learned_optimum,
        )
    # Clock offsets: the right K, or refused because the times cannot resolve the steps.
    for offset in (0.0, 1.0, 10.0, 100.0, 1e3, 1e6, 1e9, -1e9, 1.7e9):
        ok = time_rule(offset)
        yield Case(
            f"csv-offset-{offset:g}",
            learn,
            both(CONFIG_FILE, writer("data.csv", csv_text(offset))),
            ok=ok,
            names=("{d}/data.csv", "Trajectory.t", "relative to the first sample"),
            outputs=("out.json",),
            check=learned_optimum,
        )
    for offset in (0.0, 2.0):  # float32 times: 2.4e-7 s apart at 2 s
        yield Case(
            f"csv-float32-{offset:g}",
            learn,
            both(CONFIG_FILE, writer("data.csv", csv_text(offset, dtype="f4"))),
            ok=time_rule(offset, "f4") and time_rule(offset),
            names=("{d}/data.csv",),
            outputs=("out.json",),
            check=learned_optimum,
        )
    # Huge and tiny values: the same K (the plant is linear), or a clean refusal.
    for scale in (1e40, 1e20, 1e-20, 1e-100, 1e-200, 1e-300):
        yield Case(
            f"csv-scale-{scale:g}",
            learn,
            both(CONFIG_FILE, writer("data.csv", csv_text(scale=scale))),
            either=True,
            names=("{d}/data.csv",),
            outputs=("out.json",),
            check=learned_optimum,
        )
    # Too many rows (counted before parsing) and too large a file (by its size).
    rows = (header + "0,0,0,0,0,0,0\n" * 1_000_001).encode()
    yield Case(
        "csv-rows",
        learn,
        both(CONFIG_FILE, writer("data.csv", rows)),
        names=("{d}/data.csv", "1000001 data rows", "1000000"),
    )
    yield Case(
        "csv-size",
        learn,
        both(CONFIG_FILE, sparse("data.csv", 300 << 20, header.encode())),
        names=("{d}/data.csv", "268435456 bytes"),
        isolated=True,
    )
    # The configuration is checked before any row is read: a typo in it is reported even
    # though the rows are broken too.
    yield Case(
        "config-before-rows",
        learn,
        both(
            writer(
                "config.toml", toml(LEARN_TABLES).replace("[learning]", "[learning]\nintervall = 3")
            ),
            writer("data.csv", header + "0,abc\n"),
        ),
        names=("{d}/config.toml", "[learning] intervall: unknown key", "interval?"),
    )
    yield Case(
        "config-shape-from-header",
        learn,
        both(CONFIG_FILE, writer("data.csv", "t,x1,u1,w1\n0,1,2,3\n")),
        names=("{d}/config.toml", "[regulation] C: must be a nx1 matrix, got 2x2"),
    )


def npz_cases() -> Iterator[Case]:
    """Malformed NPZ archives and zip bombs (``learn``)."""
    learn = ("learn", "{d}/data.npz", "--config", "{d}/config.toml", "--json", "{d}/out.json")
    data = DATA
    broken: dict[str, tuple[bytes, str]] = {
        "not-zip": (b"t,x1,u1\n0,1,2\n", "not an NPZ archive"),
        "empty": (b"", "not an NPZ archive"),
        "truncated": (paper_npz()[:-100], "not an NPZ archive"),
        "missing-u": (npz_bytes(t=data.t, x=data.x), "missing array 'u'"),
        "extra": (paper_npz(y=data.t), "unexpected array 'y'"),
        "objects": (paper_npz(x=data.x.astype(object)), "allow_pickle"),
        "strings": (paper_npz(x=data.x.astype(str)), "dtype"),
        "complex": (paper_npz(u=data.u + 1j), "dtype"),
        "t-2d": (paper_npz(t=data.t[:, None]), "1-D"),
        "x-3d": (paper_npz(x=data.x[..., None]), "2-D"),
        "nan": (paper_npz(x=data.x * np.nan), "NaN"),
        "beyond": (paper_npz(u=data.u * 1e60), "beyond 1e+50"),
        "rows": (paper_npz(x=data.x[:-3]), "rows"),
        "float32-t": (paper_npz(t=(data.t + 2.0).astype(np.float32)), "float32"),
        "float16-t": (paper_npz(t=data.t.astype(np.float16)), "float16"),
        "offset-t": (paper_npz(t=data.t + 1e9), "relative to the first sample"),
        "channels": (paper_npz(x=np.zeros((501, 12))), "channels"),
        "no-channels": (paper_npz(x=np.zeros((501, 0))), "no channels"),
    }
    for name, (content, part) in broken.items():
        yield Case(
            f"npz-{name}",
            learn,
            both(CONFIG_FILE, writer("data.npz", content)),
            names=("{d}/data.npz", part),
        )
    yield Case(
        "npz-ok",
        learn,
        both(CONFIG_FILE, writer("data.npz", paper_npz())),
        ok=True,
        outputs=("out.json",),
        check=learned_optimum,
    )
    bombs = {
        "declared-size": (declared_size_bomb(), "bytes uncompressed"),
        "lying-size": (lying_size_bomb(), "cannot read"),
        "header-rows": (header_rows_bomb(), "rows; at most"),
        "directory": (directory_bomb(), "not an NPZ archive"),
    }
    for name, (content, part) in bombs.items():
        yield Case(
            f"npz-bomb-{name}",
            learn,
            both(CONFIG_FILE, writer("data.npz", content)),
            names=("{d}/data.npz", part),
            isolated=True,
        )


def _deflated(name: str, payload: bytes) -> bytes:
    buffer = BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for member in ("t", "u"):
            archive.writestr(f"{member}.npy", _npy(np.zeros(3)))
        archive.writestr(name, payload)
    return buffer.getvalue()


def _npy(array: np.ndarray) -> bytes:
    buffer = BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def _patch_sizes(raw: bytes, member: bytes, size: int) -> bytes:
    """Set ``member``'s uncompressed size in the zip's local and central headers."""
    patched = bytearray(raw)
    for signature, offset in ((b"PK\x03\x04", 22), (b"PK\x01\x02", 24)):
        at = patched.find(signature + b"")
        while at >= 0:
            name_at = at + (30 if signature == b"PK\x03\x04" else 46)
            if patched[name_at : name_at + len(member)] == member:
                patched[at + offset : at + offset + 4] = struct.pack("<I", size)
            at = patched.find(signature, at + 4)
    return bytes(patched)


def declared_size_bomb() -> bytes:
    """x.npy says (by the directory) it inflates to 3.9 GB: refused before decompressing."""
    return _patch_sizes(_deflated("x.npy", _npy(np.zeros((10, 2)))), b"x.npy", 0xF0000000)


def lying_size_bomb() -> bytes:
    """x.npy inflates to 64 MB but the directory says 200 bytes: read no further than that."""
    header = _npy(np.zeros((4_000_000, 2)))[:128]
    return _patch_sizes(_deflated("x.npy", header + bytes(64_000_000)), b"x.npy", 200)


def header_rows_bomb() -> bytes:
    """x.npy's header declares 1e12 rows (16 TB) over a few bytes of data."""
    stream = BytesIO()
    header = {"descr": "<f8", "fortran_order": False, "shape": (10**12, 2)}
    np.lib.format.write_array_header_1_0(stream, header)
    return _deflated("x.npy", stream.getvalue() + bytes(16))


def directory_bomb() -> bytes:
    """The end record says 60,000 members: refused before the directory is parsed."""
    raw = bytearray(paper_npz())
    at = raw.rfind(b"PK\x05\x06")
    raw[at + 8 : at + 12] = struct.pack("<HH", 60000, 60000)
    return bytes(raw)


def special_file_cases() -> Iterator[Case]:
    """FIFOs, devices, directories and links as inputs: refused at once, never read."""
    targets = {
        "fifo": fifo("in"),
        "dev-zero": symlink("in", "/dev/zero"),
        "dev-urandom": symlink("in", "/dev/urandom"),
        "dev-null": symlink("in", "/dev/null"),
        "directory": subdirectory("in"),
        "missing": _nothing,
        "loop": symlink("in", "in"),
    }
    for name, make in targets.items():
        for role, argv, extra in (
            ("motor", ("solve", "--motor", "{d}/in"), _nothing),
            ("tune", ("tune", "--motor", "{d}/in"), _nothing),
            ("data-csv", ("learn", "{d}/in.csv", "--config", "{d}/config.toml"), CONFIG_FILE),
            ("data-npz", ("learn", "{d}/in.npz", "--config", "{d}/config.toml"), CONFIG_FILE),
            ("config", ("learn", "{d}/data.csv", "--config", "{d}/in"), DATA_FILE),
        ):
            suffix = {"data-csv": ".csv", "data-npz": ".npz"}.get(role, "")
            # What could block or exhaust memory runs in a subprocess.
            isolated = name in ("fifo", "dev-zero", "dev-urandom")
            yield Case(
                f"special-{name}-{role}",
                argv,
                both(extra, _renamed(make, "in" + suffix)),
                names=(f"{{d}}/in{suffix}", "cannot read"),
                isolated=isolated,
            )
    yield Case(
        "special-dev-zero-direct",
        ("solve", "--motor", "/dev/zero"),
        names=("/dev/zero", "character device"),
        isolated=True,
    )
    yield Case(
        "special-dev-urandom-direct",
        ("learn", "/dev/urandom", "--config", "x.toml"),
        names=("/dev/urandom", "unknown file type"),
        isolated=True,
    )


def _renamed(make: Files, name: str) -> Files:
    def rename(directory: Path) -> None:
        make(directory)
        if name != "in" and os.path.lexists(directory / "in"):
            os.rename(directory / "in", directory / name)

    return rename


def output_cases() -> Iterator[Case]:
    """Output paths that must be refused before anything is computed."""
    solve = ("solve", "--json")
    paths: dict[str, tuple[str, Files, str]] = {
        "directory": ("{d}/out", subdirectory("out"), "directory"),
        "missing-directory": ("{d}/none/out.json", _nothing, "does not exist"),
        "under-a-file": ("{d}/file/out.json", writer("file", "x"), "cannot write the file"),
        "symlink": (
            "{d}/out.json",
            both(writer("real.json", "old"), symlink("out.json", "real.json")),
            "symbolic link",
        ),
        "symlink-dev-null": ("{d}/out.json", symlink("out.json", "/dev/null"), "symbolic link"),
        "dev-null": ("/dev/null", _nothing, "character device"),
        "dev-full": ("/dev/full", _nothing, "character device"),
        "fifo": ("{d}/out.json", fifo("out.json"), "FIFO"),
        "read-only": ("{d}/out.json", readonly("out.json"), "read-only"),
        "empty": ("", _nothing, "no file name"),
        "trailing-slash": ("{d}/out/", _nothing, "no file name"),
    }
    for name, (path, make, part) in paths.items():
        for command, argv, extra in (
            ("solve", solve, _nothing),
            (
                "learn",
                ("learn", "{d}/data.csv", "--config", "{d}/config.toml", "--json"),
                both(DATA_FILE, CONFIG_FILE),
            ),
            ("tune", ("tune", "--motor", "{d}/motor.toml", "--json"), MOTOR_FILE),
        ):
            yield Case(f"json-{name}-{command}", (*argv, path), both(extra, make), names=(part,))
    for command in ("reproduce", "bench"):
        dirs: dict[str, tuple[str, Files, str]] = {
            "file": ("{d}/out", writer("out", "x"), "a regular file, not a directory"),
            "foreign": ("{d}/out", subdirectory("out", "mine.txt"), "'mine.txt'"),
            "nested": ("{d}/out", subdirectory("out", "sub"), "'sub'"),
            "under-a-file": ("{d}/file/out", writer("file", "x"), "not a directory"),
            "symlink-file": (
                "{d}/out",
                both(writer("f", "x"), symlink("out", "f")),
                "not a directory",
            ),
            "dev-null": ("/dev/null", _nothing, "character device"),
            "empty": ("", _nothing, "no directory name"),
        }
        for name, (path, make, part) in dirs.items():
            yield Case(f"out-{command}-{name}", (command, "--out", path), make, names=(path, part))
    yield Case("json-stdout", ("solve", "--json", "-"), ok=True, check=solve_json())


def usage_cases() -> Iterator[Case]:
    """argparse misuse: one line, exit 2; negative numbers in any notation are values."""
    bad = [
        [],
        ["nonsense"],
        ["-x"],
        ["solve", "--speed"],
        ["solve", "--speed", "fast"],
        ["solve", "--speed", "nan"],
        ["solve", "--torque", "inf"],
        ["solve", "--speed", "-inf"],
        ["solve", "--speed", "1e309"],
        ["solve", "--unknown"],
        ["solve", "extra"],
        ["tune"],
        ["learn"],
        ["learn", "data.csv"],
        ["tune", "--motor", "m", "--algorithm", "4"],
        ["reproduce", "--seed", "-1"],
        ["reproduce", "--seed", "1e3"],
        ["reproduce", "--seed", "99999999999999"],
        ["tune", "--motor", "m", "--seed", "x"],
        ["bench", "--quick", "extra"],
        ["solve", "--json"],
        ["solve", "--motor"],
        ["solve", "--speed", "-1e9"],
        ["solve", "--torque", "-1e7"],
        ["solve", "--speed", "--torque"],
        ["solve", "--speed", "1", "--torque"],
    ]
    for index, argv in enumerate(bad):
        yield Case(f"usage-{index}", tuple(argv), names=("selftune: error: ",))
    for index, (speed, torque) in enumerate(
        [("-1e3", "10"), ("-.5", "-1.5E2"), ("-0", "-0.0"), ("1e1", "-3"), ("+20", "-1e-3")]
    ):
        yield Case(
            f"negative-{index}",
            ("solve", "--speed", speed, "--torque", torque, "--json", "-"),
            ok=True,
            check=solve_json(speed=float(speed), torque=float(torque)),
        )
    for argv in (["--help"], ["solve", "--help"], ["--version"]):
        yield Case(f"help-{'-'.join(argv)}", tuple(argv), ok=True)


CASES = [
    *motor_value_cases(),
    *learn_value_cases(),
    *corner_cases(),
    *structure_cases(),
    *csv_cases(),
    *npz_cases(),
    *special_file_cases(),
    *output_cases(),
    *usage_cases(),
]
IN_PROCESS = [case for case in CASES if not case.isolated]
ISOLATED = [case for case in CASES if case.isolated]
#: The isolated cases a plain ``pytest`` runs: one that would block (a FIFO) and one that
#: would exhaust memory (a zip bomb); the others are slow (each starts a Python process).
QUICK_ISOLATED = ("special-fifo-data-csv", "npz-bomb-lying-size")
#: The in-process cases a plain ``pytest`` leaves out: "tune-ok" learns for 4 s, and
#: tests/test_cli_tuning.py's test_tune_learns_the_optimum_of_the_motor_in_the_file[offpolicy]
#: runs the same command (the default algorithm) to its optimum, and checks its output.
SLOW_IN_PROCESS = ("tune-ok",)


# -- running ------------------------------------------------------------------------------


def snapshot(directory: Path) -> dict[str, tuple[int, int, int]]:
    """Every entry under ``directory`` (hidden ones too): mode, size, modification time."""
    entries = {}
    for root, dirs, files in os.walk(directory):
        for name in dirs + files:
            path = Path(root) / name
            info = os.lstat(path)
            entries[str(path.relative_to(directory))] = (
                info.st_mode,
                info.st_size,
                info.st_mtime_ns,
            )
    return entries


def expand(case: Case, directory: Path) -> list[str]:
    return [part.replace("{d}", str(directory)) for part in case.argv]


def run_in_process(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


# ``python -m selftune ARGS`` under a memory limit, set (resource.setrlimit) in the child
# itself before anything is imported: no preexec_fn, which is unsafe with threads.
_LIMITED = (
    "import resource, runpy, sys; "
    f"resource.setrlimit(resource.RLIMIT_AS, ({MEMORY_LIMIT}, {MEMORY_LIMIT})); "
    "sys.argv[0] = 'selftune'; "
    "runpy.run_module('selftune', run_name='__main__', alter_sys=True)"
)


def _start(argv: list[str], cwd: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    return subprocess.Popen(
        [sys.executable, "-c", _LIMITED, *argv],
        cwd=cwd,
        env=env,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def run_isolated(argv: list[str], cwd: Path) -> tuple[int, str, str]:
    """``python -m selftune argv`` with a memory limit; a timeout is a hang (code -1)."""
    process = _start(argv, cwd)
    try:
        out, err = process.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        return -1, out, "HANG: " + err
    return process.returncode, out, err


def verify(
    case: Case, directory: Path, before: dict[str, Any], result: tuple[int, str, str]
) -> None:
    """The case's outcome: one clean line and nothing changed, or a right success."""
    code, out, err = result
    assert code != -1, f"hang: {err}"
    assert "Traceback" not in err, err
    after = snapshot(directory)
    if case.ok:
        assert (code, err) == (0, ""), err
        added = sorted(set(after) - set(before))
        assert added == sorted(o for o in case.outputs if (directory / o).exists()), added
        assert all(after[k] == v for k, v in before.items())  # inputs untouched
        if case.check is not None:
            case.check(directory, out)
        return
    if case.either and code == 0:
        verify(
            Case(case.name, case.argv, ok=True, outputs=case.outputs, check=case.check),
            directory,
            before,
            result,
        )
        return
    lines = err.splitlines()
    assert code == case.code, (code, err)
    assert len(lines) == 1 and lines[0].startswith("selftune: error: "), err
    for part in case.names:
        assert part.replace("{d}", str(directory)) in lines[0], (part, lines[0])
    assert out == ""
    assert after == before, "a failed run changed its directory"


@pytest.mark.parametrize(
    "case",
    [
        pytest.param(
            case, id=case.name, marks=pytest.mark.slow if case.name in SLOW_IN_PROCESS else ()
        )
        for case in IN_PROCESS
    ],
)
def test_hostile_input_in_process(case: Case, tmp_path: Path) -> None:
    case.files(tmp_path)
    before = snapshot(tmp_path)
    verify(case, tmp_path, before, run_in_process(expand(case, tmp_path)))


# -- the value sweep at the readers: every bad value refused with one line naming its key ---


def assert_refused(read: Callable[[], object], names: tuple[str, ...], value: str) -> None:
    """``read()`` raises the one-line :class:`DataFileError` the command line prints,
    naming each of ``names``."""
    with pytest.raises(DataFileError) as raised:
        read()
    message = str(raised.value)
    assert "\n" not in message and message, (value, message)
    for part in names:
        assert part in message, (value, part, message)


@pytest.mark.parametrize("key", MOTOR_KEYS)
def test_the_motor_reader_refuses_every_bad_value(key: str, tmp_path: Path) -> None:
    """:func:`load_motor_config`, what ``solve`` and ``tune`` read MOTOR.toml with."""
    table = _table_of(MOTOR_TABLES, key)
    for index, value in refused(key, MOTOR_MATRICES):
        directory = tmp_path / str(index)
        directory.mkdir()
        writer("motor.toml", toml(MOTOR_TABLES, **{key: value}))(directory)
        path = directory / "motor.toml"
        assert_refused(partial(load_motor_config, path), (str(path), f"[{table}] {key}"), value)


@pytest.mark.parametrize("key", CONFIG_KEYS)
def test_the_learning_reader_refuses_every_bad_value(key: str, tmp_path: Path) -> None:
    """:func:`load_learn_config` with the data's dimensions, as ``learn`` reads CONFIG.toml."""
    DATA_FILE(tmp_path)
    dimensions = trajectory_dimensions(tmp_path / "data.csv")
    for index, value in refused(key, CONFIG_MATRICES):
        directory = tmp_path / str(index)
        directory.mkdir()
        writer("config.toml", toml(LEARN_TABLES, **{key: value}))(directory)
        path = directory / "config.toml"
        names = (str(path), config_key_named(key, value))
        assert_refused(partial(load_learn_config, path, *dimensions), names, value)


@pytest.fixture(scope="module")
def isolated_results(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[Path, dict[str, Any], tuple[int, str, str]]]:
    """Every isolated case the session runs (``-m``, ``-k``), run concurrently (each alone
    in its process)."""
    selected = {
        item.callspec.params["case"].name
        for item in request.session.items
        if isinstance(item, pytest.Function) and item.originalname == "test_hostile_input_isolated"
    }
    chosen = [case for case in ISOLATED if case.name in selected]
    prepared = {}
    for case in chosen:
        directory = tmp_path_factory.mktemp(case.name)
        case.files(directory)
        prepared[case.name] = (directory, snapshot(directory))
    with ThreadPoolExecutor(max_workers=4) as pool:
        futures = {
            case.name: pool.submit(
                run_isolated, expand(case, prepared[case.name][0]), prepared[case.name][0]
            )
            for case in chosen
        }
        return {name: (*prepared[name], future.result()) for name, future in futures.items()}


@pytest.mark.parametrize(
    "case",
    [
        pytest.param(
            case, id=case.name, marks=() if case.name in QUICK_ISOLATED else pytest.mark.slow
        )
        for case in ISOLATED
    ],
)
def test_hostile_input_isolated(
    case: Case, isolated_results: dict[str, tuple[Path, dict[str, Any], tuple[int, str, str]]]
) -> None:
    directory, before, result = isolated_results[case.name]
    verify(case, directory, before, result)


#: The bad values the readers are swept with: ``(file, key, index, value)``.
SWEEP = [
    *(("motor", key, *bad) for key in MOTOR_KEYS for bad in refused(key, MOTOR_MATRICES)),
    *(("config", key, *bad) for key in CONFIG_KEYS for bad in refused(key, CONFIG_MATRICES)),
]


def test_the_corpus_is_large() -> None:
    assert len(SWEEP) >= 350 and len(CASES) >= 250
    # every swept key has its route through the command line
    routes = {case.name.rsplit("-", 1)[0] for case in CASES if not (case.ok or case.either)}
    assert {f"{file}-{key}" for file, key, *_ in SWEEP} <= routes
    assert len({case.name for case in CASES}) == len(CASES)
    assert sum(case.ok for case in CASES) >= 30  # valid inputs are checked for right answers


# -- interrupts: one line, exit 130, nothing left -----------------------------------------


def _interrupted(process: subprocess.Popen[str]) -> None:
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=TIMEOUT)
    assert (process.returncode, err) == (130, "selftune: interrupted\n"), err


@pytest.mark.slow  # a whole reproduce in a subprocess; interrupted writes run in-process below
@pytest.mark.parametrize("previous", [False, True], ids=["new", "over-an-earlier-set"])
def test_ctrl_c_while_reproduce_writes_leaves_nothing(tmp_path: Path, previous: bool) -> None:
    """Interrupted while the figures are written (its temporary directory exists)."""
    if previous:  # an earlier output set, which must survive unchanged
        (tmp_path / "out").mkdir()
        for name in commands.REPRODUCE_OUTPUTS:
            (tmp_path / "out" / name).write_text("earlier run")
    before = snapshot(tmp_path)
    process = _start(["reproduce", "--out", str(tmp_path / "out")], tmp_path)
    deadline = time.monotonic() + TIMEOUT
    while not list(tmp_path.glob(".out.*.tmp")):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "the output was never written"
        time.sleep(0.005)
    _interrupted(process)
    assert snapshot(tmp_path) == before


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_ctrl_c_while_reproduce_computes(tmp_path: Path) -> None:
    """Interrupted while learning: after the imports (about 0.6 s of CPU) and before the
    figures (reproduce takes about 2.5 s of CPU); CPU time does not depend on the load."""
    before = snapshot(tmp_path)
    process = _start(["reproduce", "--out", str(tmp_path / "out")], tmp_path)
    deadline = time.monotonic() + TIMEOUT
    while _cpu_seconds(process.pid) < 1.3:
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "reproduce never got going"
        time.sleep(0.005)
    _interrupted(process)
    assert snapshot(tmp_path) == before


def test_ctrl_c_swallowed_by_a_callback_still_stops_the_command(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A SIGINT that lands in a weak-reference callback (matplotlib runs many while it
    draws) cannot propagate there; the command must stop all the same, before its output
    set is put in place, not finish and then say it was interrupted."""
    import weakref

    from selftune.core import write_text
    from selftune.core._atomic import output_directory

    class Drawn:
        pass

    def interrupted_callback(reference: object) -> None:
        raise KeyboardInterrupt

    def reproduce_command(out: str, seed: int) -> int:
        with output_directory(out, {"results.json"}, "reproduction") as directory:
            drawn = Drawn()
            reference = weakref.ref(drawn, interrupted_callback)
            del drawn  # the callback's KeyboardInterrupt goes to sys.unraisablehook
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:  # more work after the interrupt
                write_text(directory / "results.json", "{}")
            assert reference() is None
        return 0

    monkeypatch.setattr(commands, "reproduce_command", reproduce_command)
    assert main(["reproduce", "--out", str(tmp_path / "out")]) == 130
    assert snapshot(tmp_path) == {}


def test_ctrl_c_whose_keyboard_interrupt_was_lost_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """CPython can lose the KeyboardInterrupt (raised while a C function runs, replaced
    by that function's ValueError, then caught: seen in matplotlib's font matching); the
    output set is still not put in place."""
    from selftune.core import write_text
    from selftune.core._atomic import output_directory

    def reproduce_command(out: str, seed: int) -> int:
        with output_directory(out, {"results.json"}, "reproduction") as directory:
            write_text(directory / "partial.json", "{}")
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(1)  # the handler runs here
            except KeyboardInterrupt:
                pass  # lost
        return 0

    monkeypatch.setattr(commands, "reproduce_command", reproduce_command)
    assert main(["reproduce", "--out", str(tmp_path / "out")]) == 130
    assert snapshot(tmp_path) == {}


def test_ctrl_c_while_the_command_line_starts_is_one_line() -> None:
    """A SIGINT while numpy is first imported (the bulk of a command's first second) ends
    the command with one line and exit code 130, not a traceback: importing the command
    line itself imports nothing heavy, so the interrupt lands inside its handling."""
    code = (
        "import os, signal, sys\n"
        "class InterruptAtNumpy:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'numpy':\n"
        "            os.kill(os.getpid(), signal.SIGINT)\n"
        "        return None\n"
        "sys.meta_path.insert(0, InterruptAtNumpy())\n"
        "from selftune.cli import main\n"
        "sys.argv = ['selftune', 'solve']\n"
        "sys.exit(main())\n"
    )
    process = subprocess.Popen(
        [sys.executable, "-c", code], text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    _, err = process.communicate(timeout=TIMEOUT)
    assert (process.returncode, err) == (130, "selftune: interrupted\n"), err


# -- output sets: written whole or not at all ---------------------------------------------


def _set(directory: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in sorted(directory.iterdir())}


def test_reproduce_replaces_an_earlier_set_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, reproduction: Any, quick_figures: list[str]
) -> None:
    import dataclasses

    import selftune.report

    out = tmp_path / "out"
    runs = iter([reproduction, dataclasses.replace(reproduction, wall_seconds=123.0)])
    monkeypatch.setattr(selftune.report, "reproduce", lambda seed, step: next(runs))
    assert run_in_process(["reproduce", "--out", str(out)])[0] == 0
    first = _set(out)
    assert sorted(first) == sorted(commands.REPRODUCE_OUTPUTS)
    code, _, err = run_in_process(["reproduce", "--out", str(out), "--seed", "1"])
    assert (code, err) == (0, "")
    second = _set(out)
    assert sorted(second) == sorted(first)
    assert json.loads(second["results.json"])["wall_seconds"] == 123.0
    assert sorted(path.name for path in tmp_path.iterdir()) == ["out"]  # nothing beside


@pytest.mark.parametrize("earlier", [False, True], ids=["new", "over-an-earlier-set"])
def test_a_failed_reproduce_leaves_no_partial_set(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    reproduction: Any,
    quick_figures: list[str],
    earlier: bool,
) -> None:
    import selftune.report
    from selftune.report import _figures

    out = tmp_path / "out"
    monkeypatch.setattr(selftune.report, "reproduce", lambda seed, step: reproduction)
    if earlier:
        assert run_in_process(["reproduce", "--out", str(out)])[0] == 0
    before = snapshot(tmp_path)
    save_figure, calls = _figures.save_figure, []

    def failing(figure: Any, stem: Any) -> list[Path]:
        calls.append(stem)
        if len(calls) == 3:  # fig1 and fig2 are written, then the disk is full
            raise OSError(28, "No space left on device")
        return save_figure(figure, stem)

    monkeypatch.setattr(_figures, "save_figure", failing)
    code, _, err = run_in_process(["reproduce", "--out", str(out)])
    assert code == 2 and err == "selftune: error: No space left on device\n", err
    assert snapshot(tmp_path) == before


class _Bench:
    """What bench_command needs of a BenchReport, instantly."""

    wall_seconds = 1.0

    def __init__(self, fail: bool = False) -> None:
        self.fail = fail

    def to_markdown(self) -> str:
        return "# selftune bench\n"

    def to_json(self) -> dict[str, Any]:
        if self.fail:
            raise OSError(28, "No space left on device")
        return {"quick": True}


@pytest.mark.parametrize("earlier", [False, True], ids=["new", "over-an-earlier-set"])
def test_bench_writes_both_files_or_neither(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, earlier: bool
) -> None:
    out = tmp_path / "out"
    if earlier:
        out.mkdir()
        (out / "bench.md").write_text("earlier")
        (out / "bench.json").write_text("{}")
    before = snapshot(tmp_path)
    monkeypatch.setattr(bench_report, "run_bench", lambda quick, progress: _Bench(fail=True))
    code, _, err = run_in_process(["bench", "--quick", "--out", str(out)])
    assert code == 2 and err.count("\n") == 1, err
    assert snapshot(tmp_path) == before
    monkeypatch.setattr(bench_report, "run_bench", lambda quick, progress: _Bench())
    assert run_in_process(["bench", "--quick", "--out", str(out)])[0] == 0
    assert _set(out) == {"bench.json": b'{\n  "quick": true\n}', "bench.md": b"# selftune bench\n"}
    assert sorted(path.name for path in tmp_path.iterdir()) == ["out"]


def test_bench_refuses_a_file_before_it_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def never(quick: bool, progress: bool) -> None:
        raise AssertionError("the bench ran")

    monkeypatch.setattr(bench_report, "run_bench", never)
    (tmp_path / "file").write_text("x")
    code, _, err = run_in_process(["bench", "--out", str(tmp_path / "file")])
    assert code == 2 and "not a directory" in err and err.count("\n") == 1


def test_json_to_standard_output_is_the_json_alone(tmp_path: Path) -> None:
    DATA_FILE(tmp_path)
    CONFIG_FILE(tmp_path)
    argv = ["learn", str(tmp_path / "data.csv"), "--config", str(tmp_path / "config.toml")]
    code, out, err = run_in_process([*argv, "--json", "-"])
    assert (code, err) == (0, "")
    assert set(json.loads(out)) >= {"K", "P", "B", "X", "U", "control_law", "quality", "iterations"}
    assert sorted(path.name for path in tmp_path.iterdir()) == ["config.toml", "data.csv"]


# -- temporaries a killed run left ---------------------------------------------------------


def _pid_of_a_finished_process() -> int:
    process = subprocess.Popen([sys.executable, "-c", "pass"])
    process.wait()
    return process.pid


def test_a_later_run_removes_the_temporaries_a_killed_run_left(tmp_path: Path) -> None:
    """SIGKILL while an output was written leaves its temporary beside it (nothing can
    catch SIGKILL); the next run writing the same output removes it, and leaves alone
    the temporary of a process that still runs (this one) and anything not named so."""
    from selftune.core import write_text
    from selftune.core._atomic import output_directory

    dead, alive = _pid_of_a_finished_process(), os.getpid()
    stale_set, live_set = (
        tmp_path / f".out.{dead}.k2f_9x0a.tmp",
        tmp_path / f".out.{alive}.q8z3.tmp",
    )
    stale_file, live_file = (
        tmp_path / f".log.csv.{dead}.ab1c.csv",
        tmp_path / f".log.csv.{alive}.zz.csv",
    )
    for directory in (stale_set, live_set):
        directory.mkdir()
        (directory / "results.json").write_text("half written")
    for file in (stale_file, live_file):
        file.write_text("half written")
    others = [tmp_path / f".out.{dead}.tmp", tmp_path / f".other.{dead}.k2f_9x0a.tmp"]
    for file in others:
        file.write_text("the user's")

    with output_directory(tmp_path / "out", {"results.json"}, "reproduction") as directory:
        write_text(directory / "results.json", "{}")
    write_text(tmp_path / "log.csv", "t\n0\n")

    assert not stale_set.exists() and not stale_file.exists()
    assert (live_set / "results.json").read_text() == "half written"
    assert live_file.read_text() == "half written"
    assert all(file.read_text() == "the user's" for file in others)
    assert (tmp_path / "out" / "results.json").read_text() == "{}"


@pytest.mark.parametrize("kind", ["directory", "file"])
def test_ctrl_c_just_as_the_temporary_is_created_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kind: str
) -> None:
    """A SIGINT right after the temporary was created (a directory made, a file's
    descriptor closed), before the writer holds its name, must not leave it behind."""
    from selftune.core._atomic import atomic_path, output_directory

    step = "mkdir" if kind == "directory" else "close"
    original = getattr(os, step)

    def then_interrupted(*args: Any, **kwargs: Any) -> Any:
        monkeypatch.setattr(os, step, original)
        result = original(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(1)  # the handler runs here
        return result

    monkeypatch.setattr(os, step, then_interrupted)
    # Python's own SIGINT handler, whatever the process inherited: a shell's background
    # job (`cmd &` without job control) starts with SIGINT ignored, and the test then
    # delivered nothing
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            if kind == "directory":
                with output_directory(tmp_path / "out", {"results.json"}, "reproduction"):
                    pass
            else:
                with atomic_path(tmp_path / "log.csv"):
                    pass
    finally:
        signal.signal(signal.SIGINT, inherited)
    assert snapshot(tmp_path) == {}


# -- the library: bad values are errors where they enter ----------------------------------


@pytest.mark.parametrize("offset", [1e3, 1e6, 1e9])
def test_a_clock_offset_the_times_cannot_resolve_is_refused(offset: float) -> None:
    with pytest.raises(InputError, match="relative to the first sample"):
        Trajectory(t=DATA.t + offset, x=DATA.x, u=DATA.u, w=DATA.w)


def test_times_are_relative_to_the_first_sample() -> None:
    shifted = Trajectory(t=DATA.t + 10.0, x=DATA.x, u=DATA.u, w=DATA.w)
    assert shifted.t[0] == 0.0
    np.testing.assert_allclose(shifted.t, DATA.t, atol=1e-14)


@pytest.mark.parametrize(("rounded", "step"), [("float32", 1e-5), ("float16", 1e-2)])
def test_times_rounded_to_a_narrow_type_are_refused(rounded: str, step: float) -> None:
    times = (2.0 + step * np.arange(100)).astype(rounded)
    for given in (times, times.astype(np.float64)):  # also when widened again on the way
        with pytest.raises(InputError, match=rounded):
            Trajectory(t=given, x=np.ones(100), u=np.ones(99))


def test_exactly_uniform_narrow_times_are_fine() -> None:
    t = np.arange(501) / 1024.0  # float32 numbers, but exactly 1/1024 s apart
    Trajectory(t=t, x=DATA.x, u=DATA.u, w=DATA.w)


@pytest.mark.parametrize("value", [1e200, np.inf, np.nan])
def test_a_regression_on_absurd_numbers_is_an_input_error(value: float) -> None:
    Psi = np.ones((20, 3)) + np.arange(60).reshape(20, 3) ** 2
    Psi[3, 1] = value
    problem = Regression(Psi=Psi, b=np.ones(20), block_sizes={"P": 3})
    with pytest.raises(InputError, match="absurdly large"):
        solve_regression(problem)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the library warns; the CLI refuses
@pytest.mark.parametrize("scale", [1e-300, 1e200])
def test_learning_from_absurd_data_is_an_error_or_right(scale: float) -> None:
    data = Trajectory(t=DATA.t, x=DATA.x * scale, u=DATA.u * scale, w=DATA.w * scale)  # type: ignore[operator]
    try:
        learned = selftune.learn_output_regulation(
            data,
            PROBLEM.C,
            PROBLEM.E,
            PROBLEM.F,
            1e3 * np.eye(2),
            np.eye(2),
            20 * np.pi * np.eye(2),
        )
    except selftune.SelftuneError:
        return
    assert np.linalg.norm(learned.K - OPTIMUM.K) < 1e-4 * np.linalg.norm(OPTIMUM.K)


def test_saving_keeps_relative_times(tmp_path: Path) -> None:
    shifted = Trajectory(t=DATA.t + 10.0, x=DATA.x, u=DATA.u, w=DATA.w)
    save_trajectory(shifted, tmp_path / "log.csv")
    assert (tmp_path / "log.csv").read_text().splitlines()[1].startswith("0.0,")


if __name__ == "__main__":  # the corpus's composition: python tests/test_hostile.py
    kinds = {
        "user errors (exit 2, one line, nothing changed)": [
            c for c in CASES if not c.ok and not c.either
        ],
        "valid inputs (exit 0, numbers checked)": [c for c in CASES if c.ok],
        "valid but possibly unfit inputs (checked, or a clean error)": [
            c for c in CASES if c.either
        ],
        "run in a subprocess (timeout, memory limit)": ISOLATED,
    }
    print(f"{len(SWEEP)} bad configuration values, each refused by its file's reader")
    print(f"{len(CASES)} generated command lines")
    for label, cases in kinds.items():
        print(f"  {len(cases):4d} {label}")


def test_a_cleanup_interrupted_runs_to_its_end_then_raises() -> None:
    """A KeyboardInterrupt that lands in a temporary's removal (a second Ctrl-C, or the
    one re-delivered after Python lost the first) does not stop the removal halfway: it
    is run again to its end, and the first interrupt raised after."""
    from selftune._interrupts import despite_interrupts

    calls: list[int] = []

    def removal() -> None:
        calls.append(1)
        if len(calls) < 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        despite_interrupts(removal)
    assert len(calls) == 3
    done: list[int] = []
    despite_interrupts(lambda: done.append(1))
    assert done == [1]
