"""MOTOR.toml's optional ``[saturation]`` table: the simulated drive's motor saturates.

::

    [saturation]
    i_sat = 3.2     # A: the current scale of the knee (at least 1% of phi_pm / L_d)
    drop = 0.4      # the share of L_q that saturates, in [0, 1)
    cross = 0.1     # optional, >= 0: how much i_d loads the saturating path (default 0)

The analytic model :class:`selftune.sim.SaturationModel` (docs/saturation.md) on the
``[motor]`` table's inductances and flux, which become the unsaturated ones. It is the
truth the simulated drive runs, never the learner's knowledge: ``selftune tune`` then
commissions the motor over its current (:func:`selftune.tuning.commission_over_current`)
and writes the law scheduled over the q-axis current reference. It needs a ``[drive]``
table without ``temperature_rise`` (a heated saturating motor is not modelled: the flux
linkages are given at the operating temperature). With a ``[schedule]`` table the law is
also scheduled over speed and current together
(:func:`selftune.model.design_speed_current_schedule`).

A measured motor's saturation is a flux-map table instead (:class:`selftune.sim.FluxMap`)::

    [saturation]
    i_d = [-8.0, -4.0, 0.0, 4.0]              # A, strictly increasing, at least 4
    i_q = [-8.0, -4.0, 0.0, 4.0, 8.0]         # A, strictly increasing, at least 4
    psi_d = [[...], ...]                      # Wb, one row an i_d, one column an i_q
    psi_q = [[...], ...]                      # Wb, the same shape

``psi_d`` rises strictly along ``i_d``, ``psi_q`` along ``i_q``. The map is then the
simulated motor's flux linkages (the ``[motor]`` table's R_s and pole pairs beside it);
its inductances and flux stay the nameplate the commissioning starts from. The keys of
one form only.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..errors import InputError
from ..model import Motor
from ._toml import ConfigTable

if TYPE_CHECKING:  # selftune solve loads no simulator
    from ..sim import DriveSettings, FluxMap, Saturation

__all__ = ["SATURATION_KEYS", "saturation_model"]

#: The analytic model's keys of MOTOR.toml's [saturation] table.
ANALYTIC_KEYS = ("i_sat", "drop", "cross")

#: A flux map's keys of the table.
FLUX_MAP_KEYS = ("i_d", "i_q", "psi_d", "psi_q")

#: The keys of MOTOR.toml's [saturation] table (one form's).
SATURATION_KEYS = (*ANALYTIC_KEYS, *FLUX_MAP_KEYS)


def saturation_model(table: ConfigTable, motor: Motor, drive: DriveSettings | None) -> Saturation:
    """The saturation of a ``[saturation]`` table: the analytic model on ``motor``'s
    inductances and flux, or a flux map.

    Parameters
    ----------
    table : ConfigTable
        The table.
    motor : SPMSM or IPMSM
        The unsaturated motor of the ``[motor]`` table.
    drive : DriveSettings or None
        The ``[drive]`` table's drive (required).

    Raises
    ------
    DataFileError
        Naming the file, the table and the key: a missing or bad value, both forms' keys,
        no ``[drive]`` table, or a ``[drive] temperature_rise``.
    """
    from ..sim import SaturationModel  # a saturating drive's file loads the simulator

    if drive is None:
        raise table.error(
            None,
            "a saturating motor runs on a realistic drive: add a [drive] table (e.g. "
            "switching_frequency = 10000.0, input_delay = 1, dc_voltage = 540.0)",
        )
    if drive.temperature_rise != 0.0:
        raise table.error(
            None,
            f"[drive] temperature_rise = {drive.temperature_rise:g} K: a heated saturating "
            "motor is not modelled; give the motor at its operating temperature and leave "
            "temperature_rise out",
        )
    mapped = [key for key in FLUX_MAP_KEYS if key in table.data]
    if mapped:
        analytic = [key for key in ANALYTIC_KEYS if key in table.data]
        if analytic:
            raise table.error(
                analytic[0],
                f"the analytic model's keys ({', '.join(ANALYTIC_KEYS)}) or a flux map's "
                f"({', '.join(FLUX_MAP_KEYS)}), not both",
            )
        return _flux_map(table)
    i_sat = table.positive("i_sat")
    values = {
        name: table.number(name, 0.0 if name == "cross" else None) for name in ("drop", "cross")
    }
    try:
        return SaturationModel.of(motor, i_sat=i_sat, **values)
    except InputError as exc:
        key, _, reason = str(exc).partition(": ")
        raise table.error(key if key in SATURATION_KEYS else None, reason or str(exc)) from None


def _flux_map(table: ConfigTable) -> FluxMap:
    """The flux map of the table's ``i_d``, ``i_q``, ``psi_d`` and ``psi_q``."""
    from ..sim import FluxMap

    i_d, i_q = table.vector("i_d"), table.vector("i_q")
    psi_d, psi_q = table.matrix("psi_d", (None, None)), table.matrix("psi_q", (None, None))
    try:  # the map judges its grid, then the flux linkages' shape on it
        return FluxMap(i_d, i_q, psi_d, psi_q)
    except InputError as exc:
        key, _, reason = str(exc).partition(": ")
        raise table.error(key if key in FLUX_MAP_KEYS else None, reason or str(exc)) from None
