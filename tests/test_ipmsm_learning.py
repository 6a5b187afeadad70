"""Identify-then-design with the interior PMSM's structure (R_s, L_d, L_q, flux): the
structure against the model's exact sampling and the surface structure, and learning
from a noisy log against the truth and the model-based digital optimum."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from selftune.learn import (
    IpmsmStructure,
    LearningOptions,
    LearningProblem,
    SpmsmStructure,
    Trajectory,
    learn_controller,
)
from selftune.model import IPMSM, solve_digital_regulation
from selftune.sim import held, simulate, uniform

HOLDS = ("rotor", "stationary")


@settings(max_examples=30, deadline=None)
@given(
    R_s=st.floats(1e-3, 5.0),
    L_d=st.floats(25e-6, 0.1),
    ratio=st.floats(0.5, 6.6),
    w_e=st.floats(-3000.0, 3000.0),
    hold=st.sampled_from(HOLDS),
)
def test_structure_is_the_motors_exact_sampling(
    R_s: float, L_d: float, ratio: float, w_e: float, hold: str
) -> None:
    """With kappa = 1 the structure is the model's sampled plant per unit of ``w_1 = w_e
    phi_pm`` (the model's own D): Ad, Bd, Ed all three columns."""
    motor = IPMSM(R_s=R_s, L_d=L_d, L_q=ratio * L_d, phi_pm=0.1, p=1)
    h = 1e-4
    structure = IpmsmStructure(w_e, h, hold=hold)  # type: ignore[arg-type]
    Ad, Bd, Ed = structure(np.array([R_s, motor.L_d, motor.L_q, 1.0]))
    truth = motor.sampled_plant(w_e, h, hold)
    for mine, theirs in zip((Ad, Bd, Ed), truth, strict=True):
        np.testing.assert_allclose(mine, theirs, rtol=1e-10, atol=1e-12 * np.abs(theirs).max())


@pytest.mark.parametrize("hold", HOLDS)
@pytest.mark.parametrize("dead_time", [False, True])
def test_equal_inductances_are_the_surface_structure(hold: str, dead_time: bool) -> None:
    """L_d = L_q gives the surface structure's matrices (its closed forms), the interior
    form's extra reference column zero."""
    R_s, L_s, kappa, v = 0.3, 1.5e-3, 0.97, 2.5
    spmsm = SpmsmStructure(900.0, 1e-4, dead_time, hold)  # type: ignore[arg-type]
    ipmsm = IpmsmStructure(900.0, 1e-4, dead_time, hold)  # type: ignore[arg-type]
    surface = spmsm(np.array([R_s, L_s, kappa, v][: 4 if dead_time else 3]))
    interior = ipmsm(np.array([R_s, L_s, L_s, kappa, v][: 5 if dead_time else 4]))
    np.testing.assert_allclose(interior[0], surface[0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(interior[1], surface[1], rtol=1e-12, atol=1e-14)
    Ed_surface, Ed_interior = surface[2], interior[2]
    np.testing.assert_allclose(Ed_interior[:, 0], Ed_surface[:, 0], rtol=1e-12, atol=1e-14)
    assert np.all(Ed_interior[:, 1:3] == 0.0) and np.all(Ed_surface[:, 1] == 0.0)
    np.testing.assert_allclose(Ed_interior[:, 3:], Ed_surface[:, 2:], rtol=1e-12, atol=1e-14)
    assert IpmsmStructure.names(dead_time)[:3] == ("R_s", "L_d", "L_q")


def _log(motor: IPMSM, speed: float, seconds: float, noise: float, seed: int):  # type: ignore[no-untyped-def]
    """A log of the ideal (dq-hold, no delay) drive under a gentle feedback, the torque
    reference stepping and rippling so that ``[w_1, i_d*, i_q*]`` vary independently (the
    MTPA curve is not straight), with Gaussian noise on the logged currents (A rms)."""
    h = 1e-4
    problem = motor.regulation_problem(speed)
    w_1 = motor.exogenous(speed, 0.0)[0]

    def reference(t: np.ndarray) -> np.ndarray:
        steps = 0.3 * np.sign(np.sin(2 * np.pi * 20 * t))
        torque = 3.0 * (1.0 + steps + 0.2 * np.sin(2 * np.pi * 130 * t))
        currents = np.array([motor.current_reference(value) for value in torque])
        return np.column_stack([np.full_like(t, w_1), currents])

    K0 = 0.05 * np.diag([motor.L_d, motor.L_q]) / h
    data = simulate(
        problem.A, problem.B, D=problem.D, exogenous=held(reference), K=K0, X=-problem.F,
        U=np.zeros((2, 3)), exploration=uniform(2.0), h=h, num_samples=round(seconds / h),
        seed=seed,
    )  # fmt: skip
    x = data.x + np.random.default_rng(seed + 100).normal(0.0, noise, data.x.shape)
    known = (LearningProblem(1e3 * np.eye(2), np.eye(2), C=np.eye(2), F=problem.F), K0)
    return Trajectory(data.t, x, data.u, data.w), problem, known


@pytest.mark.parametrize(
    "motor",
    [
        IPMSM(R_s=0.2, L_d=2e-3, L_q=5e-3, phi_pm=0.1, p=4),
        IPMSM(R_s=0.05, L_d=1e-4, L_q=3e-4, phi_pm=0.01, p=7),
        IPMSM(R_s=2.0, L_d=0.03, L_q=0.06, phi_pm=0.5, p=2),
    ],
)
def test_interior_motor_is_identified_within_its_standard_errors(motor: IPMSM) -> None:
    """0.5 s at 10 kHz with 10 mA noise: R_s, L_d, L_q and the flux within 4 standard
    errors of the truth and within 0.5%, and the designed K within 4 of its standard
    errors of the model-based digital optimum."""
    speed = 100.0
    log, problem, known = _log(motor, speed, 0.5, 0.01, seed=1)
    options = LearningOptions(
        target="digital", method="identify", input_delay=0, structure="ipmsm",
        electrical_speed=motor.p * speed, voltage_hold="rotor",
    )  # fmt: skip
    learned = learn_controller(log, *known, options)
    estimate = learned.quality.motor
    assert estimate is not None and estimate.L_s is None
    for name in ("R_s", "L_d", "L_q", "phi_pm"):
        value, se, truth = (
            getattr(estimate, name),
            getattr(estimate, f"{name}_se"),
            getattr(motor, name),
        )
        assert abs(value - truth) <= 4.0 * se, (name, value, truth, se)
        if name != "R_s":
            assert abs(value - truth) <= 5e-3 * truth, (name, value, truth)
    optimum = solve_digital_regulation(problem, known[0].Q, known[0].R, 1e-4, input_delay=0)
    error = np.linalg.norm(learned.K - optimum.K) / np.linalg.norm(optimum.K)
    assert error <= 4.0 * learned.quality.K_relative_se + 1e-9


def test_learn_reads_the_interior_structure_from_the_config_and_reports_the_motor(  # type: ignore[no-untyped-def]
    tmp_path, capsys
) -> None:
    """``selftune learn`` with ``structure = "ipmsm"`` in CONFIG.toml: the log's three
    reference channels, the identified L_d and L_q printed and in the JSON (L_s null)."""
    from selftune.cli import main
    from selftune.learn import save_csv

    motor = IPMSM(R_s=0.2, L_d=2e-3, L_q=5e-3, phi_pm=0.1, p=4)
    log, _, known = _log(motor, 100.0, 0.5, 0.01, seed=1)
    save_csv(log, tmp_path / "log.csv")
    K0 = known[1]
    (tmp_path / "learn.toml").write_text(
        "[cost]\nQ = [[1000.0, 0.0], [0.0, 1000.0]]\nR = [[1.0, 0.0], [0.0, 1.0]]\n"
        f"[policy]\nK0 = [[{K0[0, 0]}, 0.0], [0.0, {K0[1, 1]}]]\n"
        "[regulation]\nC = [[1.0, 0.0], [0.0, 1.0]]\n"
        "E = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]\n"
        "F = [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]\n"
        '[learning]\ntarget = "digital"\nmethod = "identify"\nstructure = "ipmsm"\n'
        'electrical_speed = 400.0\nvoltage_hold = "rotor"\ninput_delay = 0\n'
    )
    out = tmp_path / "out.json"
    code = main([
        "learn", str(tmp_path / "log.csv"), "--config", str(tmp_path / "learn.toml"),
        "--json", str(out),
    ])  # fmt: skip
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "identified motor: R_s = " in printed.out and "L_q = " in printed.out
    estimate = json.loads(out.read_text())["quality"]["motor"]
    assert estimate["L_s"] is None
    for name in ("L_d", "L_q", "phi_pm"):
        truth = getattr(motor, name)
        assert abs(estimate[name] - truth) <= 4.0 * estimate[f"{name}_se"]
