"""``python -m delaytrack.live run|replay|controller|delay|robot ...``."""

import sys

from delaytrack.live.cli import main

sys.exit(main())
