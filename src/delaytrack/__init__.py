"""delaytrack: control of Euler-Lagrange systems under unknown input delay.

The curated public API. Everything here is also importable from its subpackage
(:mod:`delaytrack.plants`, :mod:`delaytrack.delays`, :mod:`delaytrack.controllers`,
:mod:`delaytrack.analysis`, :mod:`delaytrack.sim`, :mod:`delaytrack.metrics`,
:mod:`delaytrack.scenario`, :mod:`delaytrack.experiments`, :mod:`delaytrack.jobs`); figures
and HTML reports live in :mod:`delaytrack.report`.

Examples
--------
>>> import numpy as np
>>> import delaytrack as dt
>>> round(dt.razumikhin_bound(1.0, 1.0, 1.0, beta=1.0, r=1.1).h_m, 5)
0.12487
"""

# First: choose numba's cache folder before any kernel is decorated (see _compile.disk_cache).
from delaytrack._compile import disk_cache  # noqa: F401  isort: skip

# Refuses NUMBA_DISABLE_JIT=1 at import, with a message saying what to do instead.
from delaytrack._compile import jit  # noqa: F401  isort: skip

import lazy_loader

from delaytrack._version import __version__  # noqa: F401  (in __all__, from __init__.pyi)

# The names of __init__.pyi, each imported from its subpackage when first used, so that a
# command or a live node imports only what it runs (pandas, PyArrow and the studies are not
# loaded by `import delaytrack`).
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
