"""``--report DIR`` of ``selftune learn`` and ``selftune tune``: one self-contained HTML
page with the verdict on top and six figures embedded (seven with a speed schedule's),
the same PNGs beside it, written as one set; a refused log or a foreign directory writes
nothing."""

from __future__ import annotations

import base64
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from selftune.cli import main
from selftune.config import learn_with_config, load_learn_config
from selftune.learn import load_trajectory
from selftune.model import SPMSM, design_schedule
from selftune.report import (
    FIGURE_STEMS,
    figure_schedule,
    learn_figure_data,
    report_files,
    write_learn_report,
)

EXAMPLES = Path(__file__).resolve().parent.parent / "examples" / "data"
LOG, CONFIG = EXAMPLES / "drive_log.csv", EXAMPLES / "learn.toml"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class _Page(HTMLParser):
    """What a report page holds: its images, captions, verdict and anything external."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[dict[str, str]] = []
        self.captions = 0
        self.scripts = 0
        self.external: list[str] = []
        self.verdict = ""
        self._in_verdict = False
        self.headings = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        attributes = {key: value or "" for key, value in attrs}
        if tag == "img":
            self.images.append(attributes)
        self.captions += tag == "figcaption"
        self.scripts += tag == "script"
        self.headings += tag == "h1"
        for key in ("src", "href"):
            if key in attributes and not attributes[key].startswith("data:"):
                self.external.append(attributes[key])
        if tag == "p" and attributes.get("id") == "verdict":
            self._in_verdict = True

    def handle_endtag(self, tag: str) -> None:
        if tag == "p":
            self._in_verdict = False

    def handle_data(self, data: str) -> None:
        if self._in_verdict:
            self.verdict += data


def _parsed(directory: Path) -> _Page:
    page = _Page()
    page.feed((directory / "report.html").read_text(encoding="utf-8"))
    return page


def _check_page(directory: Path, scheduled: bool = False) -> _Page:
    """The set is complete (with the schedule's figure if ``scheduled``, else without it);
    the page embeds every figure as the PNG written beside it."""
    assert sorted(path.name for path in directory.iterdir()) == sorted(report_files(scheduled))
    stems = (*FIGURE_STEMS, *(["schedule"] if scheduled else []))
    page = _parsed(directory)
    assert len(FIGURE_STEMS) == 6 and len(page.images) == len(stems)
    assert page.captions == len(stems) and page.headings == 1
    assert page.scripts == 0 and page.external == []
    if scheduled:
        assert (directory / "schedule.svg").read_text().lstrip().startswith("<?xml")
    for image, stem in zip(page.images, stems, strict=True):
        prefix = "data:image/png;base64,"
        assert image["src"].startswith(prefix) and image["alt"]
        embedded = base64.b64decode(image["src"][len(prefix) :], validate=True)
        assert embedded.startswith(PNG_SIGNATURE) and len(embedded) > len(PNG_SIGNATURE)
        assert embedded == (directory / f"{stem}.png").read_bytes()
    return page


@pytest.fixture(scope="module")
def learned_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``selftune learn`` on the README's log with --report, and what it printed."""
    import contextlib
    import io

    directory = tmp_path_factory.mktemp("learn") / "report"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(["learn", str(LOG), "--config", str(CONFIG), "--report", str(directory)]) == 0
    return directory, printed.getvalue()


def test_the_learn_report_holds_six_figures_and_the_printed_verdict(
    learned_report: tuple[Path, str],
) -> None:
    directory, printed = learned_report
    page = _check_page(directory)
    assert f"wrote {directory}/ (" in printed
    # the sentence states the standard errors and the margin as the printout does
    lines = printed.splitlines()
    errors = lines[lines.index("quality (from the data alone):") + 1].strip()
    margin = re.search(r"stability margin (\S+);", printed)
    assert margin is not None
    assert page.verdict.startswith("The data support this digital controller: ")
    assert f"{errors};" in page.verdict
    assert f"a margin of {margin.group(1)} on the fitted model" in page.verdict
    assert "24 plants the data allow" in page.verdict


def test_the_poles_figure_shows_the_verdicts_margin() -> None:
    """The fitted model's slowest pole is at 1 - the verdict's margin (one computation),
    and every plant the data allow is stable with the margin the verdict accepted."""
    config = load_learn_config(str(CONFIG), 2, 2, 2)
    result = learn_with_config(load_trajectory(LOG), config, str(LOG))
    data = learn_figure_data(result)
    assert result.quality is not None
    # the measured states are the log's (from row 1: the shift), to the rounding of x~ =
    # xhat + (x~ - xhat)
    log = load_trajectory(LOG)
    shown = data.measured.shape[0]
    np.testing.assert_allclose(
        data.measured, log.x[1 : 1 + shown], rtol=0, atol=1e-14 * np.abs(log.x).max()
    )
    np.testing.assert_array_equal(data.t, log.t[1 : 1 + shown])
    assert 1.0 - np.max(np.abs(data.poles[0])) == result.quality.stability_margin
    assert data.plants == 24 and 0.0 < data.least_margin <= data.margin
    # the step response settles on the law's target X w on the fitted model
    np.testing.assert_allclose(
        data.step_estimate[-1],
        data.step_reference[-1],
        atol=1e-3 * np.abs(data.step_reference).max(),
    )


def test_tune_without_online_writes_the_report_of_the_offline_tune(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    motor = tmp_path / "motor.toml"
    motor.write_text(
        "[motor]\nR_s = 0.8\nL_s = 0.02\nphi_pm = 0.15\np = 3\n"
        "[operating_point]\nspeed = 80.0\ntorque = 4.0\n"
    )
    directory = tmp_path / "report"
    assert main(["tune", "--motor", str(motor), "--report", str(directory)]) == 0
    page = _check_page(directory)
    assert page.verdict.startswith("The data support this continuous controller: ")
    assert f"wrote {directory}/ (" in capsys.readouterr().out


def test_a_refused_log_writes_nothing_and_says_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "applied.toml"
    text = CONFIG.read_text()
    assert 'logged_input = "commanded"' in text
    config.write_text(text.replace('logged_input = "commanded"', 'logged_input = "applied"'))
    log = tmp_path / "short.csv"
    log.write_text("".join(LOG.read_text().splitlines(keepends=True)[:301]))
    directory = tmp_path / "report"
    assert main(["learn", str(log), "--config", str(config), "--report", str(directory)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert len(captured.err.strip().splitlines()) == 1 and "act 1 sample later" in captured.err
    assert sorted(tmp_path.iterdir()) == sorted([config, log])  # nothing written


def test_a_directory_of_other_files_is_refused_before_learning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    directory = tmp_path / "report"
    directory.mkdir()
    (directory / "notes.txt").write_text("mine\n")
    args = ["learn", str(LOG), "--config", str(CONFIG), "--report", str(directory)]
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1
    assert "cannot write the learn report there" in captured.err and "notes.txt" in captured.err
    assert sorted(path.name for path in directory.iterdir()) == ["notes.txt"]


@pytest.mark.slow
def test_a_previous_report_is_replaced_as_a_set(
    learned_report: tuple[Path, str], capsys: pytest.CaptureFixture[str]
) -> None:
    """The directory of a previous report is accepted (it holds the set's names only) and
    its files are replaced; with the JSON on standard output nothing else is printed."""
    directory, _ = learned_report
    (directory / "report.html").write_text("an older page\n")
    (directory / "step.png").unlink()
    args = ["learn", str(LOG), "--config", str(CONFIG), "--report", str(directory)]
    capsys.readouterr()
    assert main([*args, "--json", "-"]) == 0
    assert capsys.readouterr().out.lstrip().startswith("{")
    _check_page(directory)


def test_a_schedules_figure_joins_the_set_and_leaves_with_it(tmp_path: Path) -> None:
    """A scheduled law's report adds the schedule's figure (embedded, and as PNG and SVG);
    the next report of a law without a schedule replaces the whole set, leaving no stale
    schedule files."""
    config = load_learn_config(str(CONFIG), 2, 2, 2)
    result = learn_with_config(load_trajectory(LOG), config, str(LOG))
    motor = SPMSM(R_s=0.8, L_s=0.02, phi_pm=0.15, p=3)
    design = design_schedule(motor, [20.0, 200.0], np.diag([10.0, 10.0]), np.eye(2), 1e-4)
    single = design.pointwise_optimum(600.0).law
    figure = figure_schedule(design, design.excess_of(single), 600.0)
    directory = tmp_path / "report"
    written = write_learn_report(result, "scheduled", ["printed"], str(directory), None, figure)
    assert sorted(path.name for path in written) == sorted(report_files(True))
    _check_page(directory, scheduled=True)
    args = ["learn", str(LOG), "--config", str(CONFIG), "--report", str(directory)]
    assert main(args) == 0
    _check_page(directory)


def test_an_unstable_plant_without_a_reference_is_reported_from_its_least_squares_model(
    tmp_path: Path,
) -> None:
    """No output-error model (the plant is unstable) and no reference: the currents are the
    one-step predictions, no other plants are drawn, the response is the return of the
    logged state farthest from rest."""
    from selftune import lqr
    from selftune.learn import save_trajectory
    from selftune.sim import prbs, simulate

    A, B = np.array([[0.0, 1.0], [-2.0, 0.3]]), np.array([[0.0], [1.0]])
    K_init = lqr(A, B, np.eye(2), np.eye(1))[0]
    data = simulate(
        A, B, K=K_init, exploration=prbs(1.0, 5), x0=[1.0, 0.0], h=1e-3, num_samples=2000, seed=2
    )
    save_trajectory(data, tmp_path / "plant.csv")
    rows = ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in K_init)
    config = tmp_path / "lqr.toml"
    config.write_text(
        f"[cost]\nQ = [[1.0, 0.0], [0.0, 1.0]]\nR = [[1.0]]\n[policy]\nK0 = [{rows}]\n"
    )
    directory = tmp_path / "report"
    assert main(["learn", str(tmp_path / "plant.csv"), "--config", str(config),
                 "--report", str(directory)]) == 0  # fmt: skip
    page = _check_page(directory)
    assert "no other plants drawn (no output-error model)" in page.verdict
    result = learn_with_config(
        load_trajectory(tmp_path / "plant.csv"), load_learn_config(str(config), 2, 1, 0), "plant"
    )
    data_ = learn_figure_data(result)
    assert data_.one_step and data_.plants == 0 and data_.step_text.startswith("Return")
    # the one-step predictions are of the logged states after the first (shift 0)
    shown = data_.measured.shape[0]
    np.testing.assert_array_equal(data_.measured, data.x[1 : 1 + shown])
