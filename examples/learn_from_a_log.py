"""Learn a drive's optimal current controller from a logged CSV, as from a real drive.

The log here is simulated (5 ms of the paper's motor under a rough initial controller,
with exploration and a perturbed torque reference); a real drive's log in the same CSV
format works the same way. Run:  python examples/learn_from_a_log.py
"""

from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

import selftune
from selftune.sim import held, uniform

motor = selftune.SPMSM.paper()
problem = motor.regulation_problem(speed=10.0)
w = motor.exogenous(speed=10.0, torque=10.0)
K0 = 20 * np.pi * np.eye(2)  # the initial controller of the drive, V/A

with TemporaryDirectory() as folder:
    log = Path(folder) / "drive_log.csv"
    data = selftune.simulate(
        problem.A, problem.B, D=problem.D, K=K0, X=-problem.F,
        exogenous=held(lambda t: w + np.column_stack([0 * t, 0.5 * np.cos(3e3 * t)])),
        exploration=uniform(1.0), h=1e-5, num_samples=500, input_hold=2, seed=1,
    )  # fmt: skip
    selftune.save_trajectory(data, log)  # header t,x1,x2,u1,u2,w1,w2

    # What the engineer has: the log, and C, E, F from the flux and pole pairs.
    logged = selftune.load_trajectory(log)
    Q, R = 1e3 * np.eye(2), np.eye(2)
    known = selftune.LearningProblem(Q, R, C=problem.C, E=problem.E, F=problem.F)
    learned = selftune.learn_regulator(logged, known, K0)

optimum = selftune.solve_optimal_regulation(problem, Q, R)
print(f"learned from {logged.duration * 1e3:.1f} ms of data in {learned.iterations} iterations")
print("K  =", learned.K.round(4).tolist(), " K* =", optimum.K.round(4).tolist())
print("U  =", learned.U.round(4).tolist(), " U* =", optimum.U.round(4).tolist())
error = np.linalg.norm(learned.theta - optimum.theta) / np.linalg.norm(optimum.theta)
print(f"||Theta - Theta*|| / ||Theta*|| = {error:.1e}")
