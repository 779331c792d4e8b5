"""Names of :mod:`delaytrack._compile`, imported when first used (see ``__init__.py``)."""

from .interpret_first import Interpreting, interpret
from .stage import compile_engine

__all__ = ["Interpreting", "compile_engine", "interpret"]
