"""``python -m delaytrack.cli``: the ``delaytrack`` command."""

from delaytrack.cli import command

command()
