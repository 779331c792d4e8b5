"""numba's settings from the environment only, never from a file of the working folder.

numba reads ``.numba_config.yaml`` from the working folder when it is imported and again at
every compile, and takes each entry as a ``NUMBA_*`` setting: a file sent beside a scenario
could truncate any file at exit (``chrome_trace``), import any installed module
(``cache_locator_classes``) or turn the compiler off (``disable_jit``). :func:`import_numba`,
the package's first import of numba, has it read no such file; set ``NUMBA_*`` environment
variables instead.
"""

from __future__ import annotations

import os
import sys
import warnings
from types import ModuleType

from delaytrack.warning import DelaytrackWarning

__all__ = ["SETTINGS_FILE", "import_numba"]

#: The name of numba's settings file, read relative to the working folder.
SETTINGS_FILE = ".numba_config.yaml"
#: Where numba looks for that file from now on: a path no file can have (a file is not a
#: folder), so that a compile does not read the working folder's.
_NO_FILE = os.path.join(os.devnull, SETTINGS_FILE)


def import_numba() -> ModuleType:
    """``import numba`` with no settings read from the working folder's ``.numba_config.yaml``
    (numba then finds no YAML reader for it), and none read from it by a later compile. Warns
    (:class:`~delaytrack.warning.DelaytrackWarning`) when such a file is there: ignored, or
    read already by numba imported before this package (its settings are then taken from the
    environment again, before this package sets numba's cache folder)."""
    present = os.path.isfile(SETTINGS_FILE)
    read_before = present and "numba" in sys.modules
    if present and not read_before:
        yaml = sys.modules.get("yaml")
        sys.modules["yaml"] = None  # type: ignore[assignment]  # import yaml fails in numba
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # numba's "no YAML reader" for the file
                import numba
        finally:
            if yaml is None:
                del sys.modules["yaml"]
            else:
                sys.modules["yaml"] = yaml
    import numba
    import numba.core.config

    numba.core.config._config_fname = _NO_FILE
    # numba compares its settings at each compile with those it read last: read them now, so
    # that a compile does not set them all again (the cache folder set next among them).
    numba.core.config.reload_config()
    if present:
        done = "was read by numba, imported before delaytrack" if read_before else "is not read"
        warnings.warn(
            f"{os.path.abspath(SETTINGS_FILE)} {done}: delaytrack takes numba's settings from "
            "NUMBA_* environment variables only (a settings file in the working folder could "
            "have been sent with a scenario)",
            DelaytrackWarning,
            stacklevel=2,
        )
    return numba
