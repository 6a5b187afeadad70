"""The sampled model of a running drive, estimated chunk by chunk.

``x_(k+1) = Ad x_k + Bd a_k + Ed w_k`` (with the inverter's dead time, the dq vector
``s_k`` of the phase currents' signs as extra channels of ``w``, :mod:`..evidence._dead_time`),
from :class:`~._moments.ForgettingMoments`: instruments ``[x_(k-1), a_k, w_k]`` (and the
signs of ``x_(k-1)`` at row k's angle), so that neither the noise on ``x_k`` nor the signs
it flips near zero current bias the estimate. A chunk's rows join the previous chunk's:
any chunking gives the same moments. The transitions wait until the moments are read
(or :data:`PENDING_ROWS` of them are waiting), and are then added in one product: the
work of a product is mostly its call, not its rows. They wait laid out as the products
take them (:func:`~._moments.add_rows`), each written once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ...core import Array, positive_finite
from ...errors import InputError
from ..evidence._dead_time import phase_signs
from ..evidence._discrete_model import DiscreteModel
from ..evidence._encoder import angle_count, read_angle
from ..evidence._pulses import lost_signs
from ._moments import ForgettingMoments, add_rows, transposed_covariance

__all__ = ["OnlineModel"]

#: Rows a transition needs besides its own: the one before (the instrument) and after.
_TAIL = 2

#: The most transitions that wait to be added to the moments: the memory it takes is
#: bounded whoever reads the moments, and how seldom, and a batch stays within the
#: processor's caches (per row, 1,000 rows took a third of the time of 100 and of 2,000).
PENDING_ROWS = 1000


@dataclass
class OnlineModel:
    """The drive's sampled model under forgetting (see the module).

    Attributes
    ----------
    h : float
        Sampling period, s.
    memories : tuple of float
        The forgetting's time constants, s, one model each (a sample's weight falls by
        ``e`` over one): a fast and a slow model share the rows' work.
    n, m, q : int
        States, inputs and exogenous channels (the reference's, without the signs).
    dead_time : bool
        Model the inverter's dead time (the rows need the electrical angle).
    pulses : (float, float) or None
        With dead time on a PWM inverter: the angle its modulator turns a row's command
        ahead, rad, and its DC bus, V; the moments then keep the dead time that short
        pulses do not carry (:func:`~..evidence._pulses.lost_signs`), which the model
        leaves out (:meth:`omitted_shift`).
    dead_time_voltage : float
        ``v = t_d V_dc / T``, V, that pulses are judged short against (the caller's
        latest estimate; 0: none is short).
    """

    h: float
    memories: tuple[float, ...]
    n: int
    m: int
    q: int
    dead_time: bool = False
    pulses: tuple[float, float] | None = None
    dead_time_voltage: float = 0.0
    _memories: list[ForgettingMoments] = field(init=False, repr=False)
    _tail: tuple[Array, Array] | None = field(init=False, default=None, repr=False)
    # the angle's encoder count, rad, once a chunk has shown it (None: an exact angle;
    # not decided while the angle has not moved)
    _count: float | None = field(init=False, default=None, repr=False)
    _counted: bool = field(init=False, default=False, repr=False)
    # the waiting transitions, rows 1 to _waiting, laid out [zeta_(k-1), zeta_k, z_k, y_k,
    # z_(k-1), y_(k-1)]; row 0 the transition added last (zeros before the first). A
    # full buffer is replaced, not overwritten: the rows :meth:`add` returned stay valid.
    _rows: Array = field(init=False, repr=False)
    _waiting: int = field(init=False, default=0, repr=False)

    def __post_init__(self) -> None:
        self.h = positive_finite(self.h, "h")
        if not self.memories:
            raise InputError("memories: give at least one time constant, s")
        self.memories = tuple(positive_finite(value, "memories") for value in self.memories)
        size = self.n + self.m + self.q + (2 if self.dead_time else 0)
        self._memories = [
            ForgettingMoments(math.exp(-self.h / memory), size, self.n) for memory in self.memories
        ]
        self._rows = self._buffer(PENDING_ROWS, None)

    @property
    def moments(self) -> list[ForgettingMoments]:
        """Each memory's moments, with every transition added so far (the list itself:
        a memory may be replaced in it, as after a change)."""
        self._add_pending()
        return self._memories

    def _add_pending(self) -> None:
        """Add the waiting transitions to every memory, in one product."""
        if self._waiting:
            p, rows = self._memories[0].regressors, self._rows[1 : self._waiting + 1]
            add_rows(self._memories, rows[:, p:], rows[:, : 2 * p])
            self._rows = self._buffer(PENDING_ROWS, self._rows[self._waiting])
            self._waiting = 0

    def _buffer(self, rows: int, last: Array | None) -> Array:
        """Room for ``rows`` waiting transitions after ``last`` (None: zeros)."""
        size, n = self._memories[0].regressors, self.n
        buffer = np.empty((rows + 1, 4 * size + 2 * n))
        buffer[0] = 0.0 if last is None else last
        return buffer

    def _read(self, angle: Array) -> Array:
        """A chunk's angle: an encoder's read to better than its count over the chunk's
        own rows (the count found once: its search is a third of the reading's cost, and
        on every chunk of an exact angle the only one)."""
        if not self._counted:
            self._count = angle_count(angle)
            self._counted = self._count is not None or bool(np.ptp(angle) > 0.0)
        return angle if self._count is None else read_angle(angle, self._count)

    @property
    def channels(self) -> int:
        """Exogenous channels of the model: the reference's and, with dead time, two."""
        return self.q + (2 if self.dead_time else 0)

    def add(
        self, x: Array, a: Array, w: Array, angle: Array | None = None
    ) -> tuple[Array, Array, Array]:
        """Add a chunk of rows (the next after the last chunk's); returns the transitions
        it completed: instruments, regressors and next states (none at the very start).

        Parameters
        ----------
        x : ndarray, shape (T, n)
            Measured states at the rows.
        a : ndarray, shape (T, m)
            Input applied during each row's sample.
        w : ndarray, shape (T, q)
            Exogenous signal held during it.
        angle : ndarray, shape (T,), optional
            Electrical angle at each row, rad (needed with ``dead_time``); an encoder's
            is read to better than its count over the chunk
            (:func:`~..evidence._encoder.read_angle`; whether it is an encoder's, and
            its count, is decided on the first chunk in which the angle moves).
        """
        if self.dead_time and angle is None:
            raise InputError("angle: the dead-time model needs the electrical angle of each row")
        n, m, T = self.n, self.m, x.shape[0]
        held = 0 if self._tail is None else self._tail[0].shape[0]
        data = np.empty((held + T, n + m + w.shape[1]))  # rows [x_k, a_k, w_k]
        data[held:, :n], data[held:, n : n + m], data[held:, n + m :] = x, a, w
        angles = np.zeros(T) if angle is None else self._read(np.asarray(angle, dtype=float))
        if self._tail is not None:
            data[:held] = self._tail[0]
            angles = np.concatenate([self._tail[1], angles])
        self._tail = (data[-_TAIL:], angles[-_TAIL:])
        count = data.shape[0] - _TAIL  # transitions k -> k + 1 with a row k - 1 before
        p = self._memories[0].regressors
        if count < 1:
            return np.zeros((0, p)), np.zeros((0, p)), np.zeros((0, n))
        if self._waiting + count >= self._rows.shape[0]:  # room for the chunk
            self._rows = self._grown(count)
        first, last = self._waiting + 1, self._waiting + count + 1
        rows = self._rows[first:last]
        # zeta_k = [x_(k-1), a_k, w_k], z_k = [x_k, a_k, w_k], y_k = x_(k+1)
        width = data.shape[1]
        rows[:, p : p + n] = data[:-2, :n]
        rows[:, p + n : p + width] = data[1:-1, n:]
        rows[:, 2 * p : 2 * p + width] = data[1:-1]
        rows[:, 3 * p : 3 * p + n] = data[2:, :n]
        if self.dead_time:
            # the signs of x_k and of x_(k-1), both at row k's angle: one call
            signs = phase_signs(data[_twice(count), :n], angles[1 : count + 1])
            rows[:, 3 * p - 2 : 3 * p] = signs[0]
            rows[:, 2 * p - 2 : 2 * p] = signs[1]
            if self.pulses is not None:
                self._add_lost(rows[:, p : 2 * p], data[1 : count + 1], angles[1 : count + 1])
        # the transition before each: [zeta_(k-1)] and [z_(k-1), y_(k-1)]
        rows[:, :p] = self._rows[first - 1 : last - 1, p : 2 * p]
        rows[:, 3 * p + n :] = self._rows[first - 1 : last - 1, 2 * p : 3 * p + n]
        self._waiting += count
        if self._waiting >= PENDING_ROWS:
            self._add_pending()
        return rows[:, p : 2 * p], rows[:, 2 * p : 3 * p], rows[:, 3 * p : 3 * p + n]

    def _add_lost(self, zeta: Array, data: Array, angle: Array) -> None:
        """Each memory's moment of the dead time short pulses do not carry, over a chunk's
        transitions (rows ``[x_k, a_k, w_k]`` and their angles). A leg's pulse is short
        only where ``sqrt(3) |a_k| > V_dc - 2 v``: its room is at least ``1/2 -
        sqrt(3) |a_k| / (2 V_dc)`` of the period (space-vector duties), and short is
        within ``v / V_dc`` of none; elsewhere nothing is lost (and not computed)."""
        assert self.pulses is not None
        advance, bus = self.pulses
        n, m, v = self.n, self.m, self.dead_time_voltage
        applied = data[:, n : n + m]
        lost, rows = np.zeros((data.shape[0], 2)), np.zeros(0, dtype=np.intp)
        if v > 0.0 and 3.0 * float(np.max(np.sum(applied**2, axis=1))) > (bus - 2.0 * v) ** 2:
            lost = lost_signs(data[:, :n], applied, angle, advance, bus, v)
            rows = np.flatnonzero(np.any(lost != 0.0, axis=1))
        for memory in self._memories:
            memory.add_omitted(zeta, lost, rows)

    def _grown(self, count: int) -> Array:
        """A buffer with the waiting transitions and room for ``count`` more."""
        grown = self._buffer(max(PENDING_ROWS, self._waiting + count), None)
        grown[: self._waiting + 1] = self._rows[: self._waiting + 1]
        return grown

    def model(self, index: int = 0) -> DiscreteModel:
        """The model one memory's moments give now, with the covariance of
        ``vec([Ad, Bd, Ed])``.

        Parameters
        ----------
        index : int
            Which of :attr:`memories`.

        Raises
        ------
        numpy.linalg.LinAlgError
            If the data so far do not excite every regressor.
        """
        moments = self.moments[index]
        Theta, Sigma, covariance = moments.estimate()
        return self._discrete(moments, Theta, Sigma, covariance)

    def _discrete(
        self, moments: ForgettingMoments, Theta: Array, Sigma: Array, covariance: Array
    ) -> DiscreteModel:
        """The model of coefficients ``Theta`` from ``moments``' data."""
        n, m = self.n, self.m
        M = Theta.T  # (n, p): [Ad, Bd, Ed]
        return DiscreteModel(
            Ad=M[:, :n].copy(),
            Bd=M[:, n : n + m].copy(),
            Ed=M[:, n + m :].copy(),
            h=self.h,
            residual_rms=np.sqrt(np.maximum(np.diag(Sigma), 0.0)),
            relative_residual=float("nan"),
            condition=float(np.linalg.cond(moments.cross[:, : Theta.shape[0]])),
            transitions=moments.count,
            covariance=_row_major_covariance(covariance, Theta.shape),
        )

    def drift_free(self, recent: int, older: int) -> tuple[DiscreteModel, Array, Array, float]:
        """The model now, without the lag a steady drift leaves in a memory's estimate.

        A parameter that moves at a steady rate is estimated late by the mean age of the
        memory's weights (:attr:`~._moments.ForgettingMoments.age`: its time constant
        ``tau`` once full; a warming resistance, 0.4%/K, over a 2 s memory). Two
        memories of ages ``a < b`` are late by different amounts, so
        ``c_a Theta_a + c_b Theta_b`` with ``c_a = b / (b - a)``, ``c_b = -a / (b - a)``
        is not late at all (Brown's double smoothing). Its covariance is the older
        memory's times ``2 b (c_a^2 / (2 a) + c_b^2 / (2 b) + 2 c_a c_b / (a + b))``
        (white errors over steady excitation and full memories: 3.67 for ``b = 2 a``).
        Where the two ages are within 10% (both memories restarted from one), the older
        memory's model is returned as it is, with its lag.

        Parameters
        ----------
        recent, older : int
            The two memories (indices into :attr:`memories`, the first the shorter).

        Returns
        -------
        model : DiscreteModel
            The model now, with the covariance of ``vec([Ad, Bd, Ed])``.
        Theta : ndarray, shape (p, n)
            Its coefficients (``[Ad, Bd, Ed]'``).
        covariance : ndarray
            The covariance of ``vec(Theta)`` (column-major).
        lag : float
            How late the model is under a steady drift, s: 0, or the older memory's
            mean age where it is returned as it is.

        Raises
        ------
        numpy.linalg.LinAlgError
            If the data so far do not excite every regressor.
        """
        weights = self._drift_weights(recent, older)
        Theta_b, Sigma, covariance = self.moments[older].estimate()
        if weights is None:
            model = self._discrete(self.moments[older], Theta_b, Sigma, covariance)
            return model, Theta_b, covariance, self.moments[older].age * self.h
        Theta_a = self.moments[recent].coefficients()
        c_a, c_b = weights
        a, b = self.moments[recent].age, self.moments[older].age
        scale = 2 * b * (c_a**2 / (2 * a) + c_b**2 / (2 * b) + 2 * c_a * c_b / (a + b))
        Theta = c_a * Theta_a + c_b * Theta_b
        covariance = scale * covariance
        return self._discrete(self.moments[older], Theta, Sigma, covariance), Theta, covariance, 0.0

    def _drift_weights(self, recent: int, older: int) -> tuple[float, float] | None:
        """:meth:`drift_free`'s ``(c_a, c_b)``, or None where the ages are within 10%."""
        if not self.memories[recent] < self.memories[older]:
            raise InputError(f"memories: {recent} must be shorter than {older}")
        a, b = self.moments[recent].age, self.moments[older].age
        return (b / (b - a), -a / (b - a)) if b - a > 0.1 * b else None

    def omitted_shift(self, recent: int, older: int, effect: Array) -> Array:
        """How far the left-out effect of :meth:`_add_lost` moves :meth:`drift_free`'s
        coefficients: an error ``effect c_k`` in each transition (``effect`` (n, 2): the
        model's dead-time channels' gain with the opposite sign, ``v`` times the held
        vector's) moves a memory's IV estimate by ``G^-1 (sum w zeta c') effect'``, and
        the drift-free model by the same combination of its two memories'.

        Returns
        -------
        ndarray, shape (p, n)
            The shift of ``Theta`` (``[Ad, Bd, Ed]'``).
        """
        weights = self._drift_weights(recent, older)
        memories = (recent, older) if weights is not None else (older,)
        shift = np.zeros((self.moments[older].regressors, self.n))
        for index, weight in zip(memories, weights or (1.0,), strict=True):
            moments = self.moments[index]
            p = moments.regressors
            shift += weight * np.linalg.solve(moments.cross[:, :p], moments.omitted @ effect.T)
        return shift


@lru_cache(maxsize=8)
def _twice(count: int) -> NDArray[np.intp]:
    """Rows of a chunk's data for the signs of ``count`` transitions: ``x_k`` (first row)
    and ``x_(k-1)`` (second), both at row k's angle (the rotor's, computed once)."""
    now = np.arange(1, count + 1)
    twice = np.array([now, now - 1])
    twice.setflags(write=False)
    return twice


def _row_major_covariance(covariance: Array, shape: tuple[int, int]) -> Array:
    """The covariance of ``vec(Theta)`` (Theta (p, n), column-major) as that of
    ``vec(Theta')`` = ``vec([Ad, Bd, Ed])`` (column-major), the model's order."""
    return transposed_covariance(covariance, *shape)
