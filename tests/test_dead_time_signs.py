"""The dq vector of the phase currents' signs (selftune.learn.evidence._dead_time).

Truth: the signs of phase currents as a 12-bit ADC reads them (exact zeros included),
turned into dq by the core's Clarke and Park transforms; the part of it that short
pulses do not carry, against the simulator's carrier edges with and without dead time.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from example_counts import examples
from selftune.core._phases import (
    PHASE_DIRECTIONS,
    from_phases,
    phases_to_dq,
    space_vector_duties,
)
from selftune.learn.evidence._dead_time import phase_signs, sign_vector
from selftune.learn.evidence._pulses import lost_signs
from selftune.sim._pwm import carrier_edges

#: A 12-bit ADC's step over +-20 A, A (a power of 2: its sums are exact).
QUANTUM = 20.0 / 2048

#: How far two ways of computing the signs' vector may round apart: sums of three terms
#: of at most 2/3 and a rotation (3 eps measured); a sign that differs moves it by 2/3.
ROUNDED = 4.0 * np.finfo(float).eps

ANGLES = st.floats(-1e4, 1e4)
READINGS = st.lists(
    st.tuples(st.integers(-2048, 2047), st.integers(-2048, 2047), ANGLES), min_size=1,
    max_size=64,
)  # fmt: skip
CURRENTS = st.one_of(st.just(0.0), st.floats(-100.0, 100.0))


@examples(400, quick=60)
@given(READINGS)
def test_the_signs_are_those_of_the_phase_currents_an_adc_read(
    readings: list[tuple[int, int, float]],
) -> None:
    # i_a and i_b read, i_c = -i_a - i_b: a phase of exactly 0 A comes back from dq as
    # about 1e-16 of the current, which must count as 0, not as its rounding's sign
    counts = np.array([(a, b) for a, b, _ in readings], dtype=float)
    angle = np.array([angle for *_, angle in readings])
    phases = QUANTUM * np.column_stack([counts, -counts.sum(axis=1)])
    got = phase_signs(phases_to_dq(phases, angle), angle)
    np.testing.assert_allclose(got, phases_to_dq(np.sign(phases), angle), rtol=0, atol=ROUNDED)


@examples(200, quick=30)
@given(st.lists(st.tuples(CURRENTS, CURRENTS, ANGLES), min_size=1, max_size=64))
def test_one_sample_and_many_and_stacked_currents_give_the_same_vector(
    rows: list[tuple[float, float, float]],
) -> None:
    x = np.array([(d, q) for d, q, _ in rows])
    angle = np.array([angle for *_, angle in rows])
    got = phase_signs(x, angle)
    cos, sin = np.cos(angle).tolist(), np.sin(angle).tolist()
    each = [sign_vector(d, q, cos[k], sin[k]) for k, (d, q) in enumerate(x.tolist())]
    # a Python complex and an array's multiply round apart (by 1 ulp measured)
    np.testing.assert_allclose(got, np.array(each, dtype=float), rtol=0, atol=ROUNDED)
    arrays = sign_vector(x[:, 0], x[:, 1], np.cos(angle), np.sin(angle))
    np.testing.assert_array_equal(got, np.column_stack(arrays))
    stacked = phase_signs(np.stack([x, x[::-1]]), angle)
    np.testing.assert_array_equal(stacked, [got, phase_signs(x[::-1], angle)])


def test_the_lost_signs_are_the_dead_time_the_carrier_s_short_pulses_do_not_carry() -> None:
    """At and near the voltage limit (540 V bus, 0.5 us dead time at 10 kHz: v = 2.7 V) the
    dead time's mean voltage over a carrier period, read off the simulator's leg edges
    with it and without it, is ``-v (s - c)`` with ``s`` the phase signs' vector and ``c``
    the lost part, in dq, to rounding: the legs whose pulse or gap is shorter than the
    dead time lose only that, a leg held at 0 or 1 all of it. Below the limit's band,
    ``|u| <= (V_dc - 2 v) / sqrt(3)``, nothing is lost. The simulator propagates one
    period at a time, so a leg whose current flows in can delay its fall only to the
    period's end: it gains at most half the gap ``(1 - d) T`` that straddles the period's
    boundary, where the inverter gains all of it (the next period's rise is not moved);
    rows with such a leg whose gap is under ``2 t_d`` are compared with the halved room."""
    bus, period, dead = 540.0, 1e-4, 0.5e-6
    v, advance = dead * bus / period, 0.025
    rng = np.random.default_rng(5)
    count = 2000
    angle = rng.uniform(-np.pi, np.pi, count)
    x = rng.normal(0.0, 10.0, (count, 2))
    size = (
        bus
        / np.sqrt(3.0)
        * np.concatenate(
            [rng.uniform(0.99, 1.0, count - 100), np.full(50, 1.0), rng.uniform(0.0, 0.98, 50)]
        )
    )
    turn = rng.uniform(-np.pi, np.pi, count)
    a = np.column_stack([size * np.cos(turn), size * np.sin(turn)])
    lost = lost_signs(x, a, angle, advance, bus, v)
    signs = phase_signs(x, angle)
    modulated = (a[:, 0] + 1j * a[:, 1]) * np.exp(1j * (angle + advance))
    stationary = (x[:, 0] + 1j * x[:, 1]) * np.exp(1j * angle)
    carried = []
    for command, current in zip(modulated, stationary, strict=True):
        phase_signs_ = tuple(np.sign(np.real(current * np.exp(-2j * np.pi * np.arange(3) / 3))))
        widths = [
            np.array(
                [fall - rise for rise, fall in carrier_edges(command, bus, period, t, phase_signs_)]
            )
            for t in (dead, 0.0)
        ]
        carried.append(from_phases(bus * (widths[0] - widths[1]) / period))
    carried_dq = np.array(carried) * np.exp(-1j * angle)
    model = -v * ((signs[:, 0] - lost[:, 0]) + 1j * (signs[:, 1] - lost[:, 1]))
    duties = space_vector_duties(modulated, bus)
    inflowing = np.real(stationary[:, None] * np.conj(PHASE_DIRECTIONS)) < 0.0
    halved = np.any(inflowing & (0.0 < 1.0 - duties) & ((1.0 - duties) * period < 2 * dead), axis=1)
    assert 0 < np.sum(halved) < 0.2 * count
    np.testing.assert_allclose(carried_dq[~halved], model[~halved], rtol=0.0, atol=1e-9 * v)
    short = np.any(lost != 0.0, axis=1)
    assert np.sum(short & ~halved) >= 30 and np.sum(~short & ~halved) >= 30  # both kinds compared
    assert not np.any(short[size <= (bus - 2.0 * v) / np.sqrt(3.0)])


def test_the_dead_time_delays_every_pulse_by_half_of_it() -> None:
    """Off the voltage limit, the simulator's carrier period with dead time (a 2.5 mH,
    0.25 ohm motor, 540 V, 0.5 us) moves the current as the held command times
    ``pulse_delay_gain`` plus the dead-time voltage: the held model without the gain
    misses about 1e-4 A a period (median), with it 4% of that (at most 12%: where in
    the period the dead time's own slice falls, off the pulse's middle by up to ``d_x
    T / 2``, a term the size of ``v`` rather than of the command)."""
    from math import exp

    from selftune.learn.evidence._pulses import pulse_delay_gain
    from selftune.sim._pwm import carrier_sample, dead_time_voltage

    R_s, L_s, period, bus, dead = 0.25, 2.5e-3, 1e-4, 540.0, 0.5e-6
    decay = exp(-R_s / L_s * period)
    gain = pulse_delay_gain(R_s, L_s, dead)
    assert gain == pytest.approx(1.0 + R_s * dead / (2 * L_s), rel=1e-9)
    rng = np.random.default_rng(2)
    missed, left = [], []
    for _ in range(200):
        command = rng.uniform(20.0, 250.0) * np.exp(1j * rng.uniform(-np.pi, np.pi))
        signs = tuple(rng.choice([-1.0, 1.0], 3))
        edges = carrier_edges(command, bus, period, dead, signs)
        current, _ = carrier_sample(
            (R_s / L_s, R_s, 500.0, decay), 0j, edges, bus, period, 0j, 1 + 0j
        )
        error = dead_time_voltage(np.array([signs]), dead / period * bus)[0]
        held = (1.0 - decay) / R_s
        missed.append(abs(current - held * (command + error)))
        left.append(abs(current - held * (gain * command + error)))
    assert np.median(missed) > 5e-5
    assert np.median(left) <= 0.05 * np.median(missed)
    assert max(left) <= 0.15 * np.median(missed)
