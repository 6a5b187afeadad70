"""A target of the bench, met or missed: what every study's verdict is made of."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["TargetOutcome"]


@dataclass(frozen=True)
class TargetOutcome:
    """One target of the bench, met or missed.

    Attributes
    ----------
    name_text : str
    target_text : str
        The target, in words.
    value_text : str
        What was measured.
    met : bool or None
        None when it could not be measured (``why_text`` says why).
    why_text : str
    """

    name_text: str
    target_text: str
    value_text: str
    met: bool | None
    why_text: str
