"""Stacked evaluations give what one-at-a-time evaluations give.

Truth: the core's own discretizations (:func:`selftune.core.discretize`,
:func:`selftune.core.rotating_hold`) of the structure's continuous matrices, and the
sampled loop's radius of one plant at a time; for the change watch, its scores written out
direction by direction as its docstring states them.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from example_counts import examples
from selftune.core import ControlLaw, discretize, rotating_hold
from selftune.errors import InputError
from selftune.learn import SpmsmStructure
from selftune.learn.evidence._discrete_model import DiscreteModel
from selftune.learn.online import ChangeWatch
from selftune.learn.verdict._quality import closed_loop_radii, closed_loop_radius
from selftune.learn.verdict._verdict import plausible_models

H, SPEED = 1e-4, 150.0


def _thetas(dead_time: bool, count: int = 12) -> np.ndarray:
    rng = np.random.default_rng(4)
    columns = [rng.uniform(0.05, 2.0, count), rng.uniform(1e-3, 2e-2, count),
               rng.uniform(0.5, 1.5, count), rng.uniform(0.0, 3.0, count)]  # fmt: skip
    return np.column_stack(columns[: 4 if dead_time else 3])


def _by_the_core(structure: SpmsmStructure, theta: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(Ad, Bd, Ed)`` from the core's discretizations, one parameter vector."""
    R_s, L_s, kappa = theta[:3]
    w_e = structure.electrical_speed
    A = np.array([[-R_s / L_s, w_e], [-w_e, -R_s / L_s]])
    B = np.eye(2) / L_s
    exact = discretize(A, B, H, D=np.array([[0.0, 0.0], [-kappa / L_s, 0.0]]))
    Bd = exact.Bd
    if structure.hold == "stationary":
        Bd = rotating_hold(A, B, H, w_e, advance=0.5 * w_e * H)
    if not structure.dead_time:
        return exact.Ad, Bd, exact.Ed
    return exact.Ad, Bd, np.hstack([exact.Ed, -theta[3] * rotating_hold(A, B, H, w_e)])


#: The closed forms against the core's matrix exponentials (scaling and squaring, Pade):
#: agreement to rounding, relative to the largest entry of the three blocks (the
#: exponentials' own accuracy is normwise). Over 3,000 draws with a h to 700 and w_e h to
#: 10, the largest difference was 6e-14.
ROUNDING = 1e-13


def _agree(structure: SpmsmStructure, thetas: np.ndarray) -> None:
    stacked = structure.stack(thetas)
    for row, theta in enumerate(thetas):
        core = _by_the_core(structure, theta)
        scale = max(1.0, *(float(np.max(np.abs(block))) for block in core))
        for each, one, exact in zip(stacked, structure(theta), core, strict=True):
            np.testing.assert_array_equal(each[row], one)  # a row of a stack is its own
            assert np.max(np.abs(each[row] - exact)) <= ROUNDING * scale


@pytest.mark.parametrize("hold", ["stationary", "rotor"])
@pytest.mark.parametrize("dead_time", [False, True])
def test_a_stack_of_parameters_gives_the_cores_exponentials(hold: str, dead_time: bool) -> None:
    """The closed forms, a stack at once: each row is the one-at-a-time value, and the
    core's discretization of the continuous matrices to rounding."""
    _agree(SpmsmStructure(SPEED, H, dead_time, hold), _thetas(dead_time))  # type: ignore[arg-type]


@given(
    stiffness=st.floats(-6.0, np.log10(700.0)),
    turn=st.floats(-4.0, 1.0),
    L_s=st.floats(-5.5, -1.0),
    hold=st.sampled_from(["stationary", "rotor"]),
    sign=st.sampled_from([-1.0, 1.0]),
)
@examples(200, quick=30)
def test_the_closed_forms_hold_on_stiff_and_fast_turning_plants(
    stiffness: float, turn: float, L_s: float, hold: str, sign: float
) -> None:
    """R_s h / L_s from 1e-6 to 700 (Ad down to 1e-304), w_e h from 1e-4 to 10 rad."""
    inductance = 10.0**L_s
    theta = np.array([[10.0**stiffness * inductance / H, inductance, 0.8, 1.5]])
    structure = SpmsmStructure(sign * 10.0**turn / H, H, True, hold)  # type: ignore[arg-type]
    _agree(structure, theta)


def test_a_stack_raises_the_first_bad_rows_error() -> None:
    """A row with L_s <= 0 or a non-finite parameter: the error one-at-a-time gives."""
    structure = SpmsmStructure(SPEED, H)
    thetas = _thetas(False, 4)
    for bad, message in (([0.5, -1e-3, 1.0], "L_s: must be positive"),
                         ([np.inf, 1e-3, 1.0], "A: contains NaN")):  # fmt: skip
        thetas[2] = bad
        with pytest.raises(InputError, match=message):
            structure(thetas[2])
        with pytest.raises(InputError, match=message):
            structure.stack(thetas)


def _law() -> ControlLaw:
    structure = SpmsmStructure(SPEED, H, hold="rotor")
    Ad, Bd, _ = structure(np.array([0.6, 8e-3, 1.0]))
    K = np.hstack([np.linalg.solve(Bd, Ad) * 0.3, 0.2 * np.eye(2)])  # a delay of one sample
    return ControlLaw(K, np.eye(2), np.zeros((2, 2)), history=1, K_i=-50.0 * H * np.eye(2),
                      C=np.eye(2), F=-np.eye(2), h=H)  # fmt: skip


def test_the_plausible_plants_and_their_radii_are_the_same_stacked() -> None:
    """plausible_models with the stacked map, and closed_loop_radii, equal the
    draw-by-draw models and radii."""
    structure = SpmsmStructure(SPEED, H, hold="rotor")
    theta = np.array([0.6, 8e-3, 1.0])
    model = DiscreteModel.given(*structure(theta), H)
    covariance = np.diag((0.05 * theta) ** 2)
    one = plausible_models(model, structure, theta, covariance)
    stacked = plausible_models(model, structure, theta, covariance, stacked=structure.stack)
    assert len(one) == len(stacked) == 25
    for a, b in zip(one, stacked, strict=True):
        for name in ("Ad", "Bd", "Ed"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    law = _law()
    radii = closed_loop_radii(stacked, law, 1)
    np.testing.assert_array_equal(radii, [closed_loop_radius(each, law, 1) for each in one])


def test_the_change_watch_scores_as_its_docstring_states() -> None:
    """Three chunks, three directions: g_j = sum_k u_k' e_k over the window, its
    variance the process noise's, the measurements' (each in two errors, the window's
    first and last in one) and the reference's; equal to rounding (the scores' terms'
    sizes times a few epsilons)."""
    rng = np.random.default_rng(11)
    p, n, parameters = 6, 2, 3
    Theta = 0.3 * rng.standard_normal((p, n))
    R, Q = np.diag([2e-4, 1e-4]), np.diag([3e-5, 5e-5])
    Sigma = Q + R + Theta[:n].T @ R @ Theta[:n]
    sensitivities = rng.standard_normal((p * n, parameters))
    covariance = 1e-6 * np.eye(p * n)
    watch = ChangeWatch(250, 0.01)
    watch.reference(Theta, (Sigma, R, Q), sensitivities, covariance)
    chunks = [(rng.standard_normal((100, p)), rng.standard_normal((100, p)),
               rng.standard_normal((100, n))) for _ in range(3)]  # fmt: skip
    for chunk in chunks:
        test = watch.add(*chunk)
    assert test is not None
    zeta, z, y = (np.vstack(parts) for parts in zip(*chunks, strict=True))
    Ad = Theta[:n].T
    errors = y - z @ Theta
    expected, sizes = [], []
    for column in sensitivities.T:
        M = column.reshape((n, p), order="F")
        u = zeta @ (np.linalg.inv(Sigma) @ M).T  # u_k = Sigma^-1 M_j zeta_k
        c = np.vstack([-u[:1] @ Ad, u[:-1] - u[1:] @ Ad, u[-1:]])  # every measurement's
        a = (z.T @ u).ravel(order="F")
        variance = np.sum((u @ Q) * u) + np.sum((c @ R) * c) + a @ covariance @ a
        expected.append(np.sum(u * errors) / np.sqrt(variance))
        sizes.append(np.sum(np.abs(u * errors)) / np.sqrt(variance))
    bound = 64 * np.finfo(float).eps * (np.array(sizes) + np.abs(expected))
    assert np.all(np.abs(test.scores - np.array(expected)) <= bound), (test.scores, expected)
