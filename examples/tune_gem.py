"""Self-tune a gym-electric-motor (GEM) PMSM current loop with selftune, and compare.

An RL user's plant: GEM's continuous current-control PMSM environment, run sample by
sample by selftune.sim.GemDrive (pip install 'selftune[gem]'). selftune's off-policy
session learns the optimal digital servo controller of that loop from 50 ms of its
samples, told only p, the speed, the torque reference and the flux; the result is then
compared with the model-based optimum of the same sampled loop, and run on GEM.

Run:  python examples/tune_gem.py
"""

import numpy as np

import selftune
from selftune.report import evaluate
from selftune.sim import GemDrive
from selftune.tuning import TuningSettings, offpolicy

motor = selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
speed, torque, h = 50.0, 5.0, 1e-4  # rad/s, N m, s (10 kHz)
drive = GemDrive(motor, speed, h, input_delay=1)  # a one-sample computation delay
settings = TuningSettings(
    speed=speed,
    torque=torque,
    h=h,
    episode_length=0.05,
    K0=1.0 * np.eye(2),  # V/A: a gentle initial controller
    exploration=10.0,  # V
    input_hold=1,
    perturbation="steps",  # the torque reference steps through +-T*, +-T*/3
    target="digital",
    integral_action=True,
)
result = offpolicy(drive, settings, motor.phi_pm)
check = evaluate(result, motor, settings)  # the optimum of the same loop (dq hold, delay 1)
print(result.law.equations())
print("K   =", result.K.round(3).tolist())
print("K_i =", result.law.K_i.round(1).tolist() if result.law.K_i is not None else None)
print(f"from {result.data_seconds * 1e3:.0f} ms of GEM samples: K error {check.K_error:.1e}, "
      f"U error {check.U_error:.1e}, excess cost {check.excess_cost:.1e}")

# the learned controller on GEM: the torque step from rest
w = np.array([motor.p * speed * motor.phi_pm, torque])
step = drive.run(result.law, selftune.sim.constant(w), num_samples=1000, exploration=None, seed=0)
print(f"GEM torque after 100 ms: {motor.torque(step.x[-1, 1]):.4f} N m (reference {torque} N m)")
