"""Every Python example on the documentation pages runs as printed.

Each fenced ``python`` block of ``docs/*.md`` runs in a fresh interpreter, in a temporary folder,
and must exit without error. A block that cannot run here (it needs a computing cluster, or it
is a long sweep that another check runs) says so in an HTML comment on the line before its fence,
``<!-- not run by the tests: <why> -->``, which the test reports as a skip with that reason.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
_BLOCK = re.compile(
    r"^(?:<!-- not run by the tests: (?P<why>.+?) -->\n)?```python\n(?P<code>.*?)^```", re.S | re.M
)


def examples() -> list:
    """``pytest.param(code, id="<page>[<i>]")`` per block; a skip where the page says why."""
    params = []
    for page in sorted(DOCS.glob("*.md")):
        for i, match in enumerate(_BLOCK.finditer(page.read_text(encoding="utf-8"))):
            marks = [pytest.mark.skip(reason=match["why"])] if match["why"] else []
            params.append(pytest.param(match["code"], id=f"{page.stem}[{i}]", marks=marks))
    return params


def test_every_python_fence_of_the_pages_is_an_example() -> None:
    fences = sum(
        page.read_text(encoding="utf-8").count("```python\n") for page in DOCS.glob("*.md")
    )
    assert fences > 0 and len(examples()) == fences


@pytest.mark.slow  # each block starts Python; some run a kernel of theirs
@pytest.mark.parametrize("code", examples())
def test_the_example_runs(code: str, tmp_path: Path) -> None:
    completed = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert completed.returncode == 0, completed.stderr[-3000:]
    assert "Traceback" not in completed.stderr
