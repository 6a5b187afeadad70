"""The interior PM motor: MTPA against a brute-force search, the dq model against its
Jacobian, the regulation form against its own equations and python-control, MOTOR.toml."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from selftune.config import load_motor_config
from selftune.errors import DataFileError, InputError
from selftune.model import IPMSM, SPMSM, motor_from_parameters, solve_optimal_regulation

control = pytest.importorskip("control")


def _motor(R_s: float, L_d: float, ratio: float, phi_pm: float, p: int) -> IPMSM:
    return IPMSM(R_s=R_s, L_d=L_d, L_q=ratio * L_d, phi_pm=phi_pm, p=p)


motors = st.builds(
    _motor,
    R_s=st.floats(1e-3, 5.0),
    L_d=st.floats(25e-6, 0.1),
    ratio=st.floats(0.5, 6.6),
    phi_pm=st.floats(1e-3, 1.0),
    p=st.integers(1, 20),
)


@settings(max_examples=60, deadline=None)
@given(motor=motors, share=st.floats(-3.0, 3.0))
def test_mtpa_gives_the_torque_with_the_least_current(motor: IPMSM, share: float) -> None:
    """The MTPA references give T* and no current angle of the same magnitude gives more
    torque (a dense scan of the angle, independent of the closed form)."""
    rated = 1.5 * motor.p * motor.phi_pm * 10.0  # 10 A of i_q's worth of torque
    torque = share * rated
    i_d, i_q = motor.current_reference(torque)
    assert float(motor.torque(i_q, i_d)) == pytest.approx(torque, rel=1e-12, abs=1e-12 * rated)
    magnitude = np.hypot(i_d, i_q)
    if magnitude == 0.0:
        assert torque == 0.0
        return
    beta = np.linspace(0.0, np.pi, 400001)
    best = np.max(np.abs(motor.torque(magnitude * np.sin(beta), magnitude * np.cos(beta))))
    # the scan's step changes the torque by at most (dT/dbeta^2) dbeta^2 / 2 near the top
    assert abs(torque) >= best * (1.0 - 1e-9)
    if motor.L_d < motor.L_q:
        assert i_d <= 0.0  # the reluctance torque is used by a negative d current


def test_surface_motor_asks_for_no_d_current() -> None:
    motor = IPMSM(R_s=0.5, L_d=1e-3, L_q=1e-3, phi_pm=0.05, p=3)
    surface = SPMSM(R_s=0.5, L_s=1e-3, phi_pm=0.05, p=3)
    np.testing.assert_allclose(motor.current_reference(2.0), surface.current_reference(2.0))


def test_a_surface_motors_interior_form_is_the_same_plant() -> None:
    """IPMSM.of: the surface motor's references, torque-mode matrices and sampled plant
    (Ad, Bd and the back-EMF channel; the interior form's references are the currents,
    not the torque) are its interior form's; an interior motor is returned as it is."""
    surface = SPMSM(R_s=0.5, L_s=1e-3, phi_pm=0.05, p=3, J=2e-4)
    interior = IPMSM.of(surface)
    assert (interior.L_d, interior.L_q, interior.J) == (1e-3, 1e-3, 2e-4)
    np.testing.assert_allclose(interior.current_reference(2.0), surface.current_reference(2.0))
    for mine, theirs in zip(interior.torque_mode(80.0), surface.torque_mode(80.0), strict=True):
        np.testing.assert_allclose(mine, theirs, rtol=1e-14)
    (Ad, Bd, Ed), (Ad_s, Bd_s, Ed_s) = (
        motor.sampled_plant(80.0, 1e-4, "stationary") for motor in (interior, surface)
    )
    np.testing.assert_allclose(Ad, Ad_s, rtol=1e-12)
    np.testing.assert_allclose(Bd, Bd_s, rtol=1e-12)
    np.testing.assert_allclose(Ed[:, 0], Ed_s[:, 0], rtol=1e-12)
    motor = IPMSM(R_s=0.2, L_d=2e-3, L_q=5e-3, phi_pm=0.1, p=4)
    assert IPMSM.of(motor) is motor


@settings(max_examples=40, deadline=None)
@given(motor=motors, speed=st.floats(-500.0, 500.0))
def test_torque_mode_is_the_jacobian_of_the_full_model(motor: IPMSM, speed: float) -> None:
    """A and B are the derivatives of the nonlinear model at a held speed (central
    differences, exact for a model linear in the currents and voltages)."""
    motor = IPMSM(motor.R_s, motor.L_d, motor.L_q, motor.phi_pm, motor.p, J=0.01)
    A, B = motor.torque_mode(speed)
    base = np.array([0.3, -0.2, speed])
    u0 = np.array([1.0, 2.0])
    for column in range(2):
        step = np.zeros(3)
        step[column] = 1e-3
        slope = (motor.full_model(base + step, u0) - motor.full_model(base - step, u0)) / 2e-3
        np.testing.assert_allclose(slope[:2], A[:, column], rtol=1e-7, atol=1e-7 * np.abs(A).max())
        du = np.zeros(2)
        du[column] = 1e-3
        slope = (motor.full_model(base, u0 + du) - motor.full_model(base, u0 - du)) / 2e-3
        np.testing.assert_allclose(slope[:2], B[:, column], rtol=1e-7, atol=1e-7 * np.abs(B).max())


@settings(max_examples=40, deadline=None)
@given(motor=motors, speed=st.floats(-300.0, 300.0), torque=st.floats(-20.0, 20.0))
def test_equilibrium_is_a_rest_point_of_the_full_model(
    motor: IPMSM, speed: float, torque: float
) -> None:
    motor = IPMSM(motor.R_s, motor.L_d, motor.L_q, motor.phi_pm, motor.p, J=0.01)
    x_e, u_e = motor.equilibrium(speed, torque)
    rates = motor.full_model([x_e[0], x_e[1], speed], u_e, load_torque=torque)
    scale = np.abs(u_e).max() / min(motor.L_d, motor.L_q) + 1.0
    np.testing.assert_allclose(rates[:2], 0.0, atol=1e-10 * scale)
    assert rates[2] == pytest.approx(0.0, abs=1e-9 * (abs(torque) + 1.0) / 0.01)


@settings(max_examples=25, deadline=None)
@given(motor=motors, speed=st.floats(1.0, 300.0), torque=st.floats(-20.0, 20.0))
def test_regulation_form_tracks_the_mtpa_point(motor: IPMSM, speed: float, torque: float) -> None:
    """The optimum's X* w and U* w are the closed-form equilibrium, and K* is
    python-control's LQR gain (SLICOT) of the same A, B."""
    Q, R = 1e3 * np.eye(2), np.eye(2)
    solution = solve_optimal_regulation(motor.regulation_problem(speed), Q, R)
    w = motor.exogenous(speed, torque)
    x_e, u_e = motor.equilibrium(speed, torque)
    # X is O(1) A per unit of w, solved to ~1e-11; its error scales with |w| (w_1 is volts)
    np.testing.assert_allclose(solution.X @ w, x_e, atol=1e-9 * (np.abs(w).max() + 1.0))
    np.testing.assert_allclose(solution.U @ w, u_e, rtol=1e-8, atol=1e-8 * (np.abs(u_e).max() + 1))
    A, B = motor.torque_mode(speed)
    K, _, _ = control.lqr(A, B, Q, R)
    np.testing.assert_allclose(solution.K, K, rtol=1e-6, atol=1e-8 * np.abs(K).max())


@pytest.mark.parametrize(
    ("values", "expected"),
    [
        ({"R_s": 0.2, "L_s": 1e-3, "phi_pm": 0.1, "p": 4}, SPMSM),
        ({"R_s": 0.2, "L_d": 1e-3, "L_q": 3e-3, "phi_pm": 0.1, "p": 4}, IPMSM),
        ({"R_s": 0.2, "L_d": 1e-3, "L_q": 1e-3, "phi_pm": 0.1, "p": 4}, SPMSM),
    ],
)
def test_motor_from_parameters(values: dict[str, float], expected: type) -> None:
    motor = motor_from_parameters(values)
    assert type(motor) is expected
    assert motor.L_d == values.get("L_d", values.get("L_s"))


def test_motor_from_parameters_names_what_is_missing() -> None:
    with pytest.raises(InputError, match=r"^L_q: missing"):
        motor_from_parameters({"R_s": 0.2, "L_d": 1e-3, "phi_pm": 0.1, "p": 4})


def _write(tmp_path, motor: str) -> str:  # type: ignore[no-untyped-def]
    path = tmp_path / "motor.toml"
    path.write_text(f"[motor]\n{motor}\n[operating_point]\nspeed = 100.0\ntorque = 5.0\n")
    return str(path)


def test_motor_file_takes_d_and_q_inductances(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = load_motor_config(
        _write(tmp_path, "R_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4")
    )
    assert isinstance(config.motor, IPMSM)
    assert (config.motor.L_d, config.motor.L_q) == (2e-3, 5e-3)
    w = config.exogenous()
    assert w.shape == (3,) and w[1] < 0.0  # MTPA: negative i_d*
    same = load_motor_config(
        _write(tmp_path, "R_s = 0.2\nL_d = 2e-3\nL_q = 2e-3\nphi_pm = 0.1\np = 4")
    )
    assert isinstance(same.motor, SPMSM) and same.motor.L_s == 2e-3


@pytest.mark.parametrize(
    ("motor", "message"),
    [
        ("R_s = 0.2\nL_s = 2e-3\nL_d = 2e-3\nphi_pm = 0.1\np = 4",
         r"\[motor\] L_d: give either L_s \(a surface motor\) or L_d and L_q"),
        ("R_s = 0.2\nL_d = 2e-3\nphi_pm = 0.1\np = 4",
         r"\[motor\] L_q: missing: an interior motor needs L_d and L_q"),
        ("R_s = 0.2\nL_d = 2e-3\nL_q = -1.0\nphi_pm = 0.1\np = 4", r"\[motor\] L_q: "),
        ("R_s = 0.2\nL_d = 2e-3\nL_q = 20.0\nphi_pm = 0.1\np = 4", r"\[motor\] L_q: "),
        ("R_s = 0.2\nphi_pm = 0.1\np = 4", r"\[motor\] L_s: "),
    ],
)  # fmt: skip
def test_motor_file_inductance_mistakes_name_the_key(tmp_path, motor: str, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(DataFileError, match=message):
        load_motor_config(_write(tmp_path, motor))


def test_solve_prints_the_interior_motor_and_tune_asks_for_a_drive(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    from selftune.cli import main

    path = _write(tmp_path, "R_s = 0.2\nL_d = 2e-3\nL_q = 5e-3\nphi_pm = 0.1\np = 4")
    assert main(["solve", "--motor", path]) == 0
    out = capsys.readouterr().out
    assert "L_d = 0.002 H, L_q = 0.005 H" in out and "i_d* (A, MTPA)" in out
    assert main(["tune", "--motor", path]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "an interior PM motor is commissioned on a realistic drive" in err[0]
