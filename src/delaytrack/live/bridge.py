"""The robot bridge: where a real robot's driver plugs into the live loop's robot node.

The robot node (:mod:`delaytrack.live.robot`) runs one loop at the robot's step ``dt``; at each
step it *reads* the robot's state and *writes* the input in force, in the spirit of the
``read`` / ``write`` of a ros2_control hardware interface. What it reads from and writes to is a
:class:`RobotBridge`. The scenario's simulated plant is one bridge
(:class:`~delaytrack.live.robot.SimulatedRobot`, the default); a robot of yours is another,
built by a factory in a Python file you name on the command line::

    delaytrack live robot SCENARIO --bridge my_robot.py:make_bridge ...
    delaytrack live run SCENARIO --bridge my_robot.py:make_bridge ...

``make_bridge(scenario, dt)`` is called with the :class:`~delaytrack.scenario.Scenario` and
the robot's step ``dt`` in seconds, and returns a :class:`RobotBridge`. Naming the file on the
command line is trusting it: its code runs with your rights, as a factory you pass with
``--trust``. :func:`load_bridge` loads and checks it (:class:`BridgeError` names ``--bridge``).
"""

from __future__ import annotations

import abc
import inspect
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "DRIVER_ERRORS",
    "BridgeError",
    "RobotBridge",
    "bridge_factory",
    "check_state",
    "load_bridge",
]

#: The form of the ``--bridge`` option, for messages.
_FORM = (
    "FILE.py:FUNCTION (a Python file and its function (scenario, dt) that returns a RobotBridge)"
)


#: What a call into a bridge (the user's code, a robot's driver) may raise that the robot node
#: reports as the bridge's failure: anything but ``KeyboardInterrupt``, ``SystemExit`` included
#: (a vendor's SDK that calls ``sys.exit()`` when no device answers ended the node silently).
DRIVER_ERRORS = (Exception, SystemExit)


class BridgeError(ValueError):
    """A ``--bridge`` value that cannot be used; the message names the option, the value and
    what is valid."""


class RobotBridge(abc.ABC):
    """The robot as the robot node sees it: read its state, write its input.

    Subclass it, define :meth:`read_state` and :meth:`write_command` (and :meth:`start` and
    :meth:`close` if your robot needs them), and return an instance from the factory that
    ``--bridge FILE.py:FUNCTION`` names.

    **Who calls what, when.** The robot node calls every method on its own main thread, one
    call at a time, never two at once; your bridge may run threads of its own (a driver's
    receive thread, a simulator's clock), and guards what they share with what these methods
    touch.

    1. ``FUNCTION(scenario, dt)`` builds the bridge when the node starts, before it meets the
       other nodes.
    2. :meth:`start` is called once, then :meth:`read_state` once (with ``t = 0.0``) to check
       its shapes and values. Either raising, or a wrong shape or a value that is not finite,
       refuses the bridge: :meth:`close` is called, the node prints one line
       ``error: --bridge ...`` and exits with code 2. Until the first :meth:`write_command`
       the robot holds zero input.
    3. After the handshake, at each robot step ``j`` of the session (at ``t0 + j·dt`` on the
       monotonic clock), the node calls :meth:`read_state` (``t = j·dt``), publishes the state
       to the controller, picks the command in force under the delay rule, and calls
       :meth:`write_command` (``t = j·dt``) with it. The robot holds that input until the next
       write.
    4. :meth:`close` is called once when the node is done with the bridge, however it ended
       (the session's end, SIGINT/SIGTERM, a failure, peers that never came).

    **Units.** ``q`` and ``q̇`` are the scenario's plant coordinates, in their order
    (``plant.coordinate_names``) and units (SI: m, rad, m/s, rad/s), each an array of shape
    ``(n,)``; ``u`` is the plant's input of shape ``(m,)`` in its units (N, N·m: the ``u`` of
    ``M(q) q̈ + N(q, q̇) = G(q) u``), already saturated to the scenario's ``input_limits``.
    ``t`` is the step's time on the session clock, in seconds; the call happens at or shortly
    after it. A driver that stamps its readings reads its own clock.

    **Safety.** Before the first command and when no command has arrived for
    ``--command-timeout`` seconds, the node writes zero input at every step. A call that
    raises, or a :meth:`read_state` whose values are not finite or have the wrong shape, ends
    the session for this node: it says so on stderr in one line, calls :meth:`close`, writes
    its log and tables up to that step and exits with code 1. :meth:`close` must leave the
    robot safe (zero input, brakes on), whatever state it is in.

    **Timing.** The two calls are on the loop's critical path: they should take a small part of
    ``dt`` and must not block. A wake-up later than the next step misses the steps in between
    (counted, ``missed`` in ``steps.csv``): a real robot lives on its own clock, so the node
    reads and writes once, for the latest step, and the robot held the previous input over the
    missed ones. A call that never returns stops the node; SIGINT/SIGTERM take effect when it
    returns.
    """

    #: Whether the robot's time advances by one step ``dt`` per :meth:`write_command` (a
    #: simulated plant whose clock is the node's step count): the node then also writes the
    #: steps whose wake-up it missed, late, so that no step is skipped. False for a robot that
    #: lives in real time, which the node reads and writes once on a late wake-up.
    steps_on_write: bool = False

    def start(self) -> None:  # noqa: B027 - optional, no-op by default
        """Connect to the robot and start it streaming; called once, before any read."""

    @abc.abstractmethod
    def read_state(self, t: float) -> tuple[Any, Any]:
        """The robot's state measured now: ``(q, q̇)``, each of shape ``(n,)``, finite.

        Parameters
        ----------
        t : float
            The step's time on the session clock (seconds).
        """

    @abc.abstractmethod
    def write_command(self, t: float, u: np.ndarray) -> None:
        """Apply the input ``u`` (shape ``(m,)``) now and hold it until the next write.

        ``u`` is the node's array, valid during the call only: copy what you keep.

        Parameters
        ----------
        t : float
            The step's time on the session clock (seconds).
        u : array
        """

    def close(self) -> None:  # noqa: B027 - optional, no-op by default
        """Leave the robot safe (zero input) and release it; called once, at the end. Under
        ``delaytrack live run`` it must return within a minute (and 5 % of the session) of
        the other nodes' end, or the robot node is stopped."""


def bridge_factory(value: str) -> Any:
    """The factory named by ``--bridge FILE.py:FUNCTION``: the file is imported (it runs).

    Raises
    ------
    BridgeError
        When ``value`` has not that form, the file does not exist or raises while it is
        imported, or it has no such function.
    """
    from delaytrack._spec import module_from_file

    location, colon, name = value.rpartition(":")
    if not (colon and location.endswith(".py") and name.isidentifier()):
        raise BridgeError(f"--bridge {value!r} must be {_FORM}")
    path = Path(location).expanduser()
    if not path.is_file():
        raise BridgeError(f"--bridge {value!r}: no such file {str(path)!r}; give {_FORM}")
    try:
        module = module_from_file(path)
    except DRIVER_ERRORS as error:  # anything the user's file raises is reported
        raise BridgeError(
            f"--bridge {value!r}: importing {str(path)!r} raised {type(error).__name__}: {error}"
        ) from None
    factory = getattr(module, name, None)
    if not callable(factory):
        functions = sorted(
            n for n, f in vars(module).items() if inspect.isfunction(f) and not n.startswith("_")
        )
        raise BridgeError(
            f"--bridge {value!r}: {str(path)!r} has no function {name!r} (its functions: "
            f"{', '.join(functions) or 'none'}); give {_FORM}"
        )
    return factory


def load_bridge(value: str, scenario: Any, dt: float, n: int) -> RobotBridge:
    """The started and checked bridge of ``--bridge FILE.py:FUNCTION`` for a plant with ``n``
    coordinates: ``FUNCTION(scenario, dt)``, :meth:`~RobotBridge.start`, one
    :meth:`~RobotBridge.read_state` checked with :func:`check_state` (the bridge is closed
    again when that fails).

    Raises
    ------
    BridgeError
        Naming ``--bridge`` and the value: as :func:`bridge_factory`, or when the factory
        raises or returns something else than a :class:`RobotBridge`, or when ``start`` or
        ``read_state`` raises or the state read has the wrong shape or is not finite.
    """
    factory = bridge_factory(value)
    name = getattr(factory, "__name__", "the factory")
    try:
        bridge = factory(scenario, dt)
    except DRIVER_ERRORS as error:  # the user's code
        raise BridgeError(
            f"--bridge {value!r}: {name}(scenario, dt) raised {type(error).__name__}: {error}"
        ) from None
    if not isinstance(bridge, RobotBridge):
        raise BridgeError(
            f"--bridge {value!r}: {name}(scenario, dt) returned {type(bridge).__name__}, not a "
            "RobotBridge (subclass delaytrack.live.bridge.RobotBridge and define read_state "
            "and write_command)"
        )
    try:
        try:
            bridge.start()
            state = bridge.read_state(0.0)
        except DRIVER_ERRORS as error:  # the user's code
            raise BridgeError(
                f"--bridge {value!r}: {type(bridge).__name__} raised {type(error).__name__} "
                f"when started and read: {error}"
            ) from None
        problem = check_state(state, np.empty(2 * n))
        if problem is not None:
            raise BridgeError(f"--bridge {value!r}: {type(bridge).__name__}.{problem}")
    except BaseException:
        bridge.close()
        raise
    return bridge


def check_state(state: Any, x: np.ndarray) -> str | None:
    """Copy the ``(q, q̇)`` that :meth:`RobotBridge.read_state` returned into ``x = [q, q̇]``
    (of size ``2 n``); None when that worked, else what was wrong (``"read_state returned
    ..."``)."""
    n = x.size // 2
    want = f"({n},)"
    try:
        q, qdot = state
        q = np.asarray(q, dtype=np.float64)
        qdot = np.asarray(qdot, dtype=np.float64)
    except (TypeError, ValueError):
        return (
            f"read_state returned {type(state).__name__}; it must return (q, q̇), two arrays "
            f"of shape {want}"
        )
    if q.shape != (n,) or qdot.shape != (n,):
        return (
            f"read_state returned q of shape {q.shape} and q̇ of shape {qdot.shape}; the "
            f"scenario's plant has {n} coordinates: both must have shape {want}"
        )
    x[:n] = q
    x[n:] = qdot
    if not np.isfinite(x).all():
        return f"read_state returned a state that is not finite: {x.tolist()}"
    return None
