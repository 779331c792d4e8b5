"""``python -m delaytrack.cli``: the ``delaytrack`` command."""

from delaytrack.cli._main import command

command()
