"""The README's figure: run the README's first Python example and keep the figure it draws.

Regenerate (from the repository root, in the environment where delaytrack is installed) after
changing that example::

    python scripts/readme_figure.py

The example saves ``result.plot()`` as ``joint.png`` in its working folder; this script runs it
in a temporary folder, as ``tests/test_reproduce.py`` does, and copies the figure to
``docs/images/readme_joint.png``, the image the README shows under the example. The figure is
made by the README's own code, so the two cannot tell different stories.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: What the example saves, and where the README shows it from.
SAVED = "joint.png"
FIGURE = ROOT / "docs" / "images" / "readme_joint.png"


def first_python_example(readme: Path = README) -> str:
    """The first fenced ``python`` block of ``readme``."""
    found = re.search(r"```python\n(.*?)```", readme.read_text(encoding="utf-8"), re.S)
    if found is None:
        raise SystemExit(f"{readme} has no python example")
    return found.group(1)


def main() -> int:
    """Run the example in a temporary folder and copy its figure to :data:`FIGURE`."""
    with tempfile.TemporaryDirectory(prefix="delaytrack-readme-") as folder:
        env = {**os.environ, "MPLBACKEND": "Agg"}
        subprocess.run(
            [sys.executable, "-c", first_python_example()], cwd=folder, env=env, check=True
        )
        FIGURE.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(Path(folder) / SAVED, FIGURE)
    print(f"wrote {FIGURE.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
