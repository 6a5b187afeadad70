"""What each command does, given its values: :mod:`selftune.cli` only parses.

:mod:`selftune.cli` parses the command line and calls one of these functions with plain
values; each prints its report to standard output, writes its JSON if asked, and raises
:class:`~selftune.errors.SelftuneError` (one line) on bad input. Each imports what only
it needs when it runs, so ``selftune solve`` loads no learner, simulator or benchmark.

Every output is checked before anything is computed: a ``--json`` file must be absent
or a writable regular file (``-`` writes the JSON to standard output instead, and the
report is then left out, so that the output is the JSON alone); an output directory
must be absent, empty or a previous output set of the same command, which is replaced
as a whole. A computation that warns numerically (an overflow) or fails in numpy or
scipy on absurd input is an error naming the input, never a result.
"""

from __future__ import annotations

from ._export import export_command
from ._fleet import fleet_command
from ._learn import learn_command
from ._output import STANDARD_OUTPUT
from ._reproduce import REPRODUCE_OUTPUTS, reproduce_command
from ._solve import model_based, solve_command, solve_report
from ._tune import follow_command, online_command, tune_command

__all__ = [
    "REPRODUCE_OUTPUTS",
    "STANDARD_OUTPUT",
    "export_command",
    "fleet_command",
    "follow_command",
    "learn_command",
    "model_based",
    "online_command",
    "reproduce_command",
    "solve_command",
    "solve_report",
    "tune_command",
]
