"""The parser of the ``delaytrack`` command: one command from each command module, then the
live loop's ``live`` group."""

from __future__ import annotations

import argparse

from delaytrack._cli_options import OptionParser
from delaytrack.cli import (
    bound,
    design,
    empirical,
    margin,
    reproduce,
    simulate,
    sweep,
    tradeoff,
    tune,
)

__all__ = ["COMMANDS", "build_parser"]

#: The command modules in the order of ``delaytrack --help``; each adds one command with
#: ``add_command(commands)``.
COMMANDS = (bound, margin, design, simulate, empirical, tradeoff, reproduce, sweep, tune)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``delaytrack`` command."""
    parser = OptionParser(
        prog="delaytrack",
        description="AROLC for Euler-Lagrange systems with unknown input delay: certified delay "
        "bound, simulation, and the main job.",
    )
    from delaytrack._version import __version__

    parser.add_argument("--version", action="version", version=f"delaytrack {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OptionParser)
    commands.required = True
    for command in COMMANDS:
        command.add_command(commands)
    # The real-time loop (delaytrack[live]), imported only when a parser is built: importing
    # the command line does not import the live loop.
    from delaytrack.live.cli import add_live_commands

    add_live_commands(commands)
    return parser
