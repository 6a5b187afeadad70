"""Make examples/data/drive_log_phases.csv: drive_log.csv as the drive's firmware would
write it in its own terms, and learn_phases.toml reads it back.

The same run as drive_log.csv (made by make_drive_log.py), in the phase frame and the
drive's own column names and units: the time in ms, the phase currents a and b in mA,
the legs' duty cycles (0 to 1) of a space-vector modulator on the DC bus, the bus
voltage, and the electrical angle in degrees. The drive (the library's realistic drive,
angle compensation on, one sample of delay) logged at row k the voltage it computed
there, which it applied over the next sample at the angle theta_k + 1.5 (theta_(k+1) -
theta_k): learn_phases.toml says so with advance = 1.5.

Run:  python examples/data/make_phase_log.py [OUT.csv]
then: selftune learn examples/data/drive_log_phases.csv --config examples/data/learn_phases.toml
"""

import sys
from pathlib import Path

import numpy as np

import selftune

HERE = Path(__file__).parent
DC_VOLTAGE = 540.0  # V, the bus of make_drive_log.py's drive
ADVANCE = 1.5  # samples: the drive's angle compensation for a voltage logged when computed


def phase_columns(log: selftune.Trajectory, advance: float = ADVANCE) -> dict[str, np.ndarray]:
    """The firmware's columns of a dq log with an angle: what its modulator and sensors
    saw, in its units."""
    angle = np.unwrap(log.angle)
    steps = np.append(np.diff(angle), np.diff(angle)[-1])
    current = (log.x[:, 0] + 1j * log.x[:, 1]) * np.exp(1j * angle)  # stationary, A
    u = np.vstack([log.u, log.u[-1:]])
    voltage = (u[:, 0] + 1j * u[:, 1]) * np.exp(1j * (angle + advance * steps))
    directions = np.exp(-2j * np.pi * np.arange(3) / 3)
    currents = np.real(current[:, None] * directions)  # amplitude-invariant phases
    phases = np.real(voltage[:, None] * directions)
    zero = -0.5 * (phases.max(axis=1) + phases.min(axis=1))  # min-max zero sequence
    duties = 0.5 + (phases + zero[:, None]) / DC_VOLTAGE
    return {
        "time_ms": 1e3 * log.t,
        "Ia_mA": 1e3 * currents[:, 0],
        "Ib_mA": 1e3 * currents[:, 1],
        "PWM_A": duties[:, 0],
        "PWM_B": duties[:, 1],
        "PWM_C": duties[:, 2],
        "Vbus": np.full(log.t.shape, DC_VOLTAGE),
        "theta_el_deg": np.rad2deg(log.angle),
        "emf_ref": log.w[:, 0],
        "torque_ref": log.w[:, 1],
    }


def write_csv(columns: dict[str, np.ndarray], path: Path) -> None:
    """A header of the names, then one row per sample, every value to the last digit."""
    rows = np.column_stack(list(columns.values())).tolist()
    lines = [",".join(columns), *(",".join(map(repr, row)) for row in rows)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


if __name__ == "__main__":
    log = selftune.load_trajectory(HERE / "drive_log.csv")
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "drive_log_phases.csv"
    write_csv(phase_columns(log), out)
    print(f"wrote {out}: {log.num_samples} samples in the phase frame")
