"""Command line of the live loop: ``delaytrack live run|replay|controller|delay|robot``.

:func:`add_live_commands` adds the ``live`` group to the ``delaytrack`` parser;
``python -m delaytrack.live ...`` runs the same commands without the rest of the CLI (the
launcher starts its nodes this way).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable, Sequence
from typing import Any

from delaytrack._cli_options import (
    EXIT_USAGE,
    OptionParser,
    decimal,
    integer,
    quiet_argument,
    trust_argument,
    within,
)
from delaytrack.sim.packet_loss import MAX_SEED
from delaytrack.warning import one_line, warnings_in_one_line

__all__ = ["add_live_commands", "main"]

_PAPER = (
    "as in the paper's experiment, where the delay was injected \"by halting the programme "
    'for h(t)" between computing a command and applying it'
)


# The types of the numbers the live commands read (delaytrack._cli_options): a time that may be
# 0 (--lead, --phase), a length or a time limit (--duration, the timeouts), and the others.
_SECONDS = within(decimal, "seconds >= 0", lambda value: value >= 0)
_POSITIVE_SECONDS = within(decimal, "seconds > 0", lambda value: value > 0)
_PROBABILITY = within(
    decimal, "a probability in [0, 1) (1 would lose every command)", lambda p: 0 <= p < 1
)
_SEED = within(integer, f"an integer from 0 to {MAX_SEED}", lambda seed: 0 <= seed <= MAX_SEED)
_PORT = within(
    integer,
    "a TCP port from 1 to 65533 (the session listens on it and the next two ports; leave "
    "--port out for free ports)",
    lambda port: 1 <= port <= 65535 - 2,
)
_STEPS = within(integer, "a whole number of steps >= 1", lambda steps: steps >= 1)
_PRIORITY = within(
    integer, "a SCHED_FIFO priority from 1 to 99 (Linux)", lambda priority: 1 <= priority <= 99
)


def _session_name(text: str) -> str:
    """argparse type: a session name, one chunk of the transport's keys (``delaytrack/NAME``):
    letters, digits, ``_``, ``-`` and ``.``; no ``/`` or wildcard."""
    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,128}", text):
        raise argparse.ArgumentTypeError(
            "must be 1 to 128 letters, digits, '_', '-' or '.' (the sessions' keys are "
            f"delaytrack/NAME/...); got {text!r}"
        )
    return text


#: Zenoh's protocols whose endpoints are ``PROTOCOL/HOST:PORT``.
_PORTED = ("tcp", "udp", "tls", "quic")


def _endpoint(lowest_port: int) -> Callable[[str], str]:
    """argparse type: a Zenoh endpoint, ``PROTOCOL/ADDRESS`` (with ``?`` metadata or ``#``
    configuration after it); for TCP, UDP, TLS and QUIC the address ends in a port from
    ``lowest_port`` to 65535 (0, any free port, is for --listen only). Zenoh itself takes a
    malformed address to connect to without a word and retries it until the handshake gives
    up."""

    def endpoint(text: str) -> str:
        protocol, slash, rest = text.partition("/")
        address = re.split(r"[?#]", rest, maxsplit=1)[0]
        host, colon, port = address.rpartition(":")
        ported = protocol in _PORTED
        if (
            not slash
            or not re.fullmatch(r"[a-z][a-z0-9-]*", protocol)
            or not address
            or (ported and not (colon and host and re.fullmatch(r"[0-9]{1,5}", port)))
            or (ported and not lowest_port <= int(port) <= 65535)
        ):
            raise argparse.ArgumentTypeError(
                "must be a Zenoh endpoint PROTOCOL/ADDRESS, for TCP, UDP, TLS and QUIC "
                f"PROTOCOL/HOST:PORT with a port from {lowest_port} to 65535 (tcp/127.0.0.1:7447); "
                f"got {text!r}"
            )
        return text

    return endpoint


def _realtime_argument(command: argparse.ArgumentParser) -> None:
    """--realtime (on every node and ``live run``)."""
    command.add_argument(
        "--realtime",
        type=_PRIORITY,
        default=None,
        metavar="PRIORITY",
        help="run the node's loop under the real-time policy SCHED_FIFO at this priority "
        "(Linux; needs CAP_SYS_NICE or an rtprio limit; refused, not ignored, without them)",
    )


#: The mutual TLS flags, with what each names: on a node, and on ``live run`` (one
#: certificate for its three nodes).
_TLS_FLAGS = {
    "--tls-ca": (
        "the certificate of the authority that signed every node's certificate (PEM)",
        "the certificate of the authority that signed the nodes' certificate (PEM)",
    ),
    "--tls-certificate": (
        "this node's certificate, signed by --tls-ca, naming the host the others reach it at (PEM)",
        "the nodes' certificate, signed by --tls-ca, naming localhost (PEM)",
    ),
    "--tls-key": ("this node's private key (PEM)", "the nodes' private key (PEM)"),
}


def _tls_arguments(command: argparse.ArgumentParser, run: bool) -> None:
    """--tls-ca, --tls-certificate and --tls-key (on every node and ``live run``)."""
    for flag, (on_a_node, on_run) in _TLS_FLAGS.items():
        command.add_argument(
            flag,
            default=None,
            metavar="FILE",
            help=f"{on_run if run else on_a_node}; the three flags together make every link "
            "mutual TLS: a peer without a certificate of the same authority is not connected",
        )


def _peer_certificates(args: argparse.Namespace) -> bool:
    """Set ``args.certificates`` (:class:`~delaytrack.live.tls.PeerCertificates` of the
    absolute paths, or None without the flags); False, after one line on stderr, when the
    flags are given in part or empty, name a file that is not a regular file, hold
    certificates no peer would accept (:func:`~delaytrack.live.tls.check_certificates`), or
    come with an endpoint that TLS does not authenticate."""
    from delaytrack._io import regular_file
    from delaytrack.live.tls import TLS_PROTOCOLS, PeerCertificates, check_certificates

    given = {flag: getattr(args, flag[2:].replace("-", "_")) for flag in _TLS_FLAGS}
    args.certificates = None
    if all(value is None for value in given.values()):
        return True
    missing = [flag for flag, value in given.items() if value is None]
    if missing:
        print(
            f"error: {' and '.join(missing)} must be given with "
            f"{' and '.join(flag for flag in given if flag not in missing)}: mutual TLS needs "
            "the authority's certificate, the node's certificate and its key",
            file=sys.stderr,
        )
        return False
    empty = [flag for flag, value in given.items() if not value.strip()]
    if empty:
        print(f"error: {empty[0]} is empty: give the path of its file", file=sys.stderr)
        return False
    try:
        paths = [
            str(regular_file(value, flag, largest=2**20).resolve()) for flag, value in given.items()
        ]
        check_certificates(PeerCertificates(*paths))
    except (OSError, ValueError) as error:
        print(one_line(f"error: {error}"), file=sys.stderr)
        return False
    for flag in ("--listen", "--connect"):
        for endpoint in getattr(args, flag[2:], None) or ():
            if endpoint.partition("/")[0] not in TLS_PROTOCOLS or re.search(r"[?#]", endpoint):
                print(
                    one_line(
                        f"error: {flag} {endpoint!r}: with --tls-ca every endpoint must be "
                        "tls/HOST:PORT or quic/HOST:PORT, without ?/# settings (a tcp or udp "
                        "endpoint, or one that turns mutual TLS off, would take peers without "
                        "a certificate)"
                    ),
                    file=sys.stderr,
                )
                return False
    args.certificates = PeerCertificates(*paths)
    return True


def _loss_and_lead_arguments(command: argparse.ArgumentParser, releases: str) -> None:
    """The delay node's --loss, --loss-seed and --lead (on ``live delay`` and ``live run``)."""
    command.add_argument(
        "--loss",
        type=_PROBABILITY,
        default=None,
        metavar="P",
        help="packet loss probability (default: the scenario's packet_loss)",
    )
    command.add_argument(
        "--loss-seed",
        type=_SEED,
        default=None,
        metavar="SEED",
        help="seed of the losses of --loss (default 0)",
    )
    command.add_argument(
        "--lead",
        type=_SECONDS,
        default=None,
        metavar="S",
        help=f"{releases} this long before the robot step it is for (default: a quarter of "
        "the session's smallest delay, within 2 ms, at least min(dt/2, 0.5 ms))",
    )


def _measurement_argument(command: argparse.ArgumentParser) -> None:
    """The controller's --no-measurement-noise (on ``live controller`` and ``live run``)."""
    command.add_argument(
        "--no-measurement-noise",
        action="store_true",
        help="the controller reads the true state: turn the scenario's measurement_noise off "
        "for this session (said in the summary and the report)",
    )


def _bridge_argument(command: argparse.ArgumentParser) -> None:
    """The robot node's --bridge (on ``live robot`` and ``live run``)."""
    command.add_argument(
        "--bridge",
        default=None,
        metavar="FILE.py:FUNCTION",
        help="your robot instead of the simulated plant: FUNCTION(scenario, dt) in FILE.py "
        "returns a delaytrack.live.bridge.RobotBridge (docs/live.md, examples/live)",
    )


def _node_arguments(command: argparse.ArgumentParser, role: str) -> None:
    command.add_argument(
        "scenario", metavar="SCENARIO", help="scenario file, or the name of a shipped scenario"
    )
    command.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help=f"folder for this node's log ({role}.mcap) and tables",
    )
    _realtime_argument(command)
    _tls_arguments(command, run=False)
    command.add_argument(
        "--duration",
        type=_POSITIVE_SECONDS,
        default=None,
        metavar="S",
        help="session length in seconds (default: the scenario's duration)",
    )
    command.add_argument(
        "--session",
        type=_session_name,
        default="live",
        metavar="NAME",
        help="session name: the key prefix delaytrack/NAME (default live)",
    )
    command.add_argument(
        "--listen",
        action="append",
        type=_endpoint(0),
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable)",
    )
    command.add_argument(
        "--connect",
        action="append",
        type=_endpoint(1),
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint of a peer, e.g. tcp/10.0.0.2:7447 (repeatable)",
    )
    command.add_argument(
        "--handshake-timeout",
        type=_POSITIVE_SECONDS,
        default=60.0,
        metavar="S",
        help="give up when the other nodes have not appeared (default 60 s)",
    )
    command.add_argument(
        "--start-delay", type=_SECONDS, default=0.5, metavar="S", help=argparse.SUPPRESS
    )
    # Given by ``delaytrack live run`` when it picked the ports: a listen port taken since
    # exits with EXIT_PORT_TAKEN, without a message, and the launcher picks new ones.
    command.add_argument("--picked-ports", action="store_true", help=argparse.SUPPRESS)
    trust_argument(command)
    quiet_argument(command, "status line")
    if role == "controller":
        command.add_argument(
            "--phase",
            type=_SECONDS,
            default=None,
            metavar="S",
            help="wake this long after each tick time to read the state "
            "sampled then (default min(T_c/2, 1 ms))",
        )
        command.add_argument(
            "--state-timeout",
            type=_POSITIVE_SECONDS,
            default=None,
            metavar="S",
            help="a state older than this is stale (default max(5 T_c, 50 ms))",
        )
        command.add_argument(
            "--stale",
            choices=("hold", "zero"),
            default="hold",
            help="on a stale state, hold the last command or send zeros",
        )
        _measurement_argument(command)
    elif role == "delay":
        _loss_and_lead_arguments(command, "release")
    else:
        command.add_argument(
            "--state-every",
            type=_STEPS,
            default=None,
            metavar="STEPS",
            help="publish the state every STEPS plant steps (default T_c/dt)",
        )
        command.add_argument(
            "--command-timeout",
            type=_POSITIVE_SECONDS,
            default=None,
            metavar="S",
            help="no command for this long: zero input (default max(0.1 s, 10 T_c))",
        )
        _bridge_argument(command)


def _loss_seed_given_alone(args: argparse.Namespace) -> bool:
    """Whether ``--loss-seed`` is given without ``--loss`` (said on stderr): it would be
    ignored, as the scenario's ``packet_loss`` has a seed of its own. Otherwise it takes its
    default, 0, where it is not given."""
    if args.loss is None and args.loss_seed is not None:
        print(
            f"error: --loss-seed {args.loss_seed} seeds the losses of --loss, which is not "
            "given: give --loss P too (the scenario's packet_loss has a seed of its own)",
            file=sys.stderr,
        )
        return True
    if args.loss_seed is None:
        args.loss_seed = 0
    return False


def _node_handler(role: str) -> Any:
    def handler(args: argparse.Namespace) -> int:
        if role == "delay" and _loss_seed_given_alone(args):
            return EXIT_USAGE
        if not _peer_certificates(args):
            return EXIT_USAGE
        if role == "controller":
            from delaytrack.live.controller import main as node_main
        elif role == "delay":
            from delaytrack.live.delay import main as node_main
        else:
            from delaytrack.live.robot import main as node_main
        return node_main(args)

    return handler


def _run(args: argparse.Namespace) -> int:
    from delaytrack.live.session import run_session

    if _loss_seed_given_alone(args) or not _peer_certificates(args):
        return EXIT_USAGE
    return run_session(args)


def _replay(args: argparse.Namespace) -> int:
    from delaytrack.live.replay import replay_main

    return replay_main(args)


def _collect(args: argparse.Namespace) -> int:
    from delaytrack.live.session import collect_main

    return collect_main(args)


def add_live_commands(commands: Any) -> None:
    """Add ``live`` and its subcommands to the subparsers ``commands`` of a parser."""
    live = commands.add_parser(
        "live",
        help="run a controller in real time against a robot over Zenoh, with the delay injected",
        description="Run the loop in real time: a controller node, a delay node and a robot "
        f"node over Zenoh, {_PAPER}. 'run' starts all three on this machine; 'controller', "
        "'delay' and 'robot' start one for a distributed setup; 'replay' re-simulates a "
        "session with its realised delays.",
    )
    sub = live.add_subparsers(
        dest="live_command", metavar="LIVE_COMMAND", parser_class=OptionParser
    )
    sub.required = True
    run = sub.add_parser(
        "run",
        help="start the three nodes as processes, wait, and write the session folder",
        description="Start the controller, delay and robot nodes as separate processes on this "
        "machine (Zenoh peers on tcp/127.0.0.1, or tls/localhost with --tls-ca, --tls-certificate "
        "and --tls-key), wait for the session to end, and write the "
        "MCAP logs, ticks.csv, delays.csv and summary.json into --out.",
    )
    run.add_argument(
        "scenario", metavar="SCENARIO", help="scenario file, or the name of a shipped scenario"
    )
    run.add_argument(
        "--duration",
        type=_POSITIVE_SECONDS,
        default=None,
        metavar="S",
        help="session length in seconds (default: the scenario's duration)",
    )
    run.add_argument("--out", required=True, metavar="DIR", help="session folder to write")
    run.add_argument(
        "--port",
        type=_PORT,
        default=None,
        metavar="PORT",
        help="first of three TCP ports on 127.0.0.1 (default: free ports)",
    )
    _loss_and_lead_arguments(run, "the delay node releases a command")
    _measurement_argument(run)
    _bridge_argument(run)
    _realtime_argument(run)
    _tls_arguments(run, run=True)
    run.add_argument(
        "--handshake-timeout",
        type=_POSITIVE_SECONDS,
        default=60.0,
        metavar="S",
        help="give up when a node has not seen the others appear (default 60 s)",
    )
    trust_argument(run)
    quiet_argument(run, "status line and no summary at the end (an error still prints it)")
    run.set_defaults(handler=_run)
    replay = sub.add_parser(
        "replay",
        help="re-simulate a live session with its realised delays and report the agreement",
        description="Re-simulate a session folder written by 'live run' offline: same plant, "
        "controller and reference, the realised delays as a trace (TraceDelay), the same "
        "packet losses; print and write the agreement of tracking errors and commands.",
    )
    replay.add_argument("folder", help="session folder written by 'delaytrack live run'")
    trust_argument(replay)
    quiet_argument(replay, "progress")
    replay.set_defaults(handler=_replay)
    collect = sub.add_parser(
        "collect",
        help="summarise a session whose nodes were started one by one (summary, report)",
        description="Write summary.json, delays.csv, metrics.csv, figures and report.html of a "
        "session run with 'live controller', 'live delay' and 'live robot', from the files the "
        "three nodes wrote (put them into one folder first when the nodes ran on several "
        "machines); 'live replay' then works on the folder.",
    )
    collect.add_argument("folder", metavar="DIR", help="folder holding the three nodes' files")
    collect.add_argument("scenario", metavar="SCENARIO", help="the scenario the nodes ran")
    trust_argument(collect)
    quiet_argument(collect, "summary")
    collect.set_defaults(handler=_collect)
    for role in ("controller", "delay", "robot"):
        node = sub.add_parser(
            role,
            help=f"run the {role} node alone (for a distributed setup)",
            description=f"Run the {role} node of a live session; the other two nodes run "
            "elsewhere with the same scenario and --session, reachable through --listen and "
            "--connect endpoints.",
        )
        _node_arguments(node, role)
        node.set_defaults(handler=_node_handler(role))


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m delaytrack.live``: the ``live`` commands alone."""
    parser = OptionParser(prog="delaytrack")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OptionParser)
    commands.required = True
    add_live_commands(commands)
    args = parser.parse_args(["live", *(sys.argv[1:] if argv is None else argv)])
    with warnings_in_one_line():
        return args.handler(args)
