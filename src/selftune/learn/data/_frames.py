"""A drive's own log: its column names and units, and the phase frame, turned into
selftune's dq :class:`~._trajectory.Trajectory` (:func:`load_log`).

:class:`LogFormat` says where each quantity is (a :class:`LogColumn`: the file's column
and its unit as a scale and an offset to SI) and in which frame:

- the **currents**: ``i_d``, ``i_q`` (rotor frame), or the phase currents ``i_a``,
  ``i_b`` and optionally ``i_c`` (else ``i_c = -i_a - i_b``), turned into dq at the
  log's angle ``theta_k`` (amplitude-invariant Clarke and Park,
  :mod:`selftune.core._phases`; a common mode of three measured phases is dropped);
- the **voltages**: ``u_d``, ``u_q``, or the phase voltages ``u_a``, ``u_b``, ``u_c``,
  or the legs' duty cycles ``d_a``, ``d_b``, ``d_c`` (0 to 1) with the DC bus ``u_dc``:
  a two-level leg at duty ``d`` on the bus puts ``(d - 1/2) u_dc`` on its phase (about
  the bus's midpoint) on average over the PWM period, the convention of the library's
  inverter (:mod:`selftune.sim._inverter`, ``d_x = 1/2 + (v_x + v_0) / V_dc``; the
  zero sequence ``v_0`` is a common mode, dropped); turned into dq at the angle the
  drive modulated them with, ``theta_k + advance (theta_(k+1) - theta_k)`` (the angle
  unwrapped; the last row repeats the last step). A drive compensates its delay by
  turning its dq command forward; the library's realistic drive
  (:mod:`selftune.sim._realistic`, ``angle_compensation``) holds ``exp(j (theta_k +
  w_e h / 2)) u`` over sample k, so ``advance`` is 1/2 for a row's applied voltage and
  ``d + 1/2`` for the voltage logged when it was computed (d the input delay; the
  example's drive: 1.5); without compensation, ``-d`` and 0;
- the **references** ``w1 .. wq`` as written, and the **angle** (electrical, rad).

Every mistake is one line naming the file, the column, its ``[log]`` key and the row
(a CSV's line, an NPZ array's row from 0, a MAT vector's row from 1): a column the file
lacks (with the columns it has), a value that is not a finite number, times that do not
increase, a duty cycle outside [0, 1], a DC bus not positive, and an angle that does not
follow the phase voltages (:func:`check_angle_turns`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...core import Array
from ...core._phases import from_phases, phases_to_dq
from ...errors import DataFileError, InputError
from ._csv import load_csv_columns
from ._data_file import PathLike, build, file_error, quote
from ._io import file_format_of
from ._mat import load_mat_columns
from ._npz import load_npz_columns
from ._trajectory import Trajectory

__all__ = [
    "ANGLE_WINDOW",
    "LINE_PROMINENCE",
    "LogColumn",
    "LogFormat",
    "check_angle_turns",
    "load_log",
]

#: The keys of each frame's quantities, in the order the frames take them.
CURRENT_KEYS = {"dq": ("i_d", "i_q"), "phase": ("i_a", "i_b", "i_c")}
VOLTAGE_KEYS = {"dq": ("u_d", "u_q"), "phase": ("u_a", "u_b", "u_c"), "duty": ("d_a", "d_b", "d_c")}

#: Rows per window of the angle check (the whole log if it is shorter; none below 64).
ANGLE_WINDOW = 1024

#: How far the phase voltages' strongest line must stand above their spectrum's median
#: (power ratio) to be taken as the back-EMF's rotation: on the library's realistic drive
#: (2,000 rows at 10 kHz, 10.8 V of exploration) noise alone reaches 30, and slow
#: currents under the controller's gain up to 500 near 0 rad per row; the back-EMF at
#: 150 rad/s electrical stands at 2e4 to 8e4.
LINE_PROMINENCE = 1000.0


@dataclass(frozen=True)
class LogColumn:
    """Where one quantity of a drive's log is, and how its numbers become SI.

    Attributes
    ----------
    key : str
        The quantity (the ``[log]`` key): ``"time"``, ``"i_a"``, ``"d_a"``, ``"w1"``, ...
    column : str or None
        The file's column (a CSV header's name, an NPZ array's, a MAT variable's); None
        for a constant (``value``).
    scale : float
        SI units per file unit (``1e-3`` for mA or ms; A per count of an ADC).
    offset : float
        File units subtracted before scaling (an ADC's zero-current count).
    value : float or None
        The constant, in SI units, when ``column`` is None (a DC bus held at 540 V).
    """

    key: str
    column: str | None
    scale: float = 1.0
    offset: float = 0.0
    value: float | None = None

    def __post_init__(self) -> None:
        if (self.column is None) == (self.value is None):
            raise InputError(f"{self.key}: give a column or a constant value, not both or none")
        if not (np.isfinite(self.scale) and self.scale != 0.0 and np.isfinite(self.offset)):
            raise InputError(f"{self.key}: the scale must be finite and nonzero, the offset finite")


@dataclass(frozen=True)
class LogFormat:
    """What a drive's log holds and in which frame (see the module docstring).

    Attributes
    ----------
    time : LogColumn
        Sample times.
    currents : tuple of LogColumn
        ``i_d, i_q`` or ``i_a, i_b`` or ``i_a, i_b, i_c``.
    voltages : tuple of LogColumn
        ``u_d, u_q`` or ``u_a, u_b, u_c`` or ``d_a, d_b, d_c``.
    references : tuple of LogColumn
        ``w1 .. wq`` (may be empty).
    angle : LogColumn or None
        The electrical rotor angle; needed by phase-frame currents or voltages.
    dc_voltage : LogColumn or None
        ``u_dc``, needed by duty cycles (and only by them).
    advance : float
        Samples of the angle's step the voltages were modulated ahead of ``theta_k``
        (phase-frame voltages only).
    """

    time: LogColumn
    currents: tuple[LogColumn, ...]
    voltages: tuple[LogColumn, ...]
    references: tuple[LogColumn, ...] = ()
    angle: LogColumn | None = None
    dc_voltage: LogColumn | None = None
    advance: float = 0.0

    def __post_init__(self) -> None:
        current_keys = tuple(column.key for column in self.currents)
        if current_keys not in (
            CURRENT_KEYS["dq"],
            CURRENT_KEYS["phase"][:2],
            CURRENT_KEYS["phase"],
        ):
            raise InputError("currents: give i_d and i_q, or i_a, i_b and optionally i_c")
        voltage_keys = tuple(column.key for column in self.voltages)
        if voltage_keys not in VOLTAGE_KEYS.values():
            raise InputError("voltages: give u_d and u_q, or u_a, u_b and u_c, or d_a, d_b and d_c")
        for column in (self.time, self.angle, *self.currents, *self.voltages, *self.references):
            if column is not None and column.column is None:
                raise InputError(f"{column.key}: must be a column of the log, not a constant")
        if self.angle is None and (self.current_frame == "phase" or self.voltage_frame != "dq"):
            raise InputError("angle: missing: the phase frame needs the electrical rotor angle")
        if (self.dc_voltage is None) != (self.voltage_frame != "duty"):
            needs = (
                "missing: duty cycles need the DC-bus voltage"
                if self.dc_voltage is None
                else ("only duty cycles (d_a, d_b, d_c) need the DC-bus voltage")
            )
            raise InputError(f"u_dc: {needs}")
        if not np.isfinite(self.advance):
            raise InputError(f"advance: must be finite, got {self.advance!r}")

    @property
    def current_frame(self) -> str:
        """``"dq"`` or ``"phase"``."""
        return "dq" if self.currents[0].key == "i_d" else "phase"

    @property
    def voltage_frame(self) -> str:
        """``"dq"``, ``"phase"`` or ``"duty"``."""
        return next(
            frame for frame, keys in VOLTAGE_KEYS.items() if keys[0] == self.voltages[0].key
        )

    @property
    def dimensions(self) -> tuple[int, int, int]:
        """``(n, m, q)`` of the trajectory: 2 currents, 2 voltages, the references."""
        return 2, 2, len(self.references)

    def columns(self) -> list[LogColumn]:
        """Every quantity read from a column, in the order the format lists them."""
        given = [self.time, *self.currents, *self.voltages, *self.references]
        given += [item for item in (self.angle, self.dc_voltage) if item is not None]
        return [item for item in given if item.column is not None]


class _Values:
    """The columns a log's format reads, as arrays, and how a row is named in messages."""

    def __init__(self, path: Path, log: LogFormat) -> None:
        self.path = path
        wanted = list(dict.fromkeys(str(item.column) for item in log.columns()))
        suffix = file_format_of(path)
        self.place: Callable[[int], str]
        if suffix == ".csv":
            names, table = load_csv_columns(path)
            absent = [name for name in wanted if name not in names]
            if absent:
                item = next(c for c in log.columns() if c.column == absent[0])
                shown = ", ".join(quote(name, 24) for name in names[:16])
                more = ", ..." if len(names) > 16 else ""
                raise file_error(
                    path,
                    f"no column {quote(absent[0])} ([log] {item.key}); the header has "
                    f"{shown}{more}",
                )
            self.data = {name: table[:, names.index(name)] for name in wanted}
            self.place = lambda row: f"line {row + 2}"
        else:
            loader = load_npz_columns if suffix == ".npz" else load_mat_columns
            self.data = loader(path, wanted)
            first = 0 if suffix == ".npz" else 1
            self.place = lambda row: f"row {row + first}"
        lengths = {name: values.shape[0] for name, values in self.data.items()}
        rows = lengths[str(log.time.column)]
        for item in log.columns():
            if lengths[str(item.column)] != rows:
                raise self.error(
                    item, None, f"{lengths[str(item.column)]} rows, but the time column has {rows}"
                )
        self.rows = rows

    def error(self, item: LogColumn, row: int | None, message: str) -> DataFileError:
        """One line naming the file, the column, its key and the row."""
        where = "" if row is None else f", {self.place(row)}"
        return file_error(
            self.path, f"column {quote(str(item.column))} ([log] {item.key}){where}: {message}"
        )

    def __call__(self, item: LogColumn) -> Array:
        """The quantity in SI units: ``(value - offset) * scale``, or the constant."""
        if item.column is None:
            return np.full(self.rows, float(item.value or 0.0))
        raw = self.data[item.column]
        bad = np.flatnonzero(~np.isfinite(raw))
        if bad.size:
            raise self.error(item, int(bad[0]), f"not a finite number ({raw[bad[0]]!r})")
        return (raw - item.offset) * item.scale


def check_angle_turns(angle: Array, voltages: Array) -> tuple[int, float, float] | None:
    """Where the angle turns at another rate than the phase voltages, if it does.

    At speed the terminal voltage carries the back-EMF, which turns with the rotor: its
    stationary vector's strongest spectral line is at the electrical speed. In each
    window of :data:`ANGLE_WINDOW` rows whose line stands :data:`LINE_PROMINENCE` above
    the spectrum's median, the angle's mean step (rad per row) must be the line's
    frequency to within half a frequency bin of the window plus 10% (a speed changing
    within the window). A window without such a line (standstill, low speed, a log of
    under 64 rows) is not checked: nothing in it tells the angle.

    Parameters
    ----------
    angle : ndarray, shape (T,)
        Electrical angle at each row, rad.
    voltages : ndarray, shape (T, 3)
        The phase voltages, V (a common mode is dropped).

    Returns
    -------
    (row, step, line) or None
        The first row of the first window where they disagree, the angle's mean step
        and the voltages' line, rad per row; None where they agree.
    """
    rows = angle.shape[0]
    if rows < 64:
        return None
    width = min(rows, ANGLE_WINDOW)
    starts = list(range(0, rows - width + 1, width))
    if starts[-1] + width < rows:
        starts.append(rows - width)
    vectors = from_phases(voltages)
    frequencies = 2.0 * np.pi * np.fft.fftfreq(8 * width)
    for start in starts:
        power = np.abs(np.fft.fft(vectors[start : start + width], 8 * width)) ** 2
        peak = int(np.argmax(power))
        if power[peak] < LINE_PROMINENCE * float(np.median(power)):
            continue
        steps = np.diff(angle[start : start + width])
        step = float(np.angle(np.sum(np.exp(1j * steps))))
        line = float(frequencies[peak])
        if abs(line - step) > 0.5 * 2.0 * np.pi / width + 0.1 * abs(step):
            return start, step, line
    return None


def _modulation_angle(angle: Array, advance: float) -> Array:
    """``theta_k + advance (theta_(k+1) - theta_k)``, unwrapped; the last row repeats the
    last step."""
    unwrapped = np.unwrap(angle)
    steps = np.diff(unwrapped)
    steps = np.append(steps, steps[-1]) if steps.size else np.zeros(1)
    return unwrapped + advance * steps


def load_log(path: PathLike, log: LogFormat) -> Trajectory:
    """Read a drive's own log (``.csv``, ``.npz`` or ``.mat``) as selftune's dq trajectory.

    Parameters
    ----------
    path : str or os.PathLike
        The log: a CSV with a header of column names, an NPZ archive of 1-D arrays, or a
        MAT file of vectors, named as ``log`` says (other columns are not used; a CSV's
        must be numbers all the same).
    log : LogFormat
        Where each quantity is, its unit, its frame.

    Returns
    -------
    Trajectory
        ``t``, s; ``x = [i_d, i_q]``, A; ``u = [u_d, u_q]``, V; ``w`` the references;
        ``angle`` the electrical angle, rad, if the log has one.

    Raises
    ------
    DataFileError
        One line naming the file, the column, its ``[log]`` key and the row (see the
        module docstring).
    """
    target = Path(path)
    values = _Values(target, log)
    t = values(log.time)
    steps = np.diff(t)
    if np.any(~(steps > 0.0)):
        row = int(np.flatnonzero(~(steps > 0.0))[0]) + 1
        raise values.error(
            log.time,
            row,
            f"time {t[row]!r} s is not greater than {t[row - 1]!r} s; times must increase",
        )
    angle = None if log.angle is None else values(log.angle)
    currents = np.column_stack([values(item) for item in log.currents])
    if log.current_frame == "phase":
        if currents.shape[1] == 2:
            currents = np.column_stack([currents, -currents[:, 0] - currents[:, 1]])
        assert angle is not None  # LogFormat: the phase frame has an angle
        currents = phases_to_dq(currents, angle)
    voltages = np.column_stack([values(item) for item in log.voltages])
    if log.voltage_frame == "duty":
        assert log.dc_voltage is not None  # LogFormat: duties have a DC bus
        voltages = _duty_voltages(values, log, voltages)
    if log.voltage_frame != "dq":
        assert log.angle is not None and angle is not None
        wrong = check_angle_turns(angle, voltages)
        if wrong is not None:
            row, step, line = wrong
            raise values.error(
                log.angle,
                row,
                f"turns by {step:.4g} rad per row from here, but the phase voltages by "
                f"{line:.4g} (their strongest line, the back-EMF's): check its unit (rad or "
                "deg), its sign, and that it is the electrical angle (p times the mechanical)",
            )
        voltages = phases_to_dq(voltages, _modulation_angle(angle, log.advance))
    w = np.column_stack([values(item) for item in log.references]) if log.references else None
    return build(target, t, currents, voltages, w, angle)


def _duty_voltages(values: _Values, log: LogFormat, duties: Array) -> Array:
    """The phase voltages ``(d - 1/2) u_dc``, V, of the duty cycles; each duty in
    [0, 1] and the bus positive, or an error naming the column and the row."""
    assert log.dc_voltage is not None
    for index, item in enumerate(log.voltages):
        outside = np.flatnonzero((duties[:, index] < 0.0) | (duties[:, index] > 1.0))
        if outside.size:
            row = int(outside[0])
            raise values.error(
                item,
                row,
                f"duty cycle {duties[row, index]:.6g} outside [0, 1] (a percentage needs "
                'unit = "%", a timer\'s compare value unit = "counts" with scale = 1 / the '
                "period's counts)",
            )
    bus = values(log.dc_voltage)
    low = np.flatnonzero(~(bus > 0.0))
    if low.size:
        raise values.error(
            log.dc_voltage, int(low[0]), f"DC-bus voltage {bus[low[0]]:.6g} V is not positive"
        )
    return (duties - 0.5) * bus[:, np.newaxis]
