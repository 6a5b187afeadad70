"""Study 12: a fleet of drives on the distributed engine (issue 20).

The realistic fleet (:func:`make_fleet`): 20 motors no test uses (R_s 0.3-1.2 ohm, L_s
4-12 mH, phi_pm 0.25-0.45 Wb, p = 3, 50 rad/s) x 50 units, each unit's R_s, L_s and
phi_pm within +-5% of its motor's (uniform), two units with R_s +30% (a hot winding),
three logs deliberately broken (not a CSV, no rows, NaN rows); a log of 0.2 s of the
hardware-like drive (10 kHz, carrier PWM on 540 V, 2 V of dead time, 10 mA of noise, a
12-bit ADC) per unit, the torque stepping through +-T* and +-T*/3 (T* for 9.5 A); a
manifest with each motor's nameplate feedforward F and gentle K0 as per-drive overrides
of one configuration (identify-then-design with the SPMSM structure, the dead time
modelled: R_s, L_s, phi_pm and the dead-time voltage with standard errors).

:func:`measure_fleet` learns it serially and on a local cluster of 2 workers and
reports the throughput ratio, whether the two tables are identical (every column but
the time taken), the drives named in the summary against the truth, and the client's
peak memory (``ru_maxrss`` of a fresh process running the fleet on the cluster) at two
fleet sizes.
"""

from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..core import ControlLaw
from ..core._atomic import atomic_path
from ..errors import InputError
from ..fleet import (
    RESULT_COLUMNS,
    ResultsTable,
    fleet_client,
    map_ordered,
    read_manifest,
    require_extra,
    run_fleet,
)
from ..model import SPMSM
from ..sim import DriveSettings, RealisticDrive, held, uniform
from ._common import table
from ._targets import TargetOutcome

__all__ = [
    "FLEET_SEED",
    "TARGET_THROUGHPUT",
    "FleetDesign",
    "FleetStudy",
    "FleetTruth",
    "client_run",
    "fleet_targets",
    "make_fleet",
    "markdown_fleet",
    "measure_fleet",
]

#: The generator seed of the fleet's motors, units, hot and broken logs.
FLEET_SEED = 20_020

#: Sampling period, s; mechanical speed, rad/s; pole pairs; the q current of T*, A.
_H, _SPEED, _POLES, _CURRENT = 1e-4, 50.0, 3, 9.5

#: The broken logs' kinds, in order.
BROKEN_KINDS = ("not a CSV", "no rows", "NaN rows")

_CONFIG = """\
# selftune fleet's configuration of the bench's fleet: identify-then-design with the
# SPMSM structure, the dead time modelled; K0 and F are each motor's (the manifest).
[cost]
Q = [[1000.0, 0.0], [0.0, 1000.0]]
R = [[1.0, 0.0], [0.0, 1.0]]
[policy]
K0 = [[1.0, 0.0], [0.0, 1.0]]
[regulation]
C = [[1.0, 0.0], [0.0, 1.0]]
E = [[0.0, 0.0], [0.0, 0.0]]
F = [[0.0, 0.0], [0.0, -0.6]]
[learning]
target = "digital"
input_delay = 1
logged_input = "commanded"
integral_action = true
dead_time = true
method = "identify"
structure = "spmsm"
electrical_speed = {speed}
"""


@dataclass(frozen=True)
class FleetDesign:
    """The size of a fleet.

    Attributes
    ----------
    motors_count : int
        Motors (groups).
    units_count : int
        Units (drives) of each motor.
    hot_count : int
        Units with R_s +30%.
    broken_count : int
        Broken logs (at most 3: :data:`BROKEN_KINDS`).
    seconds : float
        Each log's length, s.
    seed : int
        The generator seed of the motors, units, hot units and broken logs.
    """

    motors_count: int = 20
    units_count: int = 50
    hot_count: int = 2
    broken_count: int = 3
    seconds: float = 0.2
    seed: int = FLEET_SEED

    @property
    def logs_count(self) -> int:
        """Logs of the fleet."""
        return self.motors_count * self.units_count


@dataclass(frozen=True)
class FleetTruth:
    """What the fleet's logs are.

    Attributes
    ----------
    manifest : str
        The manifest CSV.
    config : str
        The configuration.
    hot_drives : tuple of str
        The units with R_s +30%.
    broken_drives : tuple of str
        The broken logs' drives (kinds as :data:`BROKEN_KINDS`).
    """

    manifest: str
    config: str
    hot_drives: tuple[str, ...]
    broken_drives: tuple[str, ...]


@dataclass(frozen=True)
class _Unit:
    path: str
    motor: SPMSM
    phi_nameplate: float
    torque: float
    seconds: float
    seed: int
    broken: str


def _write_log(unit: _Unit) -> None:
    """A unit's log of the hardware-like drive (or a broken file)."""
    from ..learn import save_trajectory

    path = Path(unit.path)
    if unit.broken == "not a CSV":
        with atomic_path(path) as temporary:
            temporary.write_bytes(np.random.default_rng(unit.seed).bytes(4096))
        return
    settings = replace(DriveSettings.hardware_like(h=_H), logged_input="commanded")
    drive = RealisticDrive(unit.motor, _SPEED, _H, settings)
    w1 = _POLES * _SPEED * unit.phi_nameplate  # the back-EMF the firmware assumes
    F = -2.0 / (3.0 * _POLES * unit.phi_nameplate)
    levels = np.array([1.0, 1.0 / 3.0, -1.0 / 3.0, -1.0])

    def reference(t: np.ndarray) -> np.ndarray:
        level = levels[np.floor(t / 0.01).astype(int) % levels.size]
        return np.column_stack([np.full_like(t, w1), level * unit.torque])

    K0 = _gentle_K0(unit.motor.L_s)
    law = ControlLaw.regulator(
        K0, -np.array([[0.0, 0.0], [0.0, F]]), np.array([[0.0, 0.0], [1.0, 0.0]])
    )
    log = drive.run(
        law, held(reference), num_samples=round(unit.seconds / _H),
        exploration=uniform(10.8), seed=unit.seed,
    )  # fmt: skip
    save_trajectory(log, path)
    if unit.broken == "no rows":
        header = path.read_text(encoding="utf-8").splitlines()[0]
        path.write_text(header + "\n", encoding="utf-8")
    elif unit.broken == "NaN rows":
        lines = path.read_text(encoding="utf-8").splitlines()
        for index in range(100, 120):
            fields = lines[index].split(",")
            lines[index] = ",".join([fields[0], *["nan"] * (len(fields) - 1)])
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _gentle_K0(L_s: float) -> np.ndarray:
    """1.25% of the deadbeat gain L_s / h: stable with a one-sample delay."""
    return 0.0125 * L_s / _H * np.eye(2)


def _matrix(value: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{v:.12g}" for v in row) + "]" for row in value) + "]"


def make_fleet(directory: str | Path, design: FleetDesign, client: Any = None) -> FleetTruth:
    """Write the fleet's logs, its configuration and its manifest into ``directory``.

    Parameters
    ----------
    directory : str or Path
        Where (created).
    design : FleetDesign
        Its size.
    client : distributed.Client, optional
        Make the logs on its cluster (default: here).

    Returns
    -------
    FleetTruth
    """
    home = Path(directory)
    (home / "logs").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(design.seed)
    motors = [
        SPMSM(
            R_s=float(rng.uniform(0.4, 0.9)),
            L_s=float(rng.uniform(5e-3, 10e-3)),
            phi_pm=float(rng.uniform(0.28, 0.40)),
            p=_POLES,
        )
        for _ in range(design.motors_count)
    ]
    ids = [(i, j) for i in range(design.motors_count) for j in range(design.units_count)]
    chosen = rng.choice(len(ids), size=design.hot_count + design.broken_count, replace=False)
    hot = {ids[k] for k in chosen[: design.hot_count]}
    kinds = zip(chosen[design.hot_count :], BROKEN_KINDS, strict=False)
    broken = {ids[k]: kind for k, kind in kinds}
    units, rows = [], ["path,drive,group,policy.K0,regulation.F"]
    for i, j in ids:
        nominal = motors[i]
        factors = rng.uniform(0.95, 1.05, size=3)
        R_s = nominal.R_s * factors[0] * (1.3 if (i, j) in hot else 1.0)
        motor = SPMSM(R_s=R_s, L_s=nominal.L_s * factors[1], phi_pm=nominal.phi_pm * factors[2],
                      p=_POLES)  # fmt: skip
        drive = f"m{i:02d}-u{j:02d}"
        path = home / "logs" / f"motor{i:02d}" / f"{drive}.csv"
        path.parent.mkdir(exist_ok=True)
        torque = 1.5 * _POLES * nominal.phi_pm * _CURRENT
        units.append(_Unit(os.fspath(path), motor, nominal.phi_pm, torque, design.seconds,
                           design.seed + 1000 * i + j, broken.get((i, j), "")))  # fmt: skip
        F = np.array([[0.0, 0.0], [0.0, -2.0 / (3.0 * _POLES * nominal.phi_pm)]])
        rows.append(
            f"logs/motor{i:02d}/{drive}.csv,{drive},motor{i:02d},"
            f'"{_matrix(_gentle_K0(nominal.L_s))}","{_matrix(F)}"'
        )
    map_ordered(_write_log, units, client)
    config = home / "fleet.toml"
    config.write_text(_CONFIG.format(speed=_POLES * _SPEED), encoding="utf-8")
    manifest = home / "manifest.csv"
    manifest.write_text("\n".join(rows) + "\n", encoding="utf-8")
    name = {(i, j): f"m{i:02d}-u{j:02d}" for i, j in ids}
    return FleetTruth(
        os.fspath(manifest), os.fspath(config),
        tuple(sorted(name[k] for k in hot)),
        tuple(name[k] for k in broken),
    )  # fmt: skip


@dataclass(frozen=True)
class FleetStudy:
    """Study 12's results (see the module).

    Attributes
    ----------
    quick : bool
        The CI-sized run.
    available : bool
        Whether the extra ``fleet`` is installed (else nothing was measured).
    reason_text : str
        Why not, when not.
    logs_count, motors_count, workers_count : int
        The fleet's logs and motors, and the local cluster's workers.
    serial_seconds, parallel_seconds : float
        The fleet learned here, one log after another, and on the cluster, s (the
        cluster's start not counted).
    throughput_ratio : float
        ``serial_seconds / parallel_seconds``.
    different_values_count : int
        Values of the two tables that differ (every column but the time taken, row by
        row; 0: identical).
    learned_count : int
        Logs learned.
    hot_drives_text, named_hot_drives_text : tuple of str
        The units with R_s +30%, and those the summary names (any parameter).
    broken_drives_text, named_broken_drives_text : tuple of str
        The broken logs, and those the table says failed.
    other_outliers_text : tuple of str
        Drives named that are neither hot nor broken, with the parameter.
    refusals_text : str
        The logs not learned by cause.
    memory_logs_counts : tuple of int
        The fleet sizes whose client memory was measured (empty on the quick run).
    client_peak_rss_mebibytes : tuple of float
        The client's peak resident memory at each size (``ru_maxrss`` of a fresh process
        running the fleet on the cluster), MiB.
    wall_seconds : float
        The whole study, s.
    """

    quick: bool
    available: bool
    reason_text: str = ""
    logs_count: int = 0
    motors_count: int = 0
    workers_count: int = 0
    serial_seconds: float = math.nan
    parallel_seconds: float = math.nan
    throughput_ratio: float = math.nan
    different_values_count: int = -1
    learned_count: int = 0
    hot_drives_text: tuple[str, ...] = ()
    named_hot_drives_text: tuple[str, ...] = ()
    broken_drives_text: tuple[str, ...] = ()
    named_broken_drives_text: tuple[str, ...] = ()
    other_outliers_text: tuple[str, ...] = ()
    refusals_text: str = ""
    memory_logs_counts: tuple[int, ...] = ()
    client_peak_rss_mebibytes: tuple[float, ...] = ()
    wall_seconds: float = 0.0


#: The columns that must agree between the serial and the distributed table.
_COMPARED = tuple(name for name, *_ in RESULT_COLUMNS if name != "learn_seconds")


def _differences(first: list[Any], second: list[Any]) -> int:
    """Values that differ between two columns (NaN equal to NaN; a missing row differs)."""
    if len(first) != len(second):
        return max(len(first), len(second))
    return sum(
        not (a == b or (isinstance(a, float) and isinstance(b, float) and a != a and b != b))
        for a, b in zip(first, second, strict=True)
    )


def client_run(manifest: str, config: str, out: str, count: int, workers: int) -> dict[str, float]:
    """The fleet's first ``count`` logs on a local cluster of ``workers``: its seconds
    (the cluster's start not counted) and this process's peak resident memory, MiB (run
    in a fresh process by :func:`measure_fleet`).

    Parameters
    ----------
    manifest, config : str
        The fleet (:func:`make_fleet`).
    out : str
        The output directory.
    count : int
        Logs.
    workers : int
        Worker processes.
    """
    jobs = read_manifest(manifest, config)[:count]
    with fleet_client(None, workers) as client:
        started = time.perf_counter()
        run_fleet(jobs, out, client)
        seconds = time.perf_counter() - started
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux
    return {"seconds": seconds, "peak_rss_mib": peak}


def _in_fresh_process(arguments: list[str]) -> dict[str, float]:
    code = (
        "import json, sys\n"
        "from selftune.bench._fleet import client_run\n"
        "if __name__ == '__main__':\n"
        "    a = sys.argv[1:]\n"
        "    print(json.dumps(client_run(a[0], a[1], a[2], int(a[3]), int(a[4]))))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, *arguments], capture_output=True, text=True, check=True
    )
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def measure_fleet(
    design: FleetDesign, quick: bool, progress: bool = False, workers: int = 2
) -> FleetStudy:
    """Study 12 (see the module docstring).

    Parameters
    ----------
    design : FleetDesign
        The fleet (the issue's: 20 motors x 50 units; a handful of logs on the quick run).
    quick : bool
        The CI-sized run: the client's memory is not measured.
    progress : bool
        Show progress bars on stderr (only when it is a terminal).
    workers : int
        The local cluster's worker processes.

    Returns
    -------
    FleetStudy
    """
    started = time.perf_counter()
    try:
        require_extra()
    except InputError as exc:
        return FleetStudy(quick=quick, available=False, reason_text=str(exc))
    with tempfile.TemporaryDirectory(prefix="selftune-fleet-") as directory:
        home = Path(directory)
        with fleet_client(None, workers) as client:
            truth = make_fleet(home / "fleet", design, client)
        jobs = read_manifest(truth.manifest, truth.config)
        memory: list[dict[str, float]] = []
        sizes = () if quick else (len(jobs) // 4, len(jobs))
        for count in sizes[:-1]:
            memory.append(_in_fresh_process(
                [truth.manifest, truth.config, str(home / f"memory{count}"), str(count),
                 str(workers)]
            ))  # fmt: skip
        parallel = _in_fresh_process(
            [truth.manifest, truth.config, str(home / "parallel"), str(len(jobs)), str(workers)]
        )
        if sizes:
            memory.append(parallel)
        serial = run_fleet(jobs, home / "serial", None, progress=progress)
        tables = [ResultsTable(home / name).columns(_COMPARED) for name in ("serial", "parallel")]
    summary = serial.summary
    named = {o.drive: o.parameter for o in summary.outliers}
    failed = {drive for cause in summary.refusals for drive in cause.drives}
    return FleetStudy(
        quick=quick,
        available=True,
        logs_count=len(jobs),
        motors_count=design.motors_count,
        workers_count=workers,
        serial_seconds=serial.seconds,
        parallel_seconds=parallel["seconds"],
        throughput_ratio=serial.seconds / parallel["seconds"],
        different_values_count=sum(
            _differences(tables[0][name], tables[1][name]) for name in _COMPARED
        ),
        learned_count=summary.learned_count,
        hot_drives_text=truth.hot_drives,
        named_hot_drives_text=tuple(d for d in truth.hot_drives if d in named),
        broken_drives_text=truth.broken_drives,
        named_broken_drives_text=tuple(d for d in truth.broken_drives if d in failed),
        other_outliers_text=tuple(
            f"{d} ({p})" for d, p in sorted(named.items()) if d not in truth.hot_drives
        ),
        refusals_text=", ".join(f"{r.cause} {r.count}" for r in summary.refusals),
        memory_logs_counts=tuple(sizes),
        client_peak_rss_mebibytes=tuple(m["peak_rss_mib"] for m in memory),
        wall_seconds=time.perf_counter() - started,
    )


#: The throughput a 2-worker cluster must reach, times the serial run's (issue 20).
TARGET_THROUGHPUT = 1.7


def fleet_targets(study: FleetStudy) -> list[TargetOutcome]:
    """Study 12's targets: the throughput and the identity of the results, the hot units
    and the broken logs named (on the quick run only the identity is judged).

    Parameters
    ----------
    study : FleetStudy
        The study's results.
    """
    if not study.available:
        return [TargetOutcome("fleet", "issue 20", "not measured", None, study.reason_text)]
    identical = study.different_values_count == 0
    ratio = f"{study.throughput_ratio:.2f}x on {study.workers_count} workers"
    return [
        TargetOutcome(
            "fleet throughput",
            f">= {TARGET_THROUGHPUT:g}x the serial run on {study.workers_count} workers,"
            " identical results",
            ratio + (", identical" if identical else ", DIFFERENT results"),
            (study.throughput_ratio >= TARGET_THROUGHPUT and identical)
            if not study.quick
            else None
            if identical
            else False,
            f"{study.logs_count} logs; seeded jobs, no state shared between them",
        ),
        TargetOutcome(
            "fleet summary",
            "the hot units and the broken logs named",
            f"hot {len(study.named_hot_drives_text)}/{len(study.hot_drives_text)}, broken"
            f" {len(study.named_broken_drives_text)}/{len(study.broken_drives_text)}",
            None
            if study.quick  # a handful of logs: a refused unit leaves too few to judge
            else study.named_hot_drives_text == study.hot_drives_text
            and study.named_broken_drives_text == study.broken_drives_text,
            "robust z over each motor's units; a failed log is its row's error",
        ),
    ]


def markdown_fleet(study: FleetStudy) -> list[str]:
    """Section 12 of bench.md.

    Parameters
    ----------
    study : FleetStudy
        The study's results.
    """
    lines = ["## 12. A fleet of drives on the distributed engine", ""]
    if not study.available:
        return [*lines, f"Not measured: {study.reason_text}."]
    lines += [
        f"{study.logs_count} logs of 0.2 s ({study.motors_count} motors; the realistic"
        f" fleet of `selftune.bench._fleet.make_fleet`, seed {FLEET_SEED}), learned here one"
        f" after another and on a local Dask cluster of {study.workers_count} worker"
        f" processes; study time {study.wall_seconds:.0f} s.",
        "",
    ]
    lines += table(
        ["measure", "value"],
        [
            ["serial run, s", f"{study.serial_seconds:.1f}"],
            [f"{study.workers_count} workers, s", f"{study.parallel_seconds:.1f}"],
            ["throughput ratio", f"{study.throughput_ratio:.2f}x"],
            ["values differing between the tables (all but the time taken)",
             str(study.different_values_count)],
            ["learned", f"{study.learned_count} of {study.logs_count}"],
            ["not learned, by cause", study.refusals_text or "none"],
            ["hot units (R_s +30%) named",
             f"{', '.join(study.named_hot_drives_text) or 'none'}"
             f" of {', '.join(study.hot_drives_text) or 'none'}"],
            ["broken logs named", f"{', '.join(study.named_broken_drives_text) or 'none'}"
             f" of {', '.join(study.broken_drives_text) or 'none'}"],
            ["other drives named", ", ".join(study.other_outliers_text) or "none"],
            *[
                [f"client peak memory, {count} logs, MiB", f"{rss:.0f}"]
                for count, rss in zip(
                    study.memory_logs_counts, study.client_peak_rss_mebibytes, strict=False
                )
            ],
        ],
    )  # fmt: skip
    return lines
