"""What the commands that read a scenario or sweep file share: the scenario named on the
command line, and the ``--trust`` names checked."""

from __future__ import annotations

import argparse
from pathlib import Path

from delaytrack.cli._usage import UsageError

__all__ = ["scenario_source", "trusted"]


def scenario_source(text: str) -> Path:
    """A scenario file path, or the name of a shipped scenario (``two_link_S1``)."""
    from delaytrack.scenario import ScenarioError
    from delaytrack.scenario.builtin import scenario_file_or_builtin

    try:
        return scenario_file_or_builtin(text)
    except ScenarioError as error:
        raise UsageError(str(error)) from None


def trusted(args: argparse.Namespace) -> list[str]:
    """The ``--trust`` names, checked (:class:`delaytrack._trust.Trust`)."""
    from delaytrack._trust import Trust

    try:
        Trust.of(args.trust, "--trust")
    except ValueError as error:
        raise UsageError(str(error)) from None
    return args.trust
