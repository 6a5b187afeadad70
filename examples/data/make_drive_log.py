"""Make examples/data/drive_log.csv: 0.2 s of a drive's log, as a real drive would log it.

The library's realistic drive (selftune.sim.RealisticDrive, the hardware_like settings):
10 kHz sampling and PWM, a one-sample computation delay, carrier PWM on a 540 V bus with
2 V of dead time, 10 mA of current noise, a 12-bit ADC. The motor is unknown to the
learner; the log holds what the drive's firmware would record at each sample: the time,
the measured dq currents, the dq voltage it COMMANDED at that sample (applied one sample
later), the reference w = [p speed phi_pm, T*] and the rotor angle. The drive runs a
gentle initial controller (K0, the back-EMF fed forward from the known flux) with
exploration on the voltages, while the torque reference steps through +-T* and +-T*/3.

Run:  python examples/data/make_drive_log.py [OUT.csv [SAMPLES]]
It rewrites drive_log.csv next to this script (or writes OUT.csv, of SAMPLES samples
instead of 2,000: 40000 for 4 s); learn.toml is the
configuration that goes with it:
selftune learn examples/data/drive_log.csv --config examples/data/learn.toml
"""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

import selftune
from selftune.core import ControlLaw
from selftune.sim import DriveSettings, RealisticDrive, held, uniform

HERE = Path(__file__).parent
motor = selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)  # unknown to the learner
speed, torque, h = 50.0, 5.0, 1e-4  # rad/s (150 rad/s electrical), N m, s
settings = replace(DriveSettings.hardware_like(h=h), logged_input="commanded")
drive = RealisticDrive(motor, speed, h, settings)

w = motor.exogenous(speed, torque)  # [p speed phi_pm, T*], what the firmware knows
F = motor.regulation_problem(speed).F  # i_q* = 2 T* / (3 p phi_pm)
K0 = 1.0 * np.eye(2)  # V/A: gentle, stable with the delay
U0 = np.array([[0.0, 0.0], [1.0, 0.0]])  # u_q += p speed phi_pm: the back-EMF fed forward
levels = np.array([1.0, 1.0 / 3.0, -1.0 / 3.0, -1.0])


def reference(t: np.ndarray) -> np.ndarray:
    """w with the torque stepping through the levels, 10 ms each."""
    level = levels[np.floor(t / 0.01).astype(int) % levels.size]
    return np.column_stack([np.full_like(t, w[0]), level * torque])


log = drive.run(
    ControlLaw.regulator(K0, -F, U0),
    held(reference),
    num_samples=int(sys.argv[2]) if len(sys.argv) > 2 else 2000,
    exploration=uniform(10.8),  # +-2% of the bus on each voltage, every sample
    seed=2026,
)
out = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "drive_log.csv"
selftune.save_trajectory(log, out)  # header t,x1,x2,u1,u2,w1,w2,theta
print(f"wrote {out}: {log.num_samples} samples, {log.duration:g} s")
