"""``selftune bench``: data, learning cost, simulation, self-tuning, drive rates, honesty, noise.

One module per study. Every comparison runs in one process on this machine;
:func:`run_bench` returns a typed :class:`BenchReport` (:mod:`._report`), which
:meth:`BenchReport.to_json` and :meth:`BenchReport.to_markdown` render for ``bench.json``
and ``bench.md``. Each field name carries its unit
(``offpolicy_seconds``, ``us_per_step``, ``cost_volt2_seconds``, ...), and the JSON keys
are the field names.

1. :func:`measure_data_efficiency` (:mod:`._data_efficiency`): seconds of motor data
   until ``||K - K*|| / ||K*|| <= 1e-4`` and ``||U - U*|| / ||U*|| <= 1e-4`` on the paper's case:
   the paper's on-policy Algorithm 2 (episodes of 5 ms) against the off-policy variant
   (one batch, as short as it can be, against the identifiability floor of 11 intervals).
2. :func:`measure_learning_cost` (:mod:`._learning_cost`): the customized learner
   against the general one of Gao & Jiang (2016) on the same data.
3. :func:`measure_simulation` (:mod:`._simulation`): microseconds per control step of
   the current loop at 10 us sampling: :func:`~selftune.sim.simulate` against scipy's ``solve_ivp``
   (RK45) and gym-electric-motor's PMSM environment (optional extra ``[bench]``), each
   checked against the exact solution; and a batch of 1,000 motors.
4. :func:`measure_self_tuning_value` (:mod:`._value`): the cost (5) of a torque step and
   the steady-state torque error when R_s, L_s and phi_pm are 30% off (8 motors): LQR +
   feedforward and PI
   designed on nominal values (and on nominal R_s, L_s with the measured flux), the
   self-tuned controllers (off-policy with the flux known; Algorithm 3 with it identified),
   and the true optimum.

5. :func:`measure_drive_rates` (:mod:`._drive_rates`): each learner's error against the
   sampling rate (5-50 kHz, one-sample delay, noise-free) on three motors, and the cost
   of running the continuous K* instead of the digital optimum at bandwidths f_s/40 to f_s/8.
6. :func:`measure_honesty` (:mod:`._honesty`): 220 logs of the realistic drive with the
   hazards of real logs (misaligned voltages, float32 and 7 digits, clock offsets, ADC,
   dead time, short logs), each classified correct, refused (by cause), silent wrong or
   destabilizing.
7. :func:`measure_noise` (:mod:`._noise_study`, targets and tables in
   :mod:`._noise_report`): the reference experiment at 10 and 20 kHz, 10 and 50 mA, 5 ms to
   2 s, 20 seeds (60 for the consistency ratios), every method: p90 errors, consistency,
   short logs, learning time.
8. :func:`measure_calibration` (:mod:`._calibration`): coverage of the stated standard
   errors on seeded motors no test uses.
9. :func:`measure_realistic_drive` (:mod:`._realistic_drive`): selftune on the realistic
   drive against identify-then-design, the industrial PI recipe and nominal designs,
   every controller given the same knowledge and data; Algorithm 3's flux.
10. :func:`measure_refusals` (:mod:`._refusals`): refusals and calibration on a corpus
    (:mod:`._corpus`) of five motors logged by the realistic drive and an independent
    exact dq simulator (noise, ADC, dead time), at several lengths and seeds:
    destabilizing results, results beyond 3 standard errors, entries within 1 and 3,
    false refusals, every refusal's message.
11. :func:`measure_online` (:mod:`._online`): the online tuner on three motors through a
    120 s warm-up and a loose connection, scored against the optimum of each instant;
    a recorded log replayed.
12. :func:`measure_fleet` (:mod:`._fleet`): 1,000 logs of a fleet of drives (20 motors
    x 50 units, 2 hot, 3 broken) learned serially and on a 2-worker Dask cluster:
    throughput, identical results, the outliers and broken logs named, the client's
    memory at two sizes.
13. :func:`measure_interior` (:mod:`._interior`): interior PM motors (25 uH to 100 mH)
    commissioned on the hardware-like drive: identified L_d, L_q and flux, the torque
    with MTPA, refusals.

Outside ``selftune bench`` (run alone, as docs/schedule.md says): :func:`measure_ramp`
(:mod:`._ramp`), speed schedules learned from 1 s over 5-100% of rated speed, and
:func:`measure_ramp_draws` the same on motors drawn at random (and
:func:`measure_interior_draws` study 13 on interior ones); and (as
docs/saturation.md says) :func:`measure_saturation` (:mod:`._saturation`), saturating
motors learned at several currents, the current schedule against the true pointwise
optimum from 10% to 100% of rated current (about 1.5 min of CPU a motor), and
:func:`measure_saturation_draws` the same on motors drawn at random.

Studies 6-8 run their seeded trials through the fleet's engine
(:func:`selftune.fleet.map_ordered`): here by default, on a cluster when
``selftune bench --scheduler`` gives one, with the same numbers.

The learners never see a model; the model-based optimum and the exact closed-form
solution are used only to score them.
"""

from __future__ import annotations

from ._calibration import Calibration, CalibrationMethod, CalibrationTrial, measure_calibration
from ._common import (
    CONTROLLERS,
    COST_HORIZON_SECONDS,
    EXACT_RELATIVE_ERROR,
    MISMATCH,
    TARGET_DATA_RATIO,
    TARGET_RELATIVE_ERROR,
    TARGET_SPEEDUP,
    BenchConfig,
)
from ._corpus import CorpusLog, CorpusMotor, RefusalsConfig
from ._data_efficiency import DataEfficiency, ErrorCurve, measure_data_efficiency
from ._drive_rates import DelayCost, DriveRates, RateErrors, measure_drive_rates
from ._fleet import FleetDesign, FleetStudy, FleetTruth, make_fleet, measure_fleet
from ._gem import GymElectricMotor
from ._honesty import HazardTally, Honesty, HonestyCase, HonestyOutcome, measure_honesty
from ._interior import (
    InteriorStudy,
    interior_targets,
    markdown_interior,
    measure_interior,
    measure_interior_draws,
)
from ._learning_cost import LearningCost, LearningDataset, LearningRun, measure_learning_cost
from ._loop import SimulatorMeasurement
from ._noise_study import ConsistencyRatio, NoiseCell, NoiseConfig, NoiseStudy, measure_noise
from ._online import (
    ONLINE_MOTORS,
    ONLINE_PROFILES,
    OnlineCase,
    OnlineReplay,
    OnlineStudy,
    markdown_online,
    measure_online,
)
from ._ramp import RampStudy, markdown_ramp, measure_ramp, measure_ramp_draws
from ._realistic_drive import (
    RealisticDriveComparison,
    markdown_realistic_drive,
    measure_realistic_drive,
)
from ._refusals import (
    BlockCalibration,
    BlockSummary,
    CorpusOutcome,
    Refusals,
    markdown_refusals,
    measure_refusals,
)
from ._report import BenchReport, DriveStudiesConfig, Environment, bench_command, run_bench
from ._saturation import (
    SaturationCase,
    SaturationStudy,
    markdown_saturation,
    measure_saturation,
    measure_saturation_draws,
)
from ._simulation import BatchMeasurement, Simulation, measure_simulation
from ._targets import TargetOutcome
from ._value import ControllerOutcome, MismatchCase, SelfTuningValue, measure_self_tuning_value

__all__ = [
    "CONTROLLERS",
    "COST_HORIZON_SECONDS",
    "EXACT_RELATIVE_ERROR",
    "MISMATCH",
    "ONLINE_MOTORS",
    "ONLINE_PROFILES",
    "TARGET_DATA_RATIO",
    "TARGET_RELATIVE_ERROR",
    "TARGET_SPEEDUP",
    "BatchMeasurement",
    "BenchConfig",
    "BenchReport",
    "BlockCalibration",
    "BlockSummary",
    "Calibration",
    "CalibrationMethod",
    "CalibrationTrial",
    "ConsistencyRatio",
    "ControllerOutcome",
    "CorpusLog",
    "CorpusMotor",
    "CorpusOutcome",
    "DataEfficiency",
    "DelayCost",
    "DriveRates",
    "DriveStudiesConfig",
    "Environment",
    "ErrorCurve",
    "FleetDesign",
    "FleetStudy",
    "FleetTruth",
    "GymElectricMotor",
    "HazardTally",
    "Honesty",
    "HonestyCase",
    "HonestyOutcome",
    "InteriorStudy",
    "LearningCost",
    "LearningDataset",
    "LearningRun",
    "MismatchCase",
    "NoiseCell",
    "NoiseConfig",
    "NoiseStudy",
    "OnlineCase",
    "OnlineReplay",
    "OnlineStudy",
    "RampStudy",
    "RateErrors",
    "RealisticDriveComparison",
    "Refusals",
    "RefusalsConfig",
    "SaturationCase",
    "SaturationStudy",
    "SelfTuningValue",
    "Simulation",
    "SimulatorMeasurement",
    "TargetOutcome",
    "bench_command",
    "interior_targets",
    "make_fleet",
    "markdown_interior",
    "markdown_online",
    "markdown_ramp",
    "markdown_realistic_drive",
    "markdown_refusals",
    "markdown_saturation",
    "measure_calibration",
    "measure_data_efficiency",
    "measure_drive_rates",
    "measure_fleet",
    "measure_honesty",
    "measure_interior",
    "measure_interior_draws",
    "measure_learning_cost",
    "measure_noise",
    "measure_online",
    "measure_ramp",
    "measure_ramp_draws",
    "measure_realistic_drive",
    "measure_refusals",
    "measure_saturation",
    "measure_saturation_draws",
    "measure_self_tuning_value",
    "measure_simulation",
    "run_bench",
]
