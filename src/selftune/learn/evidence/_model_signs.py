"""The dead-time model judged on the signs of its own currents.

With the dead time modelled, the channels hold the measured phase currents' signs, which
the noise decides where a phase current is within it of zero. Each wrong sign is a
voltage error of ``2 v`` on that phase for a sample, which the model's simulation
carries for a time constant of the plant: output errors correlated in time, which the
consistency and structure tests read as an effect the model misses. Before refusing,
:func:`~._evidence.gather_evidence` judges the model refitted on the signs of its own
noise-free currents (:func:`on_model_signs`) where those explain the data better.
"""

from __future__ import annotations

import numpy as np

from ._dead_time import DeadTimeChannels, with_signs_of
from ._output_error import OutputErrorFit, fit_output_error
from ._sign_bias import model_currents

__all__ = ["MODEL_SIGN_ROUNDS", "log_det", "on_model_signs"]


#: The most refits on the signs of the model's own currents (:func:`on_model_signs`):
#: each moves the signs of the few samples whose simulated phase current changed its
#: sign; on 0.2 s logs of the hardware-like drive the second changed none.
MODEL_SIGN_ROUNDS = 3


def on_model_signs(
    channels: DeadTimeChannels, shift: int, fit: OutputErrorFit, resolution: float
) -> tuple[DeadTimeChannels, OutputErrorFit] | None:
    """The logs with the dead-time channels on the signs of the fitted model's own
    noise-free currents (:func:`~._dead_time.with_signs_of`,
    :func:`~._sign_bias.model_currents`) and the fit on them, refitted from ``fit``
    on the signs of each refit's currents while that explains the data better (a
    smaller determinant of the output errors' covariance: a larger likelihood, with as
    many parameters), at most :data:`MODEL_SIGN_ROUNDS` times; None when the first
    does not."""
    best: tuple[DeadTimeChannels, OutputErrorFit] | None = None
    for _ in range(MODEL_SIGN_ROUNDS):
        current = (channels, fit) if best is None else best
        trial = with_signs_of(channels, model_currents(current[1], current[0], shift))
        pairs = zip(trial.episodes, current[0].episodes, strict=True)
        if best is not None and all(
            np.array_equal(np.asarray(a.w), np.asarray(b.w)) for a, b in pairs
        ):
            break  # the refit's currents have the signs it was fitted on
        refit = fit_output_error(
            trial.episodes, shift, current[1].model, fit.structure, resolution=resolution
        )
        if refit is None or log_det(refit) >= log_det(current[1]):
            break
        best = (trial, refit)
    return best


def log_det(fit: OutputErrorFit) -> float:
    """``log det`` of the fit's output errors' covariance."""
    return float(np.linalg.slogdet(fit.noise_covariance)[1])
