"""Settings files of the working folder, which could have been sent beside a scenario, are not
read: numba's ``.numba_config.yaml`` and matplotlib's ``matplotlibrc``."""

from __future__ import annotations

import subprocess
import sys

CHECK = """
import delaytrack, numba
from delaytrack.delays import AbsSineDelay
import numpy as np
AbsSineDelay.S1().h(np.linspace(0.0, 1.0, 100))  # compiled (more than a few points)
numba.njit(lambda x: x + 1)(1)  # a compile: numba reads its settings again
print(numba.config.DISABLE_JIT, numba.config.CHROME_TRACE or "-")
"""


def test_a_settings_file_in_the_working_folder_is_not_read(tmp_path):
    victim = tmp_path / "precious.txt"
    victim.write_text("precious")
    working = tmp_path / "sent"
    working.mkdir()
    (working / ".numba_config.yaml").write_text(
        f"chrome_trace: {victim}\ncache_locator_classes: this.Klass\ndisable_jit: 0\n"
    )
    done = subprocess.run(
        [sys.executable, "-P", "-c", CHECK], cwd=working, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0", "-"]
    assert victim.read_text() == "precious"  # no trace written over it at exit
    assert "The Zen of Python" not in done.stdout  # the module 'this' was not imported
    assert ".numba_config.yaml is not read: delaytrack takes numba's settings" in done.stderr


def test_numbas_environment_variables_still_apply(tmp_path):
    done = subprocess.run(
        [sys.executable, "-P", "-c", "import delaytrack, numba; print(int(numba.config.OPT))"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env={**__import__("os").environ, "NUMBA_OPT": "2"},
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "2" and "not read" not in done.stderr


def test_the_figures_take_no_matplotlib_settings_from_the_working_folder(tmp_path):
    (tmp_path / "matplotlibrc").write_text("savefig.bbox: tight\nfont.size: 3000\n")
    code = (
        "import matplotlib, delaytrack.report\n"
        "print(matplotlib.rcParams['font.size'], matplotlib.rcParamsOrig['font.size'])"
    )
    done = subprocess.run(
        [sys.executable, "-P", "-c", code], cwd=tmp_path, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "3000" not in done.stdout
    assert "matplotlibrc is not read: the figures take matplotlib's settings from" in done.stderr
