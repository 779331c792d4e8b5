"""``python -m delaytrack.live run|replay|controller|delay|robot ...``."""

import sys

from delaytrack._process_exit import exit_process

try:
    from delaytrack.live.cli import main

    code = main()
except KeyboardInterrupt:  # while the modules load or the options are read
    print("interrupted", file=sys.stderr)
    code = 130
exit_process(code)
