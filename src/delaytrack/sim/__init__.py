"""The simulation engine: sampled controller, exact delayed lookup, RK4 plant, batching."""

from delaytrack._compile.ahead import compile_ahead
from delaytrack.sim.engine import STATUS_NAMES
from delaytrack.sim.measurement import MeasurementNoise
from delaytrack.sim.packet_loss import PacketLoss
from delaytrack.sim.result import SimResult
from delaytrack.sim.simulate import simulate

__all__ = [
    "STATUS_NAMES",
    "MeasurementNoise",
    "PacketLoss",
    "SimResult",
    "compile_ahead",
    "simulate",
]
