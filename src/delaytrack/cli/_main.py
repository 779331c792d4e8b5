"""``delaytrack``'s entry point: parse, run the command's handler, and end every way a
command can end with one line and an exit code."""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from typing import NoReturn, TextIO

from delaytrack._cli_options import EXIT_USAGE
from delaytrack._output import OutputFolderError
from delaytrack._process_exit import exit_process
from delaytrack.cli._parser import build_parser
from delaytrack.cli._usage import UsageError
from delaytrack.warning import one_line, warnings_in_one_line

__all__ = ["EXIT_BROKEN_PIPE", "closed_pipe_exit", "main"]

#: A reader closed standard output (``| head``): 128 + SIGPIPE, as a shell reports a program
#: that the pipe's signal ended.
EXIT_BROKEN_PIPE = 141


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``delaytrack`` command; return its exit code."""
    from delaytrack.scenario import ScenarioError
    from delaytrack.sim.interruptible import every_run_interruptible, work_left_running

    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:  # a bare call: the commands and what they do, as --help
        parser.print_help()
        return 0
    args = parser.parse_args(argv)
    try:
        with every_run_interruptible(), warnings_in_one_line():
            code = args.handler(args)  # Ctrl-C ends even a run whose kernel never returns
        sys.stdout.flush()  # here, where a reader that closed the pipe is caught
    except BrokenPipeError:
        code = closed_pipe_exit()
    except (UsageError, ScenarioError, OutputFolderError) as error:
        # One line, whatever the input held (a key with a newline in it).
        print(one_line(f"error: {error}"), file=sys.stderr)
        code = EXIT_USAGE
    except OSError as error:
        print(one_line(f"error: {error}"), file=sys.stderr)
        code = 1
    except KeyboardInterrupt as interrupted:  # where, when a factory was interrupted
        print(one_line(str(interrupted)) or "interrupted", file=sys.stderr)
        code = 130
    if work_left_running():  # a compiled run that Ctrl-C left computing: nothing waits for it
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def closed_pipe_exit(*streams: TextIO) -> int:
    """The reader of the output closed it (``| head``): end quietly, as a program that the
    pipe's signal ends (Python's advice, "Note on SIGPIPE": no flush into the closed pipe).
    Standard output, and ``streams``, go to the null device; returns
    :data:`EXIT_BROKEN_PIPE`."""
    for stream in (sys.stdout, *streams):
        os.dup2(os.open(os.devnull, os.O_WRONLY), stream.fileno())
    return EXIT_BROKEN_PIPE


def command() -> NoReturn:
    """The ``delaytrack`` program (its console script and ``python -m delaytrack.cli``):
    :func:`main` on the command line's arguments, then the exit of a whole process
    (:func:`~delaytrack._process_exit.exit_process`). It ends the process that calls it: from
    Python, call :func:`main`."""
    try:
        code = main()
    except KeyboardInterrupt:  # while the command's options were read (or its modules loaded)
        print("interrupted", file=sys.stderr)
        code = 130
    exit_process(code)
