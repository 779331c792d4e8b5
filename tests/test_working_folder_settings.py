"""Settings files of the working folder, which could have been sent beside a scenario, are not
read: numba's ``.numba_config.yaml`` and matplotlib's ``matplotlibrc``."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

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
        env={**os.environ, "NUMBA_OPT": "2"},
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "2" and "not read" not in done.stderr


@pytest.mark.parametrize("kind", ["file", "fifo"])
def test_the_figures_take_no_matplotlib_settings_from_the_working_folder(tmp_path, kind):
    # A FIFO of that name would hold matplotlib's import forever (it reads the file then).
    settings = tmp_path / "matplotlibrc"
    if kind == "fifo":
        if not hasattr(os, "mkfifo"):
            pytest.skip("no FIFOs here")
        os.mkfifo(settings)
    else:
        settings.write_text("savefig.bbox: tight\nfont.size: 3000\n")
    code = (
        "import os, delaytrack.report, matplotlib\n"
        "print(matplotlib.rcParams['font.size'], matplotlib.rcParamsOrig['font.size'])\n"
        "print(os.getcwd())"
    )
    done = subprocess.run(
        [sys.executable, "-P", "-c", code],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    sizes, working = done.stdout.splitlines()
    assert "3000" not in sizes and working == str(tmp_path)  # the working folder given back
    assert "matplotlibrc is not read: the figures take matplotlib's settings from" in done.stderr


def test_numba_imported_first_keeps_the_cache_folder_and_is_warned(tmp_path):
    # numba imported before delaytrack has read the file: delaytrack says so, and its cache
    # folder survives numba's next reading of its settings (at a compile).
    (tmp_path / ".numba_config.yaml").write_text("opt: 2\n")
    code = (
        "import numba, delaytrack\n"
        "before = numba.config.CACHE_DIR\n"
        "numba.njit(lambda x: x + 1)(1)\n"
        "print(before == numba.config.CACHE_DIR != '', int(numba.config.OPT))"
    )
    done = subprocess.run(
        [sys.executable, "-P", "-c", code], cwd=tmp_path, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "3"]  # numba's default level again, not the file's
    assert ".numba_config.yaml was read by numba, imported before delaytrack" in done.stderr
