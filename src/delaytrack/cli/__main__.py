"""``python -m delaytrack.cli``: the ``delaytrack`` command."""

import sys

from delaytrack.cli import main

sys.exit(main())
