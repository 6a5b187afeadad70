"""The dq vector of the phase currents' signs (selftune.learn.evidence._dead_time).

Truth: the signs of phase currents as a 12-bit ADC reads them (exact zeros included),
turned into dq by the core's Clarke and Park transforms.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from example_counts import examples
from selftune.core._phases import phases_to_dq
from selftune.learn.evidence._dead_time import phase_signs, sign_vector

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
