"""What makes a simulated drive realistic: :class:`DriveSettings` (see
:mod:`._realistic` for what each effect does to the data)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..core import finite_float, positive_finite, positive_integer
from ..errors import InputError
from ._inverter import COPPER_COEFFICIENT, MAGNET_COEFFICIENT
from ._pwm import dead_time_amplitude

__all__ = ["HARDWARE_LIKE", "DriveSettings"]

#: hardware_like: ``t_d f_sw V_dc`` (V), noise per phase (A rms), ADC bits and range (A).
HARDWARE_LIKE = {"dead_time_voltage": 2.0, "noise": 0.01, "adc_bits": 12, "adc_range": 50.0}


def _choice(value: object, name: str, allowed: tuple[str, ...]) -> None:
    if value not in allowed:
        raise InputError(f"{name}: expected one of {', '.join(map(repr, allowed))}, got {value!r}")


def _flag(value: object, name: str) -> None:
    if not isinstance(value, bool | np.bool_):
        raise InputError(f"{name}: expected True or False, got {value!r}")


@dataclass(frozen=True)
class DriveSettings:
    """What makes a simulated drive realistic (see the module docstring for the effects).

    Attributes
    ----------
    input_delay : int
        d, computation delay in samples (0, 1 or 2): the voltage computed at ``t_k`` is
        applied over ``[t_(k+d), t_(k+d+1))``.
    pwm : {"average", "carrier"}
        ``"average"``: the period-average voltage (the reference) minus the dead-time
        error; ``"carrier"``: center-aligned space-vector PWM, one carrier period per
        sample, propagated segment by segment (needs ``dc_voltage``).
    dead_time : float
        ``t_d``, s (needs ``dc_voltage``; less than half the sampling period); it acts
        with the sign of each true phase current at the start of each sample.
    dead_time_compensation : bool
        Add ``+t_d f_sw V_dc sign(i_phase)`` with the measured phase currents at the
        computation instant (so it is d samples old, and wrong near zero current).
    dc_voltage : float or None
        DC-bus voltage ``V_dc``, V; None: no voltage limit (no dead time, no carrier).
    current_noise : float
        Gaussian noise on each measured phase current, A rms.
    adc_bits : int or None
        ADC resolution, bits (1 to 32; needs ``adc_range``); None: no quantization.
    adc_range : float or None
        ADC full scale ``+-adc_range``, A (with ``adc_bits``).
    temperature_rise : float
        Winding and magnet temperature above the nameplate's, K (constant over the run).
    angle_compensation : bool
        Rotate the command by ``w_e (d + 1/2) h`` (``"stationary"`` hold) or keep it
        turning with the rotor (``"rotor"`` hold); without it the modulator uses
        ``theta_k``, the angle at the computation instant.
    logged_input : {"applied", "commanded"}
        Row k of the logged ``u``: the command applied over ``[t_k, t_(k+1))`` (computed at
        k - d; zeros before the first), or the command computed at k.
    voltage_hold : {"stationary", "rotor"}
        What the inverter holds over a sample: the ``alpha-beta`` vector (a PWM inverter,
        the realistic choice), or the dq vector (the ideal drive's zero-order hold; average
        PWM only).
    anti_windup : bool
        The controller's anti-windup: its integrators hold at the samples where the
        DC-bus limit scales its command (conditional integration, as the C code of
        ``selftune export`` does; :mod:`selftune.core._voltage_limit`); False: they
        integrate regardless. It acts only with ``dc_voltage``.
    encoder_counts : int or None
        The logged angle column is an encoder's reading: p times the mechanical angle in
        whole counts of ``2 pi / encoder_counts`` (counts a mechanical turn, 4 to
        2**32), wrapped; None: the exact angle. The controller turns its command with
        the exact angle (the drive's own angle observer is not modelled): only the log
        is quantized.

    Raises
    ------
    InputError
        Naming the field, if a value is out of range or a needed companion is missing.
    """

    input_delay: int = 1
    pwm: Literal["average", "carrier"] = "average"
    dead_time: float = 0.0
    dead_time_compensation: bool = False
    dc_voltage: float | None = None
    current_noise: float = 0.0
    adc_bits: int | None = None
    adc_range: float | None = None
    temperature_rise: float = 0.0
    angle_compensation: bool = True
    logged_input: Literal["applied", "commanded"] = "applied"
    voltage_hold: Literal["stationary", "rotor"] = "stationary"
    anti_windup: bool = False
    encoder_counts: int | None = None

    def __post_init__(self) -> None:
        delay = positive_integer(self.input_delay, "input_delay", minimum=0)
        if delay > 2:
            raise InputError(f"input_delay: must be 0, 1 or 2 samples, got {delay}")
        object.__setattr__(self, "input_delay", delay)
        _choice(self.pwm, "pwm", ("average", "carrier"))
        _choice(self.logged_input, "logged_input", ("applied", "commanded"))
        _choice(self.voltage_hold, "voltage_hold", ("stationary", "rotor"))
        for name in ("dead_time_compensation", "angle_compensation", "anti_windup"):
            _flag(getattr(self, name), name)
        for name in ("dead_time", "current_noise"):
            value = finite_float(getattr(self, name), name)
            if value < 0.0:
                raise InputError(f"{name}: must be >= 0, got {value!r}")
            object.__setattr__(self, name, value)
        if self.dc_voltage is not None:
            object.__setattr__(self, "dc_voltage", positive_finite(self.dc_voltage, "dc_voltage"))
        elif self.dead_time > 0.0 or self.pwm == "carrier":
            needs = "dead time" if self.dead_time > 0.0 else "carrier PWM"
            raise InputError(f"dc_voltage: {needs} needs the DC-bus voltage (V)")
        if self.voltage_hold == "rotor" and self.pwm == "carrier":
            raise InputError('voltage_hold: "rotor" needs pwm = "average" (a carrier holds duties)')
        self._check_adc()
        if self.encoder_counts is not None:
            counts = positive_integer(self.encoder_counts, "encoder_counts", minimum=4)
            if counts > 2**32:
                raise InputError(f"encoder_counts: at most 2**32 counts a turn, got {counts}")
            object.__setattr__(self, "encoder_counts", counts)
        rise = finite_float(self.temperature_rise, "temperature_rise")
        if 1.0 + COPPER_COEFFICIENT * rise <= 0.0 or 1.0 - MAGNET_COEFFICIENT * rise <= 0.0:
            raise InputError(
                f"temperature_rise: {rise!r} K makes R_s or phi_pm non-positive "
                f"(valid: {-1.0 / COPPER_COEFFICIENT:.1f} < dT < {1.0 / MAGNET_COEFFICIENT:.0f})"
            )
        object.__setattr__(self, "temperature_rise", rise)

    def _check_adc(self) -> None:
        if self.adc_bits is None:
            if self.adc_range is not None:
                raise InputError("adc_range: given without adc_bits (the ADC's resolution)")
            return
        bits = positive_integer(self.adc_bits, "adc_bits")
        if bits > 32:
            raise InputError(f"adc_bits: expected 1 to 32 bits, got {bits}")
        if self.adc_range is None:
            raise InputError("adc_range: adc_bits needs the ADC's full scale adc_range (A)")
        object.__setattr__(self, "adc_bits", bits)
        object.__setattr__(self, "adc_range", positive_finite(self.adc_range, "adc_range"))

    @property
    def adc_step(self) -> float | None:
        """The ADC's least significant bit, ``adc_range / 2**(adc_bits - 1)``, A (None
        without an ADC)."""
        if self.adc_bits is None or self.adc_range is None:
            return None
        return self.adc_range / 2 ** (self.adc_bits - 1)

    @property
    def current_resolution(self) -> float:
        """The standard deviation of a phase current's measurement error, A: the noise's
        and the ADC rounding's (a uniform error of one step, ``step / sqrt(12)``), taken
        as independent."""
        step = 0.0 if self.adc_step is None else self.adc_step
        return float(np.hypot(self.current_noise, step / np.sqrt(12.0)))

    def dead_time_voltage(self, h: float) -> float:
        """The dead time's voltage error per phase at one PWM period per sample,
        ``t_d V_dc / h``, V (0 without dead time or DC bus).

        Parameters
        ----------
        h : float
            Sampling period, the PWM period, s.
        """
        return dead_time_amplitude(self.dead_time, self.dc_voltage, h)

    @classmethod
    def ideal(cls) -> DriveSettings:
        """No delay, average PWM, dq hold, nothing else: the exact ideal drive.

        Reproduces :class:`~selftune.sim.SimulatedDrive` (and the paper's model) exactly
        while the reference's ``w_1`` is the true back-EMF ``p speed phi_pm`` (there the
        back-EMF is ``D w``; here it is always the motor's own).
        """
        return cls(input_delay=0, voltage_hold="rotor")

    @classmethod
    def hardware_like(cls, dc_voltage: float = 540.0, h: float = 1e-4) -> DriveSettings:
        """One-sample delay, carrier PWM, dead time, noise and a 12-bit ADC.

        The dead time gives ``t_d f_sw V_dc = 2 V`` at ``f_sw = 1 / h``; noise of
        10 mA rms per phase; a 12-bit ADC over +-50 A (24.4 mA per LSB).

        Parameters
        ----------
        dc_voltage : float
            DC-bus voltage, V.
        h : float
            The drive's sampling (and switching) period, s.
        """
        dc = positive_finite(dc_voltage, "dc_voltage")
        period = positive_finite(h, "h")
        return cls(
            input_delay=1,
            pwm="carrier",
            dead_time=HARDWARE_LIKE["dead_time_voltage"] * period / dc,
            dc_voltage=dc,
            current_noise=HARDWARE_LIKE["noise"],
            adc_bits=int(HARDWARE_LIKE["adc_bits"]),
            adc_range=HARDWARE_LIKE["adc_range"],
        )
