"""Names of :mod:`delaytrack.sim`, imported when first used (see ``__init__.py``)."""

from .ahead import compile_ahead
from .engine import STATUS_NAMES
from .measurement import MeasurementNoise
from .packet_loss import PacketLoss
from .result import SimResult
from .simulate import simulate

__all__ = [
    "STATUS_NAMES",
    "MeasurementNoise",
    "PacketLoss",
    "SimResult",
    "compile_ahead",
    "simulate",
]
