"""Where numba keeps delaytrack's compiled kernels: a folder keyed by the package's source.

numba validates a cached function against its own source file only. The compiled engine inlines
kernels from many files (plants, controllers, delays, references), so after an edit to one of
them numba would load a stale engine. Imported first by :mod:`delaytrack`, this module points
``numba.config.CACHE_DIR`` (read when each kernel is decorated) at
``<cache root>/<hash of every .py file of the package>``, so any change recompiles everything
once. The cache root is ``$NUMBA_CACHE_DIR`` when the user sets it, else
``$XDG_CACHE_HOME/delaytrack/numba`` (``~/.cache/delaytrack/numba``).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba

__all__ = ["cache_directory", "source_hash"]

_PACKAGE = Path(__file__).resolve().parent


def source_hash() -> str:
    """SHA-256 (16 hex digits) of the paths and contents of the package's Python files."""
    digest = hashlib.sha256(numba.__version__.encode())
    for path in sorted(_PACKAGE.rglob("*.py")):
        digest.update(str(path.relative_to(_PACKAGE)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_directory() -> Path:
    """The folder for this exact source; created on demand by numba."""
    root = os.environ.get("NUMBA_CACHE_DIR")
    if root:
        return Path(root) / "delaytrack" / source_hash()
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "delaytrack" / "numba" / source_hash()


numba.config.CACHE_DIR = str(cache_directory())
