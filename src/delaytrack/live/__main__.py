"""``python -m delaytrack.live run|replay|controller|delay|robot ...``."""

import sys

from delaytrack._process_exit import exit_process

try:
    from delaytrack.live.cli import main

    code = main()
except KeyboardInterrupt:  # while the modules load or the options are read
    print("interrupted", file=sys.stderr)
    code = 130
except BrokenPipeError:  # the reader closed the output (| head): end quietly, as delaytrack
    from delaytrack.cli._main import closed_pipe_exit

    code = closed_pipe_exit(sys.stderr)  # a status line on stderr may have met it
except OSError as error:  # a file that cannot be written, as the delaytrack command says it
    from delaytrack.warning import one_line

    print(one_line(f"error: {error}"), file=sys.stderr)
    code = 1
exit_process(code)
