"""``selftune reproduce``: the paper's Section V, its figures and results."""

from __future__ import annotations

import sys

from ..core._atomic import check_output_directory

#: The files of ``selftune reproduce``'s output set.
REPRODUCE_OUTPUTS = (
    "results.json",
    *(f"fig{index}.{suffix}" for index in range(1, 6) for suffix in ("png", "svg")),
)


def reproduce_command(out: str, seed: int) -> int:
    """``selftune reproduce``: the paper's Section V into ``out``, with progress on a
    terminal.

    Parameters
    ----------
    out : str
        The output directory: absent, empty, or a previous output of this command (its
        files are replaced as one set); checked before anything is computed.
    seed : int
        Exploration seed.
    """
    from tqdm import tqdm

    from ..report import ALGORITHM_LABELS, report, reproduce, write_outputs

    check_output_directory(out, REPRODUCE_OUTPUTS, "selftune reproduce output")
    with tqdm(
        total=len(ALGORITHM_LABELS) + 2,
        desc="reproduce",
        file=sys.stderr,
        disable=None,
        leave=False,
        bar_format="{desc}: {n_fmt}/{total_fmt} {bar} {postfix}",
    ) as bar:

        def step(label: str) -> None:
            bar.set_postfix_str(label)
            bar.update(1)

        reproduction = reproduce(seed, step=step)
        step("figures")
        paths = write_outputs(reproduction, out)
    print(report(reproduction))
    print(
        f"\nlearning and simulation took {reproduction.wall_seconds:.2f} s; wrote "
        f"{len(paths)} files to {out}/ (fig1..fig5 .png/.svg, results.json)"
    )
    return 0
