"""The end of a process the toolkit runs as a whole (:mod:`delaytrack._process_exit`)."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def test_a_whole_process_ends_with_its_status_its_exit_handlers_and_its_output():
    code = textwrap.dedent(
        """
        import atexit, gc, sys
        from delaytrack._process_exit import exit_process

        atexit.register(lambda: print("frozen at exit:", gc.get_freeze_count() > 0))
        sys.stdout.write("written, not flushed; ")
        exit_process(3)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 3, done.stderr
    assert done.stdout == "written, not flushed; frozen at exit: True\n"
