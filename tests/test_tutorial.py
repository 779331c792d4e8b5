"""docs/tutorial.ipynb: it is kept without outputs, and it runs top to bottom in a fresh kernel
(nbclient), printing the margins, metrics and sweep results it promises.

The notebook's cells that the checks read carry a tag (cell metadata ``tags``): ``margins``,
``trace``, ``metrics``, ``empirical``, ``sweep``.
"""

from __future__ import annotations

import importlib.util
import os
import re
from pathlib import Path

import pytest

from delaytrack.analysis import exact_delay_margin, razumikhin_bound

# Looked up, not imported: nbformat and nbclient take a second to import, which every pytest
# worker would pay at collection; the tests import them.
pytestmark = pytest.mark.skipif(
    any(importlib.util.find_spec(name) is None for name in ("nbformat", "nbclient", "ipykernel")),
    reason="the test extra installs nbformat, nbclient and ipykernel",
)

NOTEBOOK = Path(__file__).resolve().parents[1] / "docs" / "tutorial.ipynb"

#: Seconds each cell may take: the first simulations compile the engine (about a minute cold).
CELL_TIMEOUT = 300


def test_committed_notebook_is_valid_and_has_no_outputs() -> None:
    import nbformat

    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code, "the tutorial has no code cells"
    for index, cell in enumerate(code):
        assert cell.outputs == [], f"code cell {index} is saved with outputs; clear them"
        assert cell.execution_count is None, f"code cell {index} is saved with a count"
    text = "\n".join(cell.source for cell in notebook.cells)
    assert "Roy & Kar" in text
    assert not re.search(r"\bSPEC\b|#\d{2,}", text), "cite the paper, not internal documents"


def _tagged(notebook, tag: str):
    cells = [cell for cell in notebook.cells if tag in cell.metadata.get("tags", [])]
    assert len(cells) == 1, f"expected one cell tagged {tag!r}; found {len(cells)}"
    return cells[0]


def _text(cell) -> str:
    """Everything a cell printed or displayed as text."""
    parts = []
    for output in cell.outputs:
        if output.output_type == "stream" and output.name == "stdout":
            parts.append(output.text)
        elif output.output_type in ("execute_result", "display_data"):
            parts.append(output.get("data", {}).get("text/plain", ""))
    return "\n".join(parts)


def _milliseconds(text: str, label: str) -> float:
    match = re.search(re.escape(label) + r"\s*=\s*([0-9.]+) ms", text)
    assert match, f"{label!r} not printed in:\n{text}"
    return float(match.group(1))


@pytest.mark.slow
def test_tutorial_runs_and_reports_its_results(tmp_path: Path) -> None:
    import nbclient
    import nbformat

    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},  # the kernel's working directory
    )
    # The notebook's tempfile.mkdtemp() (delay log, sweep results) lands in tmp_path too.
    client.execute(env={**os.environ, "TMPDIR": str(tmp_path)})

    errors = [
        f"{output.ename}: {output.evalue}"
        for cell in notebook.cells
        if cell.cell_type == "code"
        for output in cell.outputs
        if output.output_type == "error"
    ]
    assert not errors, errors
    # The notebook removes its temporary folder (delay log, sweep results) as it ends.
    assert not list(tmp_path.glob("delaytrack-tutorial-*"))
    assert all(
        cell.execution_count is not None for cell in notebook.cells if cell.cell_type == "code"
    )

    # Step 2: Theorem 1's bound, the exact margin and python-control's PM / w_c agree with the
    # library, and with each other.
    margins = _text(_tagged(notebook, "margins"))
    h_m = razumikhin_bound(1.0, 1.0, 1.0, beta=1.0, r=1.1, n=1).h_m
    h_exact = exact_delay_margin(1.0, 1.0, n=1).h
    assert _milliseconds(margins, "h_m (Theorem 1, certified)") == pytest.approx(
        1e3 * h_m, abs=0.05
    )
    assert _milliseconds(margins, "h_exact (exact_delay_margin)") == pytest.approx(
        1e3 * h_exact, abs=0.05
    )
    assert _milliseconds(margins, "control.margin: PM / w_c") == pytest.approx(
        1e3 * h_exact, abs=0.05
    )
    assert _milliseconds(margins, "with h_m in the loop, delay left") == pytest.approx(
        1e3 * (h_exact - h_m), abs=0.2
    )

    # Step 3: the trace stays below h_m, both runs end ok, AROLC tracks better.
    assert "covered by Theorem 1: True" in _text(_tagged(notebook, "trace"))
    metrics = _text(_tagged(notebook, "metrics"))
    rows = {
        label: re.search(rf"{re.escape(label)}\s+0\s+(\w+)\s+20\.0\s+([0-9.]+)", metrics)
        for label in ("AROLC", "outer loop")
    }
    assert all(rows.values()), metrics
    assert {row.group(1) for row in rows.values()} == {"ok"}
    assert float(rows["AROLC"].group(2)) < float(rows["outer loop"].group(2))

    # Step 4: an empirical margin for each controller, above the certified bound.
    empirical = _text(_tagged(notebook, "empirical"))
    found = dict(
        re.findall(r"^(AROLC|outer loop)\s+empirical margin: ([0-9.]+) s", empirical, re.M)
    )
    assert set(found) == {"AROLC", "outer loop"}, empirical
    for label, value in found.items():
        assert h_m < float(value) < 1.0, f"{label}: {value} s"
    assert "h_exact, nominal loop (ms)" in empirical

    # Step 5: the sweep ran its 12 runs, all ok.
    sweep = _text(_tagged(notebook, "sweep"))
    assert "12 runs in" in sweep, sweep
    assert "statuses: {'ok': 12}" in sweep

    figures = sum(
        "image/png" in output.get("data", {})
        for cell in notebook.cells
        if cell.cell_type == "code"
        for output in cell.outputs
    )
    assert figures >= 3, f"expected the Bode plot, result.plot() and the margin figure; {figures}"
