"""Magnetic saturation (:mod:`selftune.sim._saturation`) and the drive with it.

The analytic model against its own definition (reciprocity, the Hessian by finite
differences, the reduction to constant inductances), the flux-map table against the
analytic model it samples, the refusals, and the saturating drive against an independent
numerical integration (scipy's ``solve_ivp``, DOP853) of the same flux linkages over the
drive's own voltages, at low and at high current where ``L_q`` has fallen by 40 %.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.typing import NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from selftune.core import ControlLaw
from selftune.core._phases import to_phases
from selftune.errors import InputError
from selftune.model import IPMSM
from selftune.sim import (
    DriveRecord,
    DriveSettings,
    FluxMap,
    RealisticDrive,
    Saturation,
    SaturationModel,
    constant,
    run_drive_batch,
    uniform,
)
from selftune.sim._inverter import MotorBatch, phasor_mean
from selftune.sim._linear import stack_motors
from selftune.sim._pwm import carrier_segments
from selftune.sim._saturation import NARROWEST_KNEE, STEP_RATE

Array = NDArray[np.float64]
H = 1e-4  # 10 kHz
#: The interior motor of tests/test_salient_drive.py, L_q / L_d = 3.
MOTOR = IPMSM(R_s=0.2, L_d=2e-3, L_q=6e-3, phi_pm=0.05, p=4)
#: ``w_e h`` = 0.3 and 0.02 (mechanical rad/s).
HIGH_SPEED = 0.3 / (MOTOR.p * H)
LOW_SPEED = 0.02 / (MOTOR.p * H)
DROP, CROSS = 0.6, 0.1
LOW_CURRENT, HIGH_CURRENT = 2.0, 12.0


def fitted_scale() -> float:
    """``i_s`` making the secant ``L_q`` fall by 40 % from 2 A to 12 A (at ``i_d = 0``),
    as a measured 5.6 kW machine's does."""

    def ratio(i_sat: float) -> float:
        L_q = SaturationModel.of(MOTOR, i_sat=i_sat, drop=DROP, cross=CROSS).secant(
            0.0, [LOW_CURRENT, HIGH_CURRENT]
        )[1]
        return float(L_q[1] / L_q[0]) - 0.6

    return float(brentq(ratio, 2.0, 10.0, xtol=1e-14))  # the root above the knee


SATURATION = SaturationModel.of(MOTOR, i_sat=fitted_scale(), drop=DROP, cross=CROSS)
AVERAGE_DEAD_TIME = dataclasses.replace(
    DriveSettings.hardware_like(), pwm="average", current_noise=0.0
)


@st.composite
def models(draw: st.DrawFn) -> SaturationModel:
    """Models over four decades of inductance and two of ``i_s`` (at least the model's
    floor, a share of ``phi_pm / L_d``); the cross weight capped so that ``L_dinf >= 0.1
    L_d``."""
    L_d, L_q = draw(st.floats(1e-4, 1e-2)), draw(st.floats(1e-4, 1e-2))
    drop, cross = draw(st.floats(0.0, 0.9)), draw(st.floats(0.0, 0.5))
    if drop * L_q > 0.0:  # (a subnormal drop times L_q can round to 0)
        cross = min(cross, 0.9 * L_d / (drop * L_q))
    phi_pm = draw(st.floats(0.0, 0.5))
    floor = NARROWEST_KNEE * (phi_pm / L_d) * (1.0 + 1e-9)  # the model's, past its rounding
    i_sat = max(draw(st.floats(0.5, 50.0)), floor)
    return SaturationModel(L_d, L_q, phi_pm, i_sat, drop, cross)


currents = st.floats(-100.0, 100.0)


# -- the analytic model ------------------------------------------------------------------


def central_differences(model: Saturation, i_d: float, i_q: float, delta: float) -> Array:
    """``d psi / d i`` (2, 2) by central differences of step ``delta`` (A)."""
    columns = []
    for step in ((delta, 0.0), (0.0, delta)):
        high = model.flux(i_d + step[0], i_q + step[1])
        low = model.flux(i_d - step[0], i_q - step[1])
        columns.append([(high[0] - low[0]) / (2 * delta), (high[1] - low[1]) / (2 * delta)])
    return np.array(columns, dtype=float).T


@given(models(), currents, currents)
def test_the_flux_maps_are_reciprocal_and_their_hessian_is_the_incremental_inductance(
    model: SaturationModel, i_d: float, i_q: float
) -> None:
    """Central differences of step ``delta = 1e-3 i_s`` of the flux linkages: the
    cross-saturation terms agree (reciprocity) and are the incremental matrix. Their
    truncation error is ``delta^2 / 6`` of the third derivative, which is at most a few
    ``dL / i_s^2`` (``tanh`` and its derivatives are bounded by 1 to 2): ``1e-6 dL``
    allows for 6 of them; the rounding, ``eps |psi| / delta``, stays below 1e-9 H."""
    delta = 1e-3 * model.i_sat
    numeric = central_differences(model, i_d, i_q, delta)
    tolerance = 1e-6 * model.drop * model.L_q + 1e-9
    assert abs(numeric[0, 1] - numeric[1, 0]) <= 2 * tolerance
    np.testing.assert_allclose(model.incremental(i_d, i_q), numeric, rtol=0, atol=tolerance)


@given(models(), currents, currents)
def test_the_incremental_inductance_lies_within_the_bounds(
    model: SaturationModel, i_d: float, i_q: float
) -> None:
    L = model.incremental(i_d, i_q)
    assert L[0, 1] == L[1, 0]
    low, high = model.bounds
    eigenvalues = np.linalg.eigvalsh(L)
    assert low * (1 - 1e-12) <= eigenvalues[0] and eigenvalues[1] <= high * (1 + 1e-12)
    L_d, L_q = model.secant(i_d, i_q)
    psi_d, psi_q = model.flux(i_d, i_q)
    assert L_d * i_d + model.phi_pm == pytest.approx(psi_d, rel=1e-12, abs=1e-15)
    assert L_q * i_q == pytest.approx(psi_q, rel=1e-12, abs=1e-15)


def test_no_saturation_is_the_motors_constant_inductances_to_the_bit() -> None:
    model = SaturationModel.of(MOTOR, i_sat=3.0, drop=0.0, cross=0.3)
    i_d, i_q = np.meshgrid(np.linspace(-40, 40, 9), np.linspace(-40, 40, 11))
    psi_d, psi_q = model.flux(i_d, i_q)
    assert np.array_equal(psi_d, MOTOR.phi_pm + MOTOR.L_d * i_d)
    assert np.array_equal(psi_q, MOTOR.L_q * i_q)
    L = model.incremental(i_d, i_q)
    assert np.array_equal(L, np.broadcast_to(np.diag([MOTOR.L_d, MOTOR.L_q]), L.shape))
    L_d, L_q = model.secant(i_d, i_q)
    assert np.all(np.abs(L_d / MOTOR.L_d - 1) < 1e-15) and np.all(
        np.abs(L_q / MOTOR.L_q - 1) < 1e-15
    )


def test_the_fitted_model_saturates_as_the_measured_machine() -> None:
    """The secant ``L_q`` falls by 40 % from 2 A to 12 A; the incremental one more."""
    L_q = SATURATION.secant(0.0, [0.0, LOW_CURRENT, HIGH_CURRENT])[1]
    assert L_q[0] == MOTOR.L_q
    assert L_q[2] / L_q[1] == pytest.approx(0.6, rel=1e-12)
    assert SATURATION.incremental(0.0, HIGH_CURRENT)[1, 1] < L_q[2]


# -- the flux-map table ------------------------------------------------------------------

GRID = np.linspace(-30.0, 30.0, 25)  # spacing 2.5 A


def test_the_table_interpolates_the_model_it_samples() -> None:
    """Through the nodes to rounding; between them a bicubic spline errs by at most
    ``(5 / 384) D^4`` of the flux's fourth derivative per direction (D the spacing),
    the derivative by ``D^3 / 24`` of it. The fourth derivative is ``dL / i_s^3`` times
    ``tanh''''``'s largest value (about 4.1) for ``psi_q`` along ``i_q``; both directions
    and the cross weight's share of ``psi_d`` are allowed twice."""
    table = FluxMap.sampled(SATURATION, GRID, GRID)
    d, q = np.meshgrid(GRID, GRID, indexing="ij")
    np.testing.assert_allclose(table.flux(d, q), SATURATION.flux(d, q), rtol=0, atol=1e-15)
    x = np.linspace(0.0, 5.0, 5001)
    sech2, tanh = 1 / np.cosh(x) ** 2, np.tanh(x)
    fourth = np.max(np.abs(8 * sech2 * tanh * (3 * sech2 - 1)))
    dL, i_s, spacing = DROP * MOTOR.L_q, SATURATION.i_sat, GRID[1] - GRID[0]
    M4 = 2 * 2 * dL * fourth / i_s**3
    rng = np.random.default_rng(0)
    d, q = rng.uniform(-30.0, 30.0, (2, 2000))
    np.testing.assert_allclose(
        table.flux(d, q), SATURATION.flux(d, q), rtol=0, atol=5 / 384 * spacing**4 * M4
    )
    np.testing.assert_allclose(
        table.incremental(d, q), SATURATION.incremental(d, q), rtol=0, atol=spacing**3 / 24 * M4
    )
    low, high = table.bounds
    assert low == pytest.approx(SATURATION.bounds[0], rel=0.05) and high <= MOTOR.L_q


@pytest.mark.parametrize(
    ("change", "name"),
    [
        ({"i_d": GRID[::-1]}, "i_d"),
        ({"i_q": GRID[:3]}, "i_q"),
        ({"i_q": np.where(GRID > 10, np.nan, GRID)}, "i_q"),
        ({"psi_d": "reversed"}, "psi_d"),
        ({"psi_q": "nan"}, "psi_q"),
        ({"psi_q": "shape"}, "psi_q"),
        ({"i_d": np.r_[GRID[0], GRID[0] + 1e-9, GRID[2:]]}, "i_d"),
    ],
    ids=["decreasing grid", "short grid", "non-finite grid", "non-monotonic map",
         "non-finite map", "wrong shape", "two currents a hair apart"],
)  # fmt: skip
def test_bad_tables_are_refused_naming_the_argument(change: dict[str, object], name: str) -> None:
    table = FluxMap.sampled(SATURATION, GRID, GRID)
    fields: dict[str, object] = {
        "i_d": table.i_d, "i_q": table.i_q, "psi_d": table.psi_d, "psi_q": table.psi_q
    }  # fmt: skip
    for key, value in change.items():
        original = np.array(fields[key])
        if not isinstance(value, str):
            fields[key] = value
        elif value == "reversed":
            fields[key] = original[::-1]
        elif value == "nan":
            original[3, 4] = np.nan
            fields[key] = original
        else:
            fields[key] = original[:, :-1]
    with pytest.raises(InputError, match=f"^{name}:"):
        FluxMap(**fields)  # type: ignore[arg-type]


def test_currents_outside_the_table_are_refused() -> None:
    table = FluxMap.sampled(SATURATION, GRID, GRID)
    for method in (table.flux, table.incremental, table.secant):
        with pytest.raises(InputError, match=r"^i_d, i_q: the current .* outside"):
            method(0.0, 31.0)
    with pytest.raises(InputError, match=r"^i_d, i_q: expected finite"):
        table.flux(np.nan, 0.0)


@pytest.mark.parametrize(
    ("fields", "name"),
    [({"drop": 1.0}, "drop"), ({"cross": -0.1}, "cross"), ({"cross": 1.0}, "cross"),
     ({"i_sat": 0.0}, "i_sat"), ({"L_q": np.inf}, "L_q"),
     ({"i_sat": 0.99 * NARROWEST_KNEE * abs(SATURATION.phi_pm) / SATURATION.L_d}, "i_sat")],
)  # fmt: skip
def test_bad_models_are_refused_naming_the_field(fields: dict[str, float], name: str) -> None:
    with pytest.raises(InputError, match=f"^{name}:"):
        dataclasses.replace(SATURATION, **fields)


# -- the drive ---------------------------------------------------------------------------


def law_for(speed: float, share: float = 0.25) -> ControlLaw:
    """Feedforward of the unsaturated motor and proportional feedback of ``share`` of
    the dead-beat gains, with integral action (tests/test_salient_drive.py's)."""
    problem = MOTOR.regulation_problem(speed)
    X = -problem.F
    U = -np.linalg.solve(problem.B, problem.A @ X + problem.D)
    K = share * np.diag([MOTOR.L_d, MOTOR.L_q]) / H
    return ControlLaw(K, X, U, K_i=20.0 * K, C=np.eye(2), F=-X, h=H)


def record(
    saturation: Saturation | None,
    speed: float,
    current: float,
    count: int,
    settings: DriveSettings = AVERAGE_DEAD_TIME,
) -> DriveRecord:
    drive = RealisticDrive(MOTOR, speed, H, settings, saturation)
    w = np.array([MOTOR.p * speed * MOTOR.phi_pm, 0.0, current])  # i_d* = 0, i_q* = current
    return drive.record(law_for(speed), constant(w), num_samples=count, exploration=uniform(3.0),
                        seed=5)  # fmt: skip


def average_segments(speed: float, rec: DriveRecord) -> list[tuple[float, float, complex]]:
    """Each sample's ``(t_k, t_(k+1), V)``: the stationary vector held over it rebuilt
    from the mean dq voltage, ``applied_k exp(j theta_k) / mean(exp(-j w_e s))``."""
    w_e = MOTOR.p * speed
    count = rec.applied_voltages.shape[0]
    t = H * np.arange(count + 1)
    applied = rec.applied_voltages[:, 0] + 1j * rec.applied_voltages[:, 1]
    held = applied * np.exp(1j * w_e * t[:-1]) / phasor_mean(w_e * H)
    return [(t[k], t[k + 1], complex(held[k])) for k in range(count)]


def integrate(
    saturation: Saturation, speed: float, segments: list[tuple[float, float, complex]]
) -> Array:
    """The rotor-frame currents at each segment's end from rest: ``d psi/dt = u - R_s i -
    w_e J psi`` in the currents (``di/dt = L_inc^-1 (...)``), the stationary vector V of
    each ``(t0, t1, V)`` held over it, by DOP853 at ``rtol = atol / 1 A = 1e-10``."""
    w_e = MOTOR.p * speed
    current, ends = np.zeros(2), []
    for t0, t1, held in segments:

        def rate(s: float, i: Array, V: complex = held) -> Array:
            psi_d, psi_q = saturation.flux(i[0], i[1])
            u = np.exp(-1j * w_e * s) * V
            e = [u.real - MOTOR.R_s * i[0] + w_e * psi_q, u.imag - MOTOR.R_s * i[1] - w_e * psi_d]
            return np.linalg.solve(saturation.incremental(i[0], i[1]), e)

        solution = solve_ivp(rate, (t0, t1), current, method="DOP853", rtol=1e-10, atol=1e-10)
        current = solution.y[:, -1]
        ends.append(current)
    return np.array(ends)


#: RK4's global error is of the order of ``STEP_RATE^4`` (6e-6) of the current: the step
#: rule bounds ``rate tau`` and the current's move per step by STEP_RATE, and the loop
#: contracts (measured 9e-9 to 2.2e-7 against DOP853 at 1e-10).
RK4_AGREES = STEP_RATE**4


@pytest.mark.parametrize("current", [LOW_CURRENT, HIGH_CURRENT], ids=["2 A", "12 A"])
@pytest.mark.parametrize("speed", [HIGH_SPEED, LOW_SPEED], ids=["w_e h = 0.3", "w_e h = 0.02"])
def test_the_saturating_drive_is_the_integrated_motor(speed: float, current: float) -> None:
    count = 300
    rec = record(SATURATION, speed, current, count)
    expected = integrate(SATURATION, speed, average_segments(speed, rec))
    scale = np.max(np.abs(rec.true_currents))
    i_q = np.mean(rec.true_currents[count // 2 :, 1])
    assert abs(i_q - current) < 0.25 * current  # near it: the law is the unsaturated motor's
    np.testing.assert_allclose(rec.true_currents[1:], expected, rtol=0, atol=RK4_AGREES * scale)
    psi_d, psi_q = SATURATION.flux(rec.true_currents[:, 0], rec.true_currents[:, 1])
    i_d, i_q_all = rec.true_currents.T
    np.testing.assert_allclose(
        rec.torque, 1.5 * MOTOR.p * (psi_d * i_q_all - psi_q * i_d), rtol=1e-14, atol=1e-14
    )


CARRIER = dataclasses.replace(
    DriveSettings.hardware_like(), current_noise=0.0, adc_bits=None, adc_range=None
)


@pytest.mark.parametrize("speed", [HIGH_SPEED, LOW_SPEED], ids=["w_e h = 0.3", "w_e h = 0.02"])
def test_carrier_pwm_is_the_integrated_saturating_motor(speed: float) -> None:
    """Carrier PWM with dead time at 12 A: each carrier period's seven segments rebuilt
    from the applied command (``exp(j (theta_k + w_e h / 2)) u_k``, angle compensation)
    and the true phase currents' signs at its start (:func:`carrier_segments`), as
    tests/test_salient_drive.py does for the exact path."""
    count = 150
    rec = record(SATURATION, speed, HIGH_CURRENT, count, CARRIER)
    w_e = MOTOR.p * speed
    t = H * np.arange(count + 1)
    assert CARRIER.logged_input == "applied" and CARRIER.angle_compensation
    assert CARRIER.dc_voltage is not None
    u = rec.trajectory.u[:, 0] + 1j * rec.trajectory.u[:, 1]
    command = np.exp(1j * w_e * (t[:-1] + 0.5 * H)) * u
    true = rec.true_currents[:, 0] + 1j * rec.true_currents[:, 1]
    signs = np.sign(to_phases(true[:-1] * np.exp(1j * w_e * t[:-1])))
    pwm = carrier_segments(command, CARRIER.dc_voltage, H, CARRIER.dead_time, signs)
    segments, ends = [], []
    for k in range(count):
        bounds = t[k] + pwm.boundaries[k]
        for j in range(7):
            if bounds[j + 1] > bounds[j]:
                segments.append((bounds[j], bounds[j + 1], complex(pwm.voltages[k, j])))
        ends.append(len(segments) - 1)
    expected = integrate(SATURATION, speed, segments)[ends]
    scale = np.max(np.abs(rec.true_currents))
    assert np.mean(rec.true_currents[count // 2 :, 1]) > 0.75 * HIGH_CURRENT
    np.testing.assert_allclose(rec.true_currents[1:], expected, rtol=0, atol=RK4_AGREES * scale)


def test_the_drive_on_a_flux_map_is_the_integrated_table() -> None:
    table = FluxMap.sampled(SATURATION, GRID, GRID)
    rec = record(table, LOW_SPEED, HIGH_CURRENT, 200)
    scale = np.max(np.abs(rec.true_currents))
    expected = integrate(table, LOW_SPEED, average_segments(LOW_SPEED, rec))
    np.testing.assert_allclose(rec.true_currents[1:], expected, rtol=0, atol=RK4_AGREES * scale)


def test_no_saturation_is_the_exact_drive_to_the_step_rules_accuracy() -> None:
    """``drop = 0`` through the Runge-Kutta path against the exact rotor-frame path."""
    flat = SaturationModel.of(MOTOR, i_sat=1.0, drop=0.0)
    for speed in (HIGH_SPEED, LOW_SPEED):
        exact, stepped = (
            record(None, speed, HIGH_CURRENT, 300),
            record(flat, speed, HIGH_CURRENT, 300),
        )
        scale = np.max(np.abs(exact.true_currents))
        np.testing.assert_allclose(
            stepped.true_currents, exact.true_currents, rtol=0, atol=RK4_AGREES * scale
        )
        np.testing.assert_allclose(
            stepped.torque, exact.torque, rtol=0, atol=RK4_AGREES * np.max(np.abs(exact.torque))
        )


def test_saturation_moves_the_currents_where_the_inductance_falls() -> None:
    """At 12 A the saturated motor's response differs from the unsaturated one's by far
    more than the step rule's error; at the same currents it is a different motor."""
    exact, saturated = (
        record(None, LOW_SPEED, HIGH_CURRENT, 300),
        record(SATURATION, LOW_SPEED, HIGH_CURRENT, 300),
    )
    difference = np.max(np.abs(saturated.true_currents - exact.true_currents))
    assert difference > 100 * RK4_AGREES * np.max(np.abs(exact.true_currents))


def test_a_table_drive_leaving_the_grid_is_refused() -> None:
    small = np.linspace(-4.0, 4.0, 9)
    table = FluxMap.sampled(SATURATION, small, small)
    with pytest.raises(InputError, match=r"^the drive's currents: the current .* outside"):
        record(table, LOW_SPEED, HIGH_CURRENT, 300)


def test_the_drive_refuses_what_it_does_not_model() -> None:
    with pytest.raises(InputError, match=r"^saturation: expected"):
        RealisticDrive(MOTOR, 100.0, H, DriveSettings(), "saturated")  # type: ignore[arg-type]
    warm = DriveSettings(temperature_rise=40.0)
    with pytest.raises(InputError, match=r"^saturation: .* temperature"):
        RealisticDrive(MOTOR, 100.0, H, warm, SATURATION)
    with pytest.raises(InputError, match=r"^saturation: .* temperature"):
        run_drive_batch(
            [MOTOR], 100.0, H, warm, law_for(100.0), constant(MOTOR.exogenous(100.0, 1.0)),
            num_samples=10, exploration=None, seed=0, saturation=SATURATION,
        )  # fmt: skip
    drive = RealisticDrive(MOTOR, 100.0, H, DriveSettings(), SATURATION)
    with pytest.raises(InputError, match=r"^saturation: a drive session"):
        drive.start(law_for(100.0), seed=0)


def test_a_saturating_motor_has_no_linear_sample_map() -> None:
    batch = MotorBatch.build([MOTOR], np.array([100.0]), 0.0)
    with pytest.raises(InputError, match=r"^stack_motors: a saturating motor is not linear"):
        stack_motors([batch, dataclasses.replace(batch, saturation=SATURATION)])


if __name__ == "__main__":  # python tests/test_saturation.py: the timings of docs/saturation.md
    import time

    speed, count = 100.0, 2000  # w_e h = 0.04
    w = np.array([MOTOR.p * speed * MOTOR.phi_pm, 0.0, HIGH_CURRENT])
    table = FluxMap.sampled(SATURATION, GRID, GRID)
    for name, saturation in (("exact", None), ("analytic", SATURATION), ("table", table)):
        for motors in (1, 20):
            start = time.process_time()
            run_drive_batch(
                [MOTOR] * motors, speed, H, AVERAGE_DEAD_TIME, law_for(speed), constant(w),
                num_samples=count, exploration=uniform(3.0), seed=5, saturation=saturation,
            )  # fmt: skip
            seconds = time.process_time() - start
            print(f"{name:9s} {motors:2d} motor(s): {1e3 * seconds / count:.2f} ms a sample")


@pytest.mark.parametrize("seed", [21, 5])
def test_the_drawn_saturating_motors_span_the_measured_inductance_fall(seed: int) -> None:
    """The saturation study's draws (``selftune.bench.measure_saturation_draws``) fall by
    the 20-40 % the issue measured on a real machine, and a little beyond either end,
    across the issue's motors (surface ones in their interior form, saliency up to 3)."""
    from selftune.bench._saturation import drawn_saturating, inductance_fall

    cases, redrawn = drawn_saturating(100, seed)
    falls = np.array(
        [inductance_fall(motor, torque, sat) for (motor, _, torque, _, _), sat, _ in cases]
    )
    assert np.all((falls > 0.1) & (falls < 0.5))
    low, high = np.percentile(falls, [10, 90])
    assert low < 0.22 and high > 0.36
    saliencies = np.array([motor.L_q / motor.L_d for (motor, *_), _, _ in cases])
    assert np.any(saliencies == 1.0) and np.all((saliencies >= 1.0) & (saliencies <= 3.0))
    assert 0 < redrawn < len(cases)  # some knees under the floor, but not most
