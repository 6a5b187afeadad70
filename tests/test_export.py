"""selftune export: the C law runs sample for sample with the drive's own, in float32.

The C code is compiled with the system compiler (``cc``; the tests that need it skip
with a message where there is none) and called through ctypes. The reference is the
project's own execution of the law: the stepper every simulated drive runs
(:func:`selftune.sim._stepper.run_closed_loop`), with the voltage limit and the
anti-windup of :mod:`selftune.core._voltage_limit`, on the realistic drive's closed loops
(whose logged measurements the C law is fed: the loop opened for an exact comparison).

The agreement is bounded by the float32 rounding of each sample's arithmetic (see
:func:`rounding_bound`): the C law computes in float32 what the reference computes in
float64, so the difference is a few float32 roundings (2**-24 relative) of the largest
terms the law adds, plus those the integrators accumulate.
"""

from __future__ import annotations

import ctypes
import json
import re
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from selftune.bench._online import ONLINE_MOTORS
from selftune.cli import main
from selftune.config import load_law_result
from selftune.core import Array, ControlLaw, to_jsonable
from selftune.core._voltage_limit import limit_magnitude
from selftune.learn import LearningProblem
from selftune.model import SPMSM, solve_digital_regulation
from selftune.report import FIRMWARE_FILES, firmware
from selftune.sim import DriveRecord, DriveSettings, RealisticDrive, steps
from selftune.sim._stepper import feedback_of, run_closed_loop

COMPILER = shutil.which("cc")
needs_compiler = pytest.mark.skipif(
    COMPILER is None, reason="no C compiler (cc) on this machine: the exported C is not run"
)

#: How the tests compile the law: strict C99, every warning an error, float32 kept.
FLAGS = (
    "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic",
    "-Wconversion", "-Wdouble-promotion", "-Wshadow", "-Wstrict-prototypes",
)  # fmt: skip

#: float32's unit roundoff.
EPS32 = 2.0**-24

H = 1e-4
SAMPLES = 100_000

#: A caller of the two functions that runs a whole recorded sequence in one call.
HARNESS = """
#include <stddef.h>
#include "selftune_law.h"

size_t harness_state_size(void) { return sizeof(selftune_state); }

void harness_run(selftune_state *s, long count, const float *i_dq, const float *w,
                 const float *omega_e, float *u_dq)
{
    long k;

    selftune_init(s);
    for (k = 0; k < count; ++k) {
        selftune_step(s, i_dq + 2 * k, w + HARNESS_Q * k, omega_e[k], u_dq + 2 * k);
    }
}
"""


def servo_law(motor: SPMSM, speed: float, delay: int = 1) -> ControlLaw:
    """The optimal digital servo law of ``motor`` on a realistic drive (stationary hold)."""
    problem = motor.regulation_problem(speed)
    Q, R = 1e3 * np.eye(2), np.eye(2)
    weight = LearningProblem(Q=Q, R=R, C=problem.C, F=problem.F, integral_action=True)
    return solve_digital_regulation(
        problem, Q, R, H, input_delay=delay, integral_weight=weight.integral_weight,
        plant=motor.sampled_plant(speed, H, "stationary"),
    ).law  # fmt: skip


def write_result(path: Path, law: ControlLaw, **extra: object) -> Path:
    """A JSON result as ``selftune learn`` writes it: the law, h and the delay."""
    document = {"control_law": law.document(), "h": H, "input_delay": law.history, **extra}
    path.write_text(json.dumps(to_jsonable(document)))
    return path


class CompiledLaw:
    """The exported C law of a JSON result, compiled and loaded."""

    def __init__(self, result: Path, u_max: float, directory: Path) -> None:
        files = firmware(
            load_law_result(result), u_max, source=result.name, version="test", date="today"
        )
        for name, text in files.files.items():
            (directory / name).write_text(text)
        q = load_law_result(result).law.q
        (directory / "harness.c").write_text(f"#define HARNESS_Q {q}\n" + HARNESS)
        library = directory / "libselftune_law.so"
        sources = [str(directory / "selftune_law.c"), str(directory / "harness.c")]
        compiled = subprocess.run(
            [str(COMPILER), *FLAGS, "-shared", "-fPIC", "-o", str(library), *sources, "-lm"],
            capture_output=True, text=True,
        )  # fmt: skip
        assert compiled.returncode == 0, compiled.stderr
        self.files = files
        self.library = library
        self.lib = ctypes.CDLL(str(library))
        self.lib.harness_state_size.restype = ctypes.c_size_t

    def run(self, x: Array, w: Array, omega_e: Array) -> Array:
        """The voltages the C law returns from rest, fed ``x`` (N, 2), ``w`` (N, q) and
        ``omega_e`` (N,) as float32."""
        count = x.shape[0]
        single = [np.ascontiguousarray(a, dtype=np.float32) for a in (x, w, omega_e)]
        u = np.zeros((count, 2), dtype=np.float32)
        state = ctypes.create_string_buffer(self.lib.harness_state_size())
        pointer = ctypes.POINTER(ctypes.c_float)
        self.lib.harness_run(
            state, ctypes.c_long(count), *(a.ctypes.data_as(pointer) for a in single),
            u.ctypes.data_as(pointer),
        )  # fmt: skip
        return u.astype(float)


class Replay:
    """Recorded measurements as the stepper's plant: the law's loop opened."""

    def __init__(self, x: Array) -> None:
        self.x = x

    def measure(self, k: int) -> Array:
        return self.x[np.newaxis, min(k, self.x.shape[0] - 1)]

    def advance(self, k: int, applied: Array, computed_at: int) -> None:
        pass


def stepper_commands(law: ControlLaw, x: Array, w: Array, u_max: float) -> Array:
    """The project's law execution (the drives' stepper, limited, with anti-windup) on
    the measurements ``x`` and references ``w``: the commands it computes (N, 2)."""
    count = x.shape[0]
    loop = run_closed_loop(
        Replay(x), feedback_of([law]), w[np.newaxis], np.zeros((1, count, 2)), 0,
        limit=lambda u: limit_magnitude(u, u_max), anti_windup=True,
    )  # fmt: skip
    return loop.computed[0]


def rounding_bound(law: ControlLaw, x: Array, w: Array, u: Array, u_max: float) -> Array:
    """A bound on ``|u_C - u|`` at each sample from float32 rounding (V), for the law
    fed ``x``, ``w`` whose float64 commands are ``u`` (limited).

    Each sample's command is a sum of ``c = columns + r + q + 8`` rounded operations
    (the inputs', the gains', the products', the sums', the limit's), so it is off by at
    most ``c eps |terms|``, ``|terms|`` the sum of the magnitudes the law adds:
    ``|U||w| + |K| [|x| + |X||w|; |u_past| + |U||w|] + |K_i||z|``. The integrators
    accumulate ``9 eps h (|C||x| + |F||w|) + eps |z|`` per sample they integrate, which
    ``|K_i|`` carries into the command; and the past voltages the law feeds back carry
    their own error through ``K``'s columns on them.
    """
    count, history = x.shape[0], law.history
    A = np.abs
    past = [np.vstack([np.zeros((lag, 2)), u[: count - lag]]) for lag in range(history, 0, -1)]
    steady = A(w) @ A(law.U).T
    deviation = np.hstack([A(x) + A(w) @ A(law.X).T, *(A(p) + steady for p in past)])
    terms = steady + deviation @ A(law.K).T
    carried = np.zeros(count)
    if law.K_i is not None and law.C is not None and law.F is not None:
        held = np.hypot(u[:, 0], u[:, 1]) >= u_max * (1.0 - 1e-12)
        e = x @ law.C.T + w @ law.F.T
        z = np.vstack([np.zeros((1, law.r)), np.cumsum(H * e * ~held[:, np.newaxis], axis=0)])
        terms = terms + A(z[:-1]) @ A(law.K_i).T
        size = H * (A(x) @ A(law.C).T + A(w) @ A(law.F).T)
        step = (9.0 * size + A(z[1:])) * ~held[:, np.newaxis]
        lost = np.vstack([np.zeros((1, law.r)), np.cumsum(step, axis=0)])[:-1]
        carried = np.max(lost @ A(law.K_i).T, axis=1) * EPS32
    columns = law.K.shape[1] + law.r + law.q + 8
    local = columns * EPS32 * np.max(terms, axis=1) + carried
    feedback = [np.max(np.sum(A(law.K[:, law.n + 2 * j : law.n + 2 * j + 2]), axis=1))
                for j in range(history)]  # fmt: skip
    bound = np.empty(count)
    for k in range(count):
        bound[k] = local[k] + sum(
            feedback[j] * bound[k - history + j] for j in range(history) if k - history + j >= 0
        )
    return bound


#: The three motors (the online study's: a servo at 1,200 rad/s, a medium and a large
#: one, at their speeds and rated torques), and the torque levels of the steps, as
#: fractions of twice the rated torque.
MOTORS = [(motor, speed) for _, motor, speed, *_ in ONLINE_MOTORS]
RATED = [torque for *_, torque, _, _ in ONLINE_MOTORS]
LEVELS = (0.0, 1.0, -1.0, 0.5, 1.0, 0.0, -1.0, 0.25, 1.0, -0.5)


def u_max_for(law: ControlLaw, motor: SPMSM, speed: float, torque: float) -> float:
    """The drive's limit: 1.25 times the steady voltage ``|U w|`` at ``torque`` (V), so
    that a step to it takes the voltage to the limit for some samples."""
    return float(1.25 * np.linalg.norm(law.U @ motor.exogenous(speed, torque)))


@pytest.fixture(scope="module")
def drives(
    tmp_path_factory: pytest.TempPathFactory,
) -> list[tuple[ControlLaw, Path, DriveRecord, float]]:
    """Each motor's law, its JSON result and a 10^5-sample closed loop of the realistic
    drive (noise, one-sample delay, the DC-bus limit, anti-windup) under torque steps
    every second that take the voltage to its limit (25 s of CPU for the three)."""
    directory = tmp_path_factory.mktemp("results")
    cases = []
    times = SAMPLES * H / len(LEVELS) * np.arange(1, len(LEVELS))
    for index, ((motor, speed), rated) in enumerate(zip(MOTORS, RATED, strict=True)):
        law = servo_law(motor, speed)
        u_max = u_max_for(law, motor, speed, 2.0 * rated)
        settings = DriveSettings(input_delay=1, dc_voltage=np.sqrt(3.0) * u_max,
                                 current_noise=0.01, anti_windup=True)  # fmt: skip
        reference = steps(times, [motor.exogenous(speed, 2.0 * level * rated) for level in LEVELS])
        record = RealisticDrive(motor, speed, H, settings).record(
            law, reference, num_samples=SAMPLES, exploration=None, seed=index
        )
        result = write_result(directory / f"motor{index}.json", law)
        cases.append((law, result, record, u_max))
    return cases


@pytest.mark.slow
@needs_compiler
def test_the_c_law_runs_sample_for_sample_with_the_drives_law(
    drives: list[tuple[ControlLaw, Path, DriveRecord, float]], tmp_path: Path
) -> None:
    """On three motors' realistic drives, 10^5 samples with saturating torque steps: fed
    the drive's measurements, the C law returns the drive's commands to float32
    rounding: within :func:`rounding_bound` at every sample (docs/export.md gives the
    figures measured)."""
    for index, ((motor, speed), (law, result, record, u_max)) in enumerate(
        zip(MOTORS, drives, strict=True)
    ):
        directory = tmp_path / f"motor{index}"
        directory.mkdir()
        compiled = CompiledLaw(result, u_max, directory)
        log = record.trajectory
        x, w = log.x[:SAMPLES], log.w[:SAMPLES]
        expected = record.commanded_voltages
        saturated = np.hypot(*expected.T) >= u_max * (1.0 - 1e-12)
        assert 5 <= np.sum(saturated) < SAMPLES // 100  # the steps do reach the limit
        # the drive's law is the stepper's on its own measurements
        np.testing.assert_allclose(stepper_commands(law, x, w, u_max), expected, atol=1e-9)
        u = compiled.run(x, w, np.full(SAMPLES, motor.p * speed))
        error = np.hypot(*(u - expected).T)
        bound = rounding_bound(law, x, w, expected, u_max)
        assert np.all(error <= bound), (index, int(np.argmax(error / bound)))
        worst, median = error.max() / u_max, np.median(error) / u_max
        print(f"motor {index}: |u_C - u| at most {worst:.2e} u_max, "
              f"{(error / bound).max():.2f} of the bound; median {median:.2e}")  # fmt: skip


@needs_compiler
def test_the_c_law_compiles_clean_and_calls_nothing_but_sqrtf(tmp_path: Path) -> None:
    motor, speed = MOTORS[0]
    result = write_result(tmp_path / "law.json", servo_law(motor, speed))
    compiled = CompiledLaw(result, 100.0, tmp_path)
    if shutil.which("nm") is None:
        pytest.skip("no nm on this machine: the library's symbols are not listed")
    listing = subprocess.run(
        ["nm", "-D", "--undefined-only", str(compiled.library)],
        check=True, capture_output=True, text=True,
    ).stdout  # fmt: skip
    called = {
        line.split()[-1].split("@")[0] for line in listing.splitlines() if line.split()[0] == "U"
    }
    assert called <= {"sqrtf"}, called
    source = compiled.files.source
    assert "malloc" not in source and "double" not in source
    assert re.findall(r"#include <([^>]+)>", source) == ["math.h"]


@needs_compiler
@pytest.mark.parametrize(
    ("history", "integral", "q"), [(0, False, 2), (1, False, 2), (2, True, 2), (1, True, 3)]
)
def test_every_form_of_the_law_runs_as_the_stepper_runs_it(
    history: int, integral: bool, q: int, tmp_path: Path
) -> None:
    """Laws with 0, 1 and 2 past voltages, with and without integrators, with 2 reference
    channels or 3 (an interior motor's [w_1, i_d*, i_q*]), on random measurements whose
    commands often exceed the limit: the C law is the stepper's."""
    # seeds whose integrators leave the limit acting at 1-90% of the samples
    rng = np.random.default_rng(history if q == 2 else 7)
    X = rng.normal(0, 1, (2, q))
    extra = {}
    if integral:  # e = x - X w: zero on average about the steady state
        extra = dict(K_i=rng.normal(0, 300.0, (2, 2)), C=np.eye(2), F=-X, h=H)
    law = ControlLaw(
        K=rng.normal(0, 5.0, (2, 2 + 2 * history)) * np.r_[np.ones(2), 0.05 * np.ones(2 * history)],
        X=X, U=rng.normal(0, 1, (2, q)), history=history, **extra,
    )  # fmt: skip
    result = write_result(tmp_path / "law.json", law)
    u_max = 20.0
    compiled = CompiledLaw(result, u_max, tmp_path)
    count = 20_000
    # |U w| as large with q channels as with 2: the limit acts about as often
    w = np.repeat(rng.normal(0, 10.0 * np.sqrt(2 / q), (count // 1000, q)), 1000, axis=0)
    x = w @ X.T + rng.normal(0, 2.0, (count, 2))
    expected = stepper_commands(law, x, w, u_max)
    assert 0.01 < np.mean(np.hypot(*expected.T) >= u_max * (1 - 1e-12)) < 0.9
    u = compiled.run(x, w, np.zeros(count))
    bound = rounding_bound(law, x, w, expected, u_max)
    assert np.all(np.hypot(*(u - expected).T) <= bound)


#: Samples of a step response: 50 ms at rest (settled), then 100 ms after the step.
STEP_SAMPLES = 1500


def step_response(
    law: ControlLaw, motor: SPMSM, speed: float, torque: float, u_max: float, anti_windup: bool
) -> tuple[float, int, DriveRecord]:
    """A torque step from 0 to ``torque`` at 50 ms on the realistic drive with the limit
    ``u_max``: the true i_q's relative overshoot, the samples at the limit after the step
    (the start from rest may reach it too), the record."""
    reference = steps([0.05], [motor.exogenous(speed, 0.0), motor.exogenous(speed, torque)])
    settings = DriveSettings(dc_voltage=np.sqrt(3.0) * u_max, anti_windup=anti_windup)
    record = RealisticDrive(motor, speed, H, settings).record(
        law, reference, num_samples=STEP_SAMPLES, exploration=None, seed=0
    )
    target = torque / (1.5 * motor.p * motor.phi_pm)
    overshoot = float(record.true_currents[500:, 1].max() / target - 1.0)
    at_limit = np.hypot(*record.commanded_voltages[500:].T) >= u_max * (1.0 - 1e-12)
    return overshoot, int(np.sum(at_limit)), record


def test_anti_windup_changes_nothing_where_the_limit_never_acts() -> None:
    """Below the limit the law with anti-windup is the law, bit for bit; at the limit it
    is not (the flag acts)."""
    (motor, speed), rated = MOTORS[1], RATED[1]
    law = servo_law(motor, speed)
    u_max = u_max_for(law, motor, speed, 2.0 * rated)
    for torque, differs in ((0.1 * rated, False), (2.0 * rated, True)):
        runs = [step_response(law, motor, speed, torque, u_max, flag)[2] for flag in (False, True)]
        same = np.array_equal(runs[0].commanded_voltages, runs[1].commanded_voltages)
        assert same is not differs


@needs_compiler
def test_anti_windup_keeps_a_saturated_steps_overshoot_within_the_linear_loops(
    tmp_path: Path,
) -> None:
    """A step to twice the rated torque, the limit 1.25 times its steady voltage: the
    voltage stays at the limit for 3 to 23 samples. The bound: the overshoot of the same
    law on a step small enough never to reach the limit (the linear loop's own,
    3.9-4.5%). With anti-windup the saturated step stays within it (0.13-1.6%);
    without, the integrators wind up and it overshoots beyond it (6.6-24%). The C law
    returns the anti-windup run's commands."""
    for index, ((motor, speed), rated) in enumerate(zip(MOTORS, RATED, strict=True)):
        law = servo_law(motor, speed)
        u_max = u_max_for(law, motor, speed, 2.0 * rated)
        linear, never, _ = step_response(law, motor, speed, 0.02 * rated, u_max, True)
        assert never == 0 and linear > 0.0
        clamped, limited, record = step_response(law, motor, speed, 2.0 * rated, u_max, True)
        wound, _, _ = step_response(law, motor, speed, 2.0 * rated, u_max, False)
        assert limited >= 2
        assert clamped <= linear < wound, (index, clamped, linear, wound)
        directory = tmp_path / f"motor{index}"
        directory.mkdir()
        compiled = CompiledLaw(write_result(directory / "law.json", law), u_max, directory)
        x, w, commands = (
            record.trajectory.x[:-1],
            record.trajectory.w[:-1],
            record.commanded_voltages,
        )
        u = compiled.run(x, w, np.full(STEP_SAMPLES, motor.p * speed))
        bound = rounding_bound(law, x, w, commands, u_max)
        assert np.all(np.hypot(*(u - commands).T) <= bound)
        print(f"motor {index}: overshoot linear {linear:.2%}, clamped {clamped:.2%} "
              f"({limited} samples at the limit), wound up {wound:.2%}")  # fmt: skip


def test_the_numbers_read_back_to_the_laws_float32(tmp_path: Path) -> None:
    motor, speed = MOTORS[0]
    law = servo_law(motor, speed)
    result = load_law_result(write_result(tmp_path / "law.json", law))
    source = firmware(result, 100.0, source="law.json", version="v", date="d").source
    for name, matrix in (("U", law.U), ("X", law.X), ("K", law.K), ("K_I", law.K_i)):
        block = re.search(rf"static const float {name}\[\d+\]\[\d+\] = \{{(.*?)\}};", source, re.S)
        assert block is not None, name
        numbers = [float(t[:-1]) for t in re.findall(r"-?[\d.]+(?:e[-+]\d+)?f", block[1])]
        assert np.array_equal(np.float32(numbers), np.float32(matrix).ravel()), name


def export(*args: str) -> int:
    return main(["export", *args])


def test_export_of_a_learned_law_states_what_its_file_says(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """learn, then export: the header names h, the delay, that the file names no motor,
    the limit given, the anti-windup and the state's order."""
    learned = tmp_path / "learned.json"
    assert main(["learn", "examples/data/drive_log.csv", "--config", "examples/data/learn.toml",
                 "--json", str(learned)]) == 0  # fmt: skip
    capsys.readouterr()
    out = tmp_path / "firmware"
    assert export(str(learned), "--out", str(out), "--u-max", "311.77") == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(FIRMWARE_FILES)
    header = (out / "selftune_law.h").read_text()
    for stated in ("Sampling period h: 0.0001 s", "Computation delay assumed: 1 sample",
                   "Motor: not stated in the file", "SELFTUNE_U_MAX = 311.769989 V",
                   "Anti-windup: integrator clamping", "x1 x2 u1[k-1] u2[k-1] z1 z2",
                   "from learned.json (control_law)", "#define SELFTUNE_DELAY 1"):  # fmt: skip
        assert stated in header, stated
    assert "wrote selftune_law.h, selftune_law.c" in capsys.readouterr().out
    # exported again over the first: replaced as one set
    assert export(str(learned), "--out", str(out), "--u-max", "100") == 0
    assert "SELFTUNE_U_MAX 100.0f" in (out / "selftune_law.h").read_text()


def test_export_takes_the_limit_and_the_motor_from_an_online_result(tmp_path: Path) -> None:
    motor, speed = MOTORS[2]
    law = servo_law(motor, speed)
    result = write_result(
        tmp_path / "online.json", law, motor=motor,
        drive={"input_delay": 1, "dc_voltage": 540.0},
    )  # fmt: skip
    assert export(str(result), "--out", str(tmp_path / "out")) == 0
    header = (tmp_path / "out" / "selftune_law.h").read_text()
    assert f"SELFTUNE_U_MAX {np.float32(540.0 / np.sqrt(3.0)):.9g}f" in header
    assert "Motor: R_s = 0.05 ohm, L_s = 0.0008 H, phi_pm = 0.25 Wb, p = 8" in header


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.pop("control_law"), "control_law: missing"),
        (lambda d: d.update(schedule={"electrical_speed": [0, 1]}), "schedule.K: missing"),
        (lambda d: d["control_law"]["K"][0].__setitem__(0, 1e39), "is not a finite float32"),
        (lambda d: d["control_law"]["K"][0].__setitem__(0, float("nan")), "control_law"),
        (  # three states: not a current loop
            lambda d: d["control_law"].update(
                K=[[0.0] * 5] * 2, X=[[0.0, 0.0]] * 3, C=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
            ),
            "(n, m) = (3, 2)",
        ),
    ],
)
def test_export_refuses_in_one_line_and_writes_nothing(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    change: Callable[[dict[str, object]], object],
    message: str,
) -> None:
    motor, speed = MOTORS[0]
    document = json.loads(json.dumps(to_jsonable(
        {"control_law": servo_law(motor, speed).document(), "h": H})))  # fmt: skip
    change(document)
    result = tmp_path / "result.json"
    result.write_text(json.dumps(document))
    out = tmp_path / "out"
    code = export(str(result), "--out", str(out), "--u-max", "100")
    error = capsys.readouterr().err
    assert code == 2 and message in error and error.count("\n") == 1, error
    assert not out.exists()


def test_export_refuses_a_missing_limit_and_a_foreign_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    motor, speed = MOTORS[0]
    result = write_result(tmp_path / "law.json", servo_law(motor, speed))
    assert export(str(result), "--out", str(tmp_path / "out")) == 2
    assert "--u-max: " in capsys.readouterr().err
    for bad in ("0", "-5", "inf"):
        assert export(str(result), "--out", str(tmp_path / "out"), "--u-max", bad) == 2
    assert not (tmp_path / "out").exists()
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    assert export(str(result), "--out", str(foreign), "--u-max", "100") == 2
    assert sorted(p.name for p in foreign.iterdir()) == ["notes.txt"]
