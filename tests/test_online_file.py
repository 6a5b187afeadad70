"""PROFILE.toml (load_online_config): the issue's file, steps, and one line per mistake."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from selftune import DataFileError
from selftune.config import OnlineConfig, load_online_config
from selftune.sim import ParameterProfile

#: The file of the issue, verbatim.
WARM_UP = """\
[online]
duration = 120.0        # s of drive time
[[online.profile]]      # piecewise linear in time; factors on the motor's values
time = 0.0
R_s = 1.0
phi_pm = 1.0
[[online.profile]]
time = 120.0
R_s = 1.4
phi_pm = 0.92
"""

FAULT = """\
[online]
duration = 120.0
[[online.profile]]
time = 0.0
R_s = 1.0
phi_pm = 1.0
L_s = 1.0
[[online.profile]]
time = 60.0
R_s = 1.0
phi_pm = 1.0
[[online.profile]]
time = 60.0
R_s = 1.2
phi_pm = 1.0
L_s = 0.9
[[online.profile]]
time = 120.0
R_s = 1.2
phi_pm = 1.0
L_s = 0.9
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "profile.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_the_issues_file_reads_as_its_ramp(tmp_path: Path) -> None:
    config = load_online_config(write(tmp_path, WARM_UP))
    assert isinstance(config, OnlineConfig)
    assert config.duration == 120.0
    assert config.source.endswith("profile.toml")
    assert isinstance(config.profile, ParameterProfile)
    at = config.factors([0.0, 30.0, 60.0, 120.0])
    np.testing.assert_allclose(at.R_s, [1.0, 1.1, 1.2, 1.4], rtol=1e-15)
    np.testing.assert_allclose(at.phi_pm, [1.0, 0.98, 0.96, 0.92], rtol=1e-15)
    np.testing.assert_array_equal(at.L_s, 1.0)  # not given: the motor's own
    with pytest.raises(AttributeError):
        config.duration = 1.0  # type: ignore[misc]


def test_two_rows_at_one_time_make_a_step(tmp_path: Path) -> None:
    config = load_online_config(write(tmp_path, FAULT))
    before, at = config.factors(np.nextafter(60.0, 0.0)), config.factors(60.0)
    assert (float(before.R_s), float(before.L_s)) == (1.0, 1.0)
    assert (float(at.R_s), float(at.L_s)) == (1.2, 0.9)


def replaced(old: str, new: str, text: str = WARM_UP) -> str:
    assert old in text
    return text.replace(old, new, 1)


SECOND_TIME = "time = 120.0"
BAD_FILES = [
    (replaced(SECOND_TIME, "time = -5.0"), "[[online.profile]] row 2: time: -5.0 s is before"),
    (replaced("time = 0.0", "time = 2.0"), "[[online.profile]] row 1: time: must be 0"),
    (replaced("R_s = 1.4", "R_s = -1.4"), "[[online.profile]] row 2: R_s: must be positive"),
    (replaced("R_s = 1.4", "R_s = 0"), "[[online.profile]] row 2: R_s: must be positive"),
    (replaced("phi_pm = 0.92", "phi_pm = inf"), "[[online.profile]] row 2: phi_pm: must be finite"),
    (replaced("phi_pm = 0.92", "phi_pm = nan"), "[[online.profile]] row 2: phi_pm: must be finite"),
    (replaced("R_s = 1.4", 'R_s = "1.4"'), "[[online.profile]] row 2: R_s: must be a number"),
    (replaced("phi_pm = 0.92\n", "L_s = 0.0\nphi_pm = 0.92\n"), "row 2: L_s: must be positive"),
    (replaced("phi_pm = 0.92\n", ""), "[[online.profile]] row 2: phi_pm: missing"),
    (
        replaced("R_s = 1.0", "Rs = 1.0"),
        "[[online.profile]] row 1: Rs: unknown key (known: time, R_s, phi_pm, L_s; did you "
        "mean R_s?)",
    ),
    (
        WARM_UP + "[[online.profile]]\ntime = 120.0\nR_s = 1.5\nphi_pm = 0.9\n"
        "[[online.profile]]\ntime = 120.0\nR_s = 1.5\nphi_pm = 0.9\n",
        "[[online.profile]] row 4: time: a third point at 120.0 s",
    ),
    (replaced("duration = 120.0", "duration = -1.0"), "[online] duration: must be positive"),
    (replaced("duration = 120.0", "duration = 130.0"), "[online] duration: 130 s is beyond"),
    (
        replaced("duration = 120.0", "duration = 1e9").replace("time = 120.0", "time = 1e9"),
        "[online] duration: 1e+09 s is more than 3600 s of drive time",
    ),
    (replaced("duration = 120.0        # s of drive time\n", ""), "[online] duration: missing"),
    (replaced("duration = 120.0", "duration = 120.0\nlength = 3"), "[online] length: unknown key"),
    ("[online]\nduration = 1.0\n", "[online] profile: missing"),
    (
        "[online]\nduration = 1.0\nprofile = 3\n",
        "[online] profile: must be [[online.profile]] rows",
    ),
    (
        "[online]\nduration = 1.0\nprofile = []\n",
        "[online] profile: must be [[online.profile]] rows",
    ),
    ("[onlin]\nduration = 1.0\n", "onlin: unknown table (known: [online]; did you mean [online]?)"),
    ("", "[online]: missing table"),
]


@pytest.mark.parametrize(("text", "message"), BAD_FILES)
def test_each_mistake_is_one_line_naming_the_key(tmp_path: Path, text: str, message: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(DataFileError) as info:
        load_online_config(path)
    shown = str(info.value)
    assert "\n" not in shown
    assert shown.startswith(f"{path}: ")
    assert message in shown
