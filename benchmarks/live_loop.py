"""The live loop in real time (``delaytrack live run``), for ``make bench``.

The paper's experiment: the P3-DX (``robot_S1``: PayloadRobot, AROLC with the paper's gains,
the S1 delay, ``dt`` = 1 ms) run as three processes over Zenoh on this machine, at
``T_c`` = 10 ms (the paper's period) and at ``T_c`` = 1 ms (the stretch), each session
followed by ``live replay`` (the sim-to-real check of the delay model). Wall-clock timings
depend on what else the machine runs, so each case carries the load average before and after
it; read misses and tails against it. The numbers issue 36 asks for (idle 2-core machine,
``T_c`` = 10 ms, 60 s): 0 deadline misses, compute p99 <= 0.1 ms, lateness p99 <= 1 ms,
realised delay minus ``h`` p99 <= 1 ms, replay RMS difference <= 5 % of the RMS tracking error.

``python benchmarks/live_loop.py [--quick]`` runs the cases alone and prints them as JSON;
:func:`live_cases` is what ``benchmarks/run.py`` calls (skipped there with ``--skip-live`` or
``DELAYTRACK_BENCH_SKIP_LIVE=1``: the cases take two to three minutes).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from delaytrack.live._tables import ms, per_second

__all__ = ["format_live", "live_case", "live_cases"]

SCENARIO = "robot_S1"


#: The SCHED_FIFO priority of the real-time variant (``--realtime``).
REALTIME = 50


def realtime_allowed() -> bool:
    """Whether this process may use SCHED_FIFO (the ``--realtime`` sessions run only then)."""
    try:
        policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        os.sched_setscheduler(0, policy, param)
        return True
    except (AttributeError, OSError):
        return False


def live_case(
    T_c: float, duration: float, keep: Path | None = None, realtime: int | None = None
) -> dict:
    """One ``live run`` of the P3-DX at ``T_c`` for ``duration`` seconds (with ``--realtime
    realtime`` when given), and its replay; the session folder is copied to ``keep`` when
    given."""
    from delaytrack.live.replay import replay
    from delaytrack.scenario import load_builtin

    with tempfile.TemporaryDirectory() as folder:
        scenario_file = Path(folder) / f"{SCENARIO}_T_c.toml"
        load_builtin(SCENARIO).replace(T_c=T_c).to_toml(scenario_file)
        out = Path(folder) / "session"
        load_before = os.getloadavg()
        start = time.perf_counter()
        finished = subprocess.run(
            [
                sys.executable,
                "-m",
                "delaytrack.live",
                "run",
                str(scenario_file),
                "--duration",
                repr(duration),
                "--out",
                str(out),
                "--quiet",
                *([] if realtime is None else ["--realtime", str(realtime)]),
            ],
            capture_output=True,
            text=True,
        )
        wall = time.perf_counter() - start
        load_after = os.getloadavg()
        if finished.returncode != 0:
            raise RuntimeError(f"live run failed ({finished.returncode}): {finished.stderr}")
        summary = json.loads((out / "summary.json").read_text())
        agreement = replay(out)
        if keep is not None:
            shutil.copytree(out, keep, dirs_exist_ok=True)
    nodes = summary["nodes"]
    controller, robot, delay = nodes["controller"], nodes["robot"], nodes["delay"]
    return {
        "case": f"live P3-DX AROLC S1, T_c = {T_c * 1e3:g} ms, {duration:g} s"
        + ("" if realtime is None else f", SCHED_FIFO {realtime}"),
        "realtime_priority": realtime,
        "T_c_s": T_c,
        "duration_s": duration,
        "wall_s": wall,
        "load_average_before": list(load_before),
        "load_average_after": list(load_after),
        "cores": len(os.sched_getaffinity(0)),
        "controller_ticks": controller["ticks"],
        "controller_deadline_misses": controller["missed"],
        "controller_compute_ms_p50": controller["compute_ms_p50"],
        "controller_compute_ms_p99": controller["compute_ms_p99"],
        "controller_lateness_ms_p50": controller["lateness_ms_p50"],
        "controller_lateness_ms_p99": controller["lateness_ms_p99"],
        "controller_stale_ticks": controller["stale"],
        "robot_steps": robot["steps"],
        "robot_missed_steps": robot["missed_steps"],
        "robot_lateness_ms_p99": robot["lateness_ms_p99"],
        "robot_late_applications": robot["late_applications"],
        "delay_node_wakes_per_s": delay.get("wakes_per_s"),
        "delay_node_missed_steps": delay["missed_steps"],
        "realised_minus_h_ms_p50": summary["realised_minus_h_ms_p50"],
        "realised_minus_h_abs_ms_p99": summary["realised_minus_h_abs_ms_p99"],
        "realised_minus_h_abs_ms_p99_of_the_rule": summary[
            "realised_minus_h_abs_ms_p99_of_the_rule"
        ],
        "never_applied": summary["never_applied"],
        "replay_error_rms_relative": agreement["error_difference_rms_relative"],
        "replay_worst_coordinate": agreement["worst_coordinate"],
    }


def live_cases(quick: bool = False, keep: Path | None = None) -> list[dict]:
    """The sessions: ``T_c`` = 10 ms and 1 ms, 60 s each (6 s with ``quick``), under the normal
    policy and, where this machine allows it, under SCHED_FIFO beside it; their folders copied
    into ``keep/T_c_10ms`` (``..._fifo``) when given."""
    duration = 6.0 if quick else 60.0
    policies = [None, REALTIME] if realtime_allowed() else [None]
    return [
        live_case(
            T_c,
            duration,
            None
            if keep is None
            else Path(keep) / f"T_c_{T_c * 1e3:g}ms{'' if realtime is None else '_fifo'}",
            realtime,
        )
        for T_c in (0.01, 0.001)
        for realtime in policies
    ]


def format_live(cases: list[dict]) -> str:
    """A few lines per case for the terminal (n/a where a session measured nothing: ``null``
    in its JSON)."""
    lines = []
    for c in cases:
        before = ", ".join(f"{v:.2f}" for v in c["load_average_before"])
        after = ", ".join(f"{v:.2f}" for v in c["load_average_after"])
        lines += [
            f"{c['case']} (load average {before} before, {after} after, {c['cores']} cores):",
            f"  controller: {c['controller_deadline_misses']} of "
            f"{c['controller_ticks'] + c['controller_deadline_misses']} ticks missed, compute "
            f"p99 {ms(c['controller_compute_ms_p99'])}, lateness p99 "
            f"{ms(c['controller_lateness_ms_p99'])}",
            f"  robot: {c['robot_missed_steps']} of {c['robot_steps']} steps missed, lateness "
            f"p99 {ms(c['robot_lateness_ms_p99'])}; delay node "
            f"{per_second(c['delay_node_wakes_per_s'])} wake-ups/s",
            f"  |realised delay - h(t)| p99 {ms(c['realised_minus_h_abs_ms_p99'])} (the exact "
            f"rule on the step grid alone {ms(c['realised_minus_h_abs_ms_p99_of_the_rule'])}); "
            "replay "
            f"RMS difference {100 * c['replay_error_rms_relative']:.2f} % of the RMS tracking "
            "error",
        ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 s sessions instead of 60 s")
    parser.add_argument("--keep", metavar="DIR", help="copy the session folders into DIR")
    args = parser.parse_args()
    cases = live_cases(args.quick, args.keep)
    print(format_live(cases), file=sys.stderr)
    print(json.dumps(cases, indent=1))


if __name__ == "__main__":
    main()
