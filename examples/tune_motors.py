"""Self-tune three different motors with the off-policy variant and compare with the optimum.

Run:  python examples/tune_motors.py
"""

import selftune
from selftune.report import evaluate
from selftune.tuning import TuningSettings, run_algorithm

motors = {
    "paper": (selftune.SPMSM.paper(), 10.0, 10.0),
    "small servo": (selftune.SPMSM(R_s=1.2, L_s=0.012, phi_pm=0.08, p=4), 150.0, 2.5),
    "large": (selftune.SPMSM(R_s=0.2, L_s=0.05, phi_pm=0.9, p=3), 50.0, 40.0),
}
for name, (motor, speed, torque) in motors.items():
    settings = TuningSettings(speed=speed, torque=torque, input_hold=2)
    result = run_algorithm("offpolicy", motor, settings)
    check = evaluate(result, motor, settings)
    print(
        f"{name:>12}: {result.data_seconds * 1e3:.0f} ms of data, "
        f"Theta error {check.final_theta_error:.1e}, K error {check.K_error:.1e}, "
        f"U error {check.U_error:.1e}"
    )
