"""Matplotlib's settings for the toolkit's figures: the user's own, never those of a
``matplotlibrc`` in the working folder.

Matplotlib reads its settings from the first ``matplotlibrc`` of its search, and the working
folder's comes first, before ``$MATPLOTLIBRC`` and the user's configuration folder. A file sent
beside a scenario could then make every figure ask for gigabytes (``font.size: 3000`` with
``savefig.bbox: tight``). :func:`without_the_working_folder` reads the settings again from the
next file of matplotlib's search when that happened.
"""

from __future__ import annotations

import os
import warnings
from typing import Any, cast

import matplotlib

from delaytrack.warning import DelaytrackWarning

__all__ = ["without_the_working_folder"]

#: The name of matplotlib's settings file.
SETTINGS_FILE = "matplotlibrc"


def without_the_working_folder() -> None:
    """If matplotlib took its settings from the working folder's ``matplotlibrc``, take them
    from the next file of its search instead (``$MATPLOTLIBRC``, the user's configuration
    folder, matplotlib's own) and warn (:class:`~delaytrack.warning.DelaytrackWarning`). The
    backend is left as it is."""
    if not (
        os.path.isfile(SETTINGS_FILE)
        and os.path.samefile(matplotlib.matplotlib_fname(), SETTINGS_FILE)
    ):
        return
    given = os.environ.get("MATPLOTLIBRC")
    candidates = [given, os.path.join(given, SETTINGS_FILE)] if given else []
    candidates += [
        os.path.join(matplotlib.get_configdir(), SETTINGS_FILE),
        os.path.join(matplotlib.get_data_path(), SETTINGS_FILE),
    ]
    chosen = next(path for path in candidates if os.path.isfile(path))
    read = matplotlib.rc_params_from_file(chosen, use_default_template=True)
    settings = {key: read[key] for key in read if key != "backend"}
    for kept in (matplotlib.rcParams, matplotlib.rcParamsOrig):  # Orig: a new process reads it
        cast(Any, kept).update(settings)
    warnings.warn(
        f"{os.path.abspath(SETTINGS_FILE)} is not read: the figures take matplotlib's settings "
        f"from {chosen} (a settings file in the working folder could have been sent with a "
        "scenario)",
        DelaytrackWarning,
        stacklevel=2,
    )
