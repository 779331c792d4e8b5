"""Matplotlib's settings for the toolkit's figures: the user's own, never those of a
``matplotlibrc`` in the working folder.

Matplotlib reads its settings when it is imported, from the first ``matplotlibrc`` of its
search, and the working folder's comes first, before ``$MATPLOTLIBRC`` and the user's
configuration folder. A file sent beside a scenario could then make every figure ask for
gigabytes (``font.size: 3000`` with ``savefig.bbox: tight``), and a FIFO or a device of that
name would hold the import forever. :func:`import_matplotlib` imports it from another folder.
"""

from __future__ import annotations

import os
import sys
import warnings
from types import ModuleType

from delaytrack.warning import DelaytrackWarning

__all__ = ["import_matplotlib"]

#: The name of matplotlib's settings file.
SETTINGS_FILE = "matplotlibrc"


def import_matplotlib() -> ModuleType:
    """``import matplotlib``, from this package's folder when the working folder holds a
    ``matplotlibrc`` (of any kind: matplotlib would read it), so that its settings come from
    the next place of its search (``$MATPLOTLIBRC``, the user's configuration folder,
    matplotlib's own); warns (:class:`~delaytrack.warning.DelaytrackWarning`) when it did, or
    when matplotlib, imported before this package, has read that file already.

    The working folder is the process's: for the moment of the import, another thread would
    see this package's folder as its working folder.
    """
    try:
        present = os.path.lexists(SETTINGS_FILE)
        working = os.getcwd()
    except OSError:  # a working folder removed meanwhile: nothing there to read
        present = False
    read_before = present and "matplotlib" in sys.modules
    if present and not read_before:
        os.chdir(os.path.dirname(__file__))
        try:
            import matplotlib
        finally:
            os.chdir(working)
    import matplotlib

    if present:
        done = (
            "was read by matplotlib, imported before delaytrack" if read_before else "is not read"
        )
        warnings.warn(
            f"{os.path.join(working, SETTINGS_FILE)} {done}: the figures take matplotlib's "
            f"settings from {matplotlib.matplotlib_fname()} (a settings file in the working "
            "folder could have been sent with a scenario)",
            DelaytrackWarning,
            stacklevel=2,
        )
    return matplotlib
