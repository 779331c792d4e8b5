"""Ports for the tests that start live nodes by hand, on ports they give them.

A port found free is free only until another program binds it, and the tests run in parallel
with live sessions of their own. Those sessions pick ports with ``bind(("127.0.0.1", 0))`` and
open connections whose local ports the kernel also takes from its ephemeral range, so a port of
that range, found free, may be taken before the node listens on it. The ports here are drawn at
random below that range, where the kernel hands out none, and checked free when drawn.
"""

from __future__ import annotations

import random
import socket
from pathlib import Path

#: Where the kernel's ephemeral range begins (Linux's default where it cannot be read).
_RANGE = Path("/proc/sys/net/ipv4/ip_local_port_range")


def free_ports(count: int) -> list[int]:
    """``count`` distinct ports on 127.0.0.1, free when drawn, below the ephemeral range."""
    try:
        first_ephemeral = int(_RANGE.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        first_ephemeral = 32768
    # Ports from 1024 (below them, binding needs privileges) up to the range: 12 000 of them,
    # enough that two tests drawing at once hardly ever draw the same.
    low = max(1024, first_ephemeral - 12000)
    drawn: list[int] = []
    draw = random.SystemRandom()
    while len(drawn) < count:
        port = draw.randrange(low, first_ephemeral)
        if port in drawn:
            continue
        with socket.socket() as probe:
            try:
                probe.bind(("127.0.0.1", port))
            except OSError:
                continue
        drawn.append(port)
    return drawn
