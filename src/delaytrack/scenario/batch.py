"""Scenarios that differ only in name, delay and seed, run as one batched simulation."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from delaytrack._spec import SpecError as ScenarioError
from delaytrack.delays import delay_from_spec
from delaytrack.scenario.scenario import Scenario, delay_as_run, simulate_built
from delaytrack.sim import SimResult


def run_batched(scenarios: Sequence[Scenario], *, progress: bool = False) -> SimResult:
    """Run scenarios that differ only in name, delay and seed as one batched simulation.

    Batch element ``i`` is ``scenarios[i]``; the result equals running each scenario alone.

    Raises
    ------
    ScenarioError
        If the list is empty or the scenarios differ in anything else than name, delay and seed.
    """
    if not scenarios:
        raise ScenarioError("run_batched needs at least one scenario")
    first = scenarios[0]
    shared = _shared_part(first)
    for other in scenarios[1:]:
        if _shared_part(other) != shared:
            different = sorted(k for k in shared if _shared_part(other).get(k) != shared.get(k))
            raise ScenarioError(
                f"scenarios {first.name!r} and {other.name!r} differ in {different}; only name, "
                "delay and seed may differ within a batch"
            )
    built = first.build()
    delays = [delay_from_spec(delay_as_run(scenario)) for scenario in scenarios]
    return simulate_built(first, built, delays, progress=progress)


def _shared_part(scenario: Scenario) -> dict[str, Any]:
    data = scenario.to_dict()
    for key in ("name", "delay", "seed"):
        data.pop(key, None)
    return data
