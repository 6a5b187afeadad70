"""A batch on which ADP's policy iteration fails falls back to identify-then-design.

No log of the tests' drives breaks policy iteration (20 noisy logs tried), so the
failure is injected where the digital learner raises it; what is tested is what the
pipeline does with it: the controller designed from the same output-error model as
``method = "identify"`` designs from, that method and a note saying why in the result,
and the failure itself where no model exists to fall back on.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import selftune
import selftune.learn._pipeline as pipeline
from selftune.errors import PolicyIterationFailure
from selftune.learn import LearningOptions, LearningProblem, learn_controller
from selftune.tuning import run_algorithm

DATA = Path(__file__).resolve().parents[1] / "examples" / "data"

#: The README's problem and options for its log.
PROBLEM = LearningProblem(
    Q=1e3 * np.eye(2), R=np.eye(2), C=np.eye(2),
    F=np.array([[0.0, 0.0], [0.0, -2 / (3 * 3 * 0.35)]]), integral_action=True,
)  # fmt: skip
OPTIONS = LearningOptions(target="digital", input_delay=1, logged_input="commanded", dead_time=True)


def _failing(*args: object, **kwargs: object) -> object:
    raise PolicyIterationFailure(
        "digital policy iteration step 3: the learned P is not positive semidefinite",
        step=3,
        symptom="P not positive semidefinite",
    )


def test_a_failed_policy_iteration_falls_back_to_the_model(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    log = selftune.load_trajectory(DATA / "drive_log.csv")
    identified = learn_controller(log, PROBLEM, np.eye(2), replace(OPTIONS, method="identify"))
    monkeypatch.setattr(pipeline, "_digital_adp", _failing)
    learned = learn_controller(log, PROBLEM, np.eye(2), OPTIONS)
    assert learned.method == "identify"
    np.testing.assert_array_equal(learned.K, identified.K)
    np.testing.assert_array_equal(learned.U, identified.U)
    assert any(
        "policy iteration failed on this batch" in note and "step 3" in note
        for note in learned.quality.notes
    )


def test_without_a_model_the_failure_is_the_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    log = selftune.load_trajectory(DATA / "drive_log.csv")
    real = pipeline._precise

    def without_fit(*args: object, **kwargs: object) -> object:
        evidence, known, errors = real(*args, **kwargs)  # type: ignore[arg-type]
        return replace(evidence, fit=None), known, errors

    monkeypatch.setattr(pipeline, "_precise", without_fit)
    monkeypatch.setattr(pipeline, "_digital_adp", _failing)
    with pytest.raises(PolicyIterationFailure, match="step 3"):
        learn_controller(log, PROBLEM, np.eye(2), OPTIONS)


def test_a_tuning_session_keeps_the_model_designed_controller(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The off-policy session on the README's motor: the fallback's result has no
    policy-iteration steps to list (it had crashed reading the first) and says why."""
    monkeypatch.setattr(pipeline, "_digital_adp", _failing)
    monkeypatch.setattr(pipeline, "_continuous_adp", _failing)
    result = run_algorithm("offpolicy", selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3))
    assert result.history == ()
    assert any("policy iteration failed on this batch" in note for note in result.quality.notes)


def test_a_k0_that_does_not_stabilize_the_data_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    """Policy iteration fails from a K0 that destabilizes the fitted loop: the cause is
    K0 (a user's input), so nothing is designed and the refusal says so."""
    log = selftune.load_trajectory(DATA / "drive_log.csv")
    monkeypatch.setattr(pipeline, "_digital_adp", _failing)
    with pytest.raises(PolicyIterationFailure, match="K0 does not stabilize the loop the data"):
        learn_controller(log, PROBLEM, -100.0 * np.eye(2), OPTIONS)
