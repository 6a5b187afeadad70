"""What the learner knows of the motor: the regulation form built from p, speed, T* and flux,
and the reference perturbation the paper applies."""

from __future__ import annotations

import numpy as np

from ..core import Array, finite_float, positive_finite, positive_integer
from ._settings import Perturbation

__all__ = [
    "PAPER_PERTURBATION",
    "STEP_DWELL",
    "STEP_LEVELS",
    "known_flux_form",
    "reference_perturbation",
]

#: The paper's reference perturbation (Sec. V), w_d(t) = [sin(1000 t), 0.1 cos(3000 t)].
PAPER_PERTURBATION = ((1.0, 1000.0, 0.0), (0.1, 3000.0, 0.5 * np.pi))

#: The ``"steps"`` torque reference, in units of T*: it reverses the current, so that an
#: inverter's dead-time voltage (which follows the current's sign) cannot pass for
#: back-EMF (which does not), and visits four levels, so that it cannot pass for a
#: resistance either.
STEP_LEVELS = (1.0, 1.0 / 3.0, -1.0 / 3.0, -1.0)

#: Time at each level of the ``"steps"`` reference, s.
STEP_DWELL = 0.01


def reference_perturbation(t: Array, kind: Perturbation, torque: float = 1.0) -> Array:
    """``w_d(t)``, shape (len(t), 2): the paper's on both channels, or on the torque only.

    ``"paper"``: ``[sin(1000 t), 0.1 cos(3000 t)]``. ``"torque"``: ``[0, 0.1 cos(3000 t)]``
    -- a drive can move its torque reference but not the back-EMF ``p speed phi_pm``.
    ``"steps"``: the torque reference walks through :data:`STEP_LEVELS` times T*, each
    held :data:`STEP_DWELL`, i.e. ``[0, (level(t) - 1) T*]``: what a drive with an
    inverter needs (see :data:`STEP_LEVELS`).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Times, s.
    kind : {"paper", "torque", "steps"}
        Which channels are perturbed, and how.
    torque : float
        T*, N m (``"steps"`` only).
    """
    t = np.asarray(t, dtype=float)
    if kind == "steps":
        index = np.floor(t / STEP_DWELL).astype(int) % len(STEP_LEVELS)
        level = np.asarray(STEP_LEVELS)[index]
        return np.column_stack([np.zeros_like(t), (level - 1.0) * torque])
    columns = [
        amplitude * np.sin(frequency * t + phase)
        for amplitude, frequency, phase in PAPER_PERTURBATION
    ]
    if kind == "torque":
        columns[0] = np.zeros_like(t)
    return np.column_stack(columns)


def known_flux_form(
    pole_pairs: int, speed: float, torque: float, phi_pm: float
) -> tuple[Array, Array, Array, Array]:
    """``(C, E, F, w)`` of the known-flux torque-regulation form (eq. 8): what the learner knows.

    ``w = [p speed phi_pm, T*]``, ``e = [i_d, i_q - i_q*]`` with ``i_q* = 2 T* / (3 p phi_pm)``::

        C = I,  E = 0,  F = [[0, 0], [0, -2 / (3 p phi_pm)]]

    the same C, E, F as :meth:`selftune.model.SPMSM.regulation_problem`, built from the
    values a drive engineer has (no resistance or inductance).

    Parameters
    ----------
    pole_pairs : int
        p.
    speed : float
        Mechanical speed, rad/s.
    torque : float
        Torque reference T*, N m.
    phi_pm : float
        Magnet flux linkage, Wb (known, or identified by Algorithm 3).
    """
    p = positive_integer(pole_pairs, "pole_pairs")
    phi_pm = positive_finite(phi_pm, "phi_pm")
    speed, torque = finite_float(speed, "speed"), finite_float(torque, "torque")
    F = np.array([[0.0, 0.0], [0.0, -2.0 / (3.0 * p * phi_pm)]])
    w = np.array([p * speed * phi_pm, torque])
    return np.eye(2), np.zeros((2, 2)), F, w
