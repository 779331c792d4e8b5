"""The ``delaytrack`` command: thin wrappers that parse, call the library and print.

Commands, one module each (``add_command(commands)`` adds it, its handler runs it)::

    delaytrack bound --k1 1 --k2 1 [--q 1] [--beta 1] [--r 1.1] [--n 5] [--json] [--quiet]
    delaytrack margin --k1 1 --k2 1 [--q 1] [--beta 1] [--r 1.1] [--n 5] [--json] [--quiet]
    delaytrack design [--n 2] [--gain-bound 1] [--min-bandwidth W] [--r 1.1] [--seed 0] [--json]
        [--quiet]
    delaytrack simulate SCENARIO.toml [--out DIR] [--format parquet|csv|both] [--trust NAME]
        [--quiet]
    delaytrack empirical SCENARIO.toml --threshold VALUE[,VALUE...]
        [--profile constant|abs-sine|abs-sine-offset]
        [--metric ae|rms|max] [--settle S] [--resolution S] [--upper S] [--frequency W] [--json]
        [--trust NAME] [--quiet]
    delaytrack reproduce [--out results] [--duration SECONDS] [--no-dt-check] [--no-contact]
        [--no-robustness] [--decision] [--size default|full] [--scheduler ADDRESS]
        [--gains PATH] [--quiet] [--job paper|two-link|margins|robustness|decision]
    delaytrack sweep SWEEP.toml [--out DIR] [--scheduler ADDRESS] [--workers N] [--trust NAME]
        [--quiet]
    delaytrack tune-baselines [--out PATH] [--quiet]
    delaytrack tradeoff SCENARIO [--zeta Z] [--omega LO HI N] [--draws N] [--threshold VALUE]
        [--upper S] [--envelope H_MAX [--knowledge exact|±X%|unknown] [--decision-draws N]]
        [--out DIR] [--scheduler ADDRESS] [--trust NAME] [--quiet]

and ``delaytrack live ...`` (:mod:`delaytrack.live.cli`, added when the parser is built).

Long work shows progress bars on stderr; ``--quiet`` turns them off, and every command accepts
it (where nothing runs long it changes nothing). ``delaytrack`` alone prints the commands.

A factory that a scenario or sweep file names (``type = "python:..."``) is Python code: only a
``.py`` file beside that file (or below) runs unless ``--trust NAME`` (repeatable: a module name,
or a path to a ``.py`` file or a folder) allows more.

Bad input ends with exit code 2 and a one-line ``error: ...`` naming the argument, the value and
what is valid; never a traceback. The library's refusals name its arguments
(:class:`~delaytrack._validation.ArgumentError`); a command says them with its flags
(:func:`delaytrack.cli._usage.flagged`).
"""

from delaytrack.cli._main import main
from delaytrack.cli._parser import build_parser

__all__ = ["build_parser", "main"]
