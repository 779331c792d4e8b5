"""``python -m delaytrack.live run|replay|controller|delay|robot ...``."""

from delaytrack._process_exit import exit_process
from delaytrack.live.cli import main

exit_process(main())
