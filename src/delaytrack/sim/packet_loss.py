"""Lost command packets on the delayed channel.

Each command is sent as one packet. With probability ``p`` (independently per tick, seeded) the
packet of tick ``k`` is lost: the actuators never receive it and keep applying the latest
command they did receive (a zero-order hold over the loss; before any, ``u_init``). With the
delay rule (the command of the latest tick ``t_j <= t - h(t)``), this means that where the rule
would apply command ``k``, the actuators apply the latest received command ``j <= k``. The
record ``commands`` is what the controller sent; ``applied`` what the actuators applied.

Whether packet ``k`` is lost is :func:`~delaytrack._counter_noise.uniform` of the seed and ``k``
below ``p``: the same for a run alone, in a batch and on any thread. Packets that arrive out of
order are those the delay profile reorders (where ``t - h(t)`` runs backwards); this model adds
no reordering of its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from delaytrack._compile.jit import hot_kernel
from delaytrack._counter_noise import uniform
from delaytrack._validation import is_integer_at_least

__all__ = ["MAX_SEED", "PacketLoss", "packet_lost"]

#: Largest seed (it lives in a float parameter vector and is hashed as 32 bits).
MAX_SEED = 2**32 - 1


@hot_kernel
def packet_lost(k, loss):
    """Whether the packet of tick ``k`` is lost; ``loss = [p, seed]``."""
    return loss[0] > 0.0 and uniform(int(loss[1]), k) < loss[0]


@dataclass(frozen=True)
class PacketLoss:
    """Lost command packets (module docstring).

    Parameters
    ----------
    probability : float
        Probability ``p`` in [0, 1) that a packet is lost, independently per tick.
    seed : int
        Seed of the losses, 0 to 2³² − 1.
    """

    probability: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        p = self.probability
        if isinstance(p, bool) or not isinstance(p, int | float) or not 0.0 <= p < 1.0:
            raise ValueError(
                f"packet_loss.probability must be a number in [0, 1) (1 would lose every "
                f"command); got {p!r}"
            )
        object.__setattr__(self, "probability", float(p))
        if not is_integer_at_least(self.seed, 0) or self.seed > MAX_SEED:
            raise ValueError(
                f"packet_loss.seed must be an integer from 0 to {MAX_SEED}; got {self.seed!r}"
            )

    def params(self) -> list[float]:
        """``[p, seed]``."""
        return [self.probability, float(self.seed)]

    def to_spec(self) -> dict[str, Any]:
        """Plain data (a scenario's ``packet_loss`` table)."""
        return {"probability": self.probability, "seed": self.seed}
