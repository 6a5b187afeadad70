"""The phase signs the next sample shows, where the measured current does not decide them.

A phase current measured within :data:`UNDECIDED` standard deviations of its measurement
error of zero may have either sign. The sign held over a sample moves the next sample's
current by the dead time's ``-v Bd s_k``: a wrong one by ``2 v`` on that phase, far more
than the noise on a small inductance (0.48 V moves 33 uH by 1.4 A in 0.1 ms, against ADC
steps of 0.05-0.2 A). So of the sign patterns that keep every decided phase's measured
sign, each sample takes the one whose one-step prediction from the measured currents is
nearest the next measured currents, weighted by their noise (:func:`next_signs`). The
learner uses it on the logs (:mod:`._model_signs`) and on the simulations that measure
that fit's bias (:mod:`._sign_bias`).
"""

from __future__ import annotations

import itertools

import numpy as np

from ...core import Array
from ...core._phases import from_phases, phase_currents
from ._propagation import _Log

__all__ = ["UNDECIDED", "next_signs"]

#: A measured phase current within this many standard deviations of its measurement
#: error of zero has a sign the measurement does not decide.
UNDECIDED = 3.0

#: Every pattern of three phase signs, shape (8, 3).
_PATTERNS = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))


def next_signs(
    x: Array, a: Array, w: Array, angle: Array, matrices: tuple[Array, Array, Array], noise: Array
) -> Array:
    """The dq vectors of the phase signs held over each sample, undecided ones taken as the
    next sample shows them (see the module).

    Parameters
    ----------
    x : ndarray, shape (T + 1, 2)
        The measured currents ``[i_d, i_q]``, A.
    a : ndarray, shape (T, m)
        The applied inputs.
    w : ndarray, shape (T, q)
        The exogenous channels before the signs'.
    angle : ndarray, shape (T,)
        The electrical angle at each sample, rad.
    matrices : (Ad, Bd, Ed)
        The model; the last two columns of ``Ed`` are the signs' gain.
    noise : ndarray, shape (2, 2)
        The measurement noise's covariance on the states, A^2.

    Returns
    -------
    ndarray, shape (T, 2)
    """
    Ad, Bd, Ed = matrices
    q = w.shape[1]
    weight = 1.0 / np.sqrt(np.diag(noise))
    per_phase = float(np.sqrt(1.5 * np.mean(np.diag(noise))))  # dq variance 2/3 of a phase's
    # what the signs' channels must explain of each next sample
    left = _Log(x=x, a=a, w=w).one_step_residuals((Ad, Bd, Ed[:, :q]))
    phases = phase_currents(x[:-1], angle)
    decided = np.abs(phases) > UNDECIDED * per_phase
    allowed = np.all(
        ~decided[:, np.newaxis, :] | (_PATTERNS == np.sign(phases)[:, np.newaxis, :]), axis=2
    )  # (T, 8)
    vectors = from_phases(_PATTERNS)[np.newaxis, :] * np.exp(-1j * angle)[:, np.newaxis]
    moved = np.stack([vectors.real, vectors.imag], axis=-1) @ Ed[:, q:].T  # (T, 8, 2)
    cost = np.sum(((left[:, np.newaxis, :] - moved) * weight) ** 2, axis=2)
    best = np.argmin(np.where(allowed, cost, np.inf), axis=1)
    chosen = vectors[np.arange(best.size), best]
    return np.column_stack([chosen.real, chosen.imag])
