"""MuJoCo's profiling clock, stopped while a simulation runs a MuJoCo model.

MuJoCo times the stages of ``mj_step`` (and of ``mj_fwdPosition``, ``mj_fwdVelocity``, ...,
which a MuJoCo model's terms kernel calls) for its profiler, ``mjData.timer``: each stage reads
the clock ``mjcb_time`` at its start and at its end when one is installed. MuJoCo's Python
bindings install one, the steady clock in milliseconds, when they make the first ``mjData`` of
a process in which none is installed. For a small model these clock reads cost about as much as
the physics: the three-link arm of ``examples/mujoco_arm`` steps 1.74 times as fast without
them (``make bench``, MuJoCo 4.0).

While a simulation runs a MuJoCo model, :func:`profiler_clock_stopped` installs a clock that
always reads 0 (a function of two machine instructions, compiled once a process by llvmlite,
numba's code generator, in a few milliseconds), so that the profiler costs nothing, and puts
back the clock before it when the last such simulation of the process ends. A stopped clock and
not none: the bindings would install theirs again as soon as a thread of the batch made its own
copy of the model. No number of a simulation changes (the profiler only observes); the
simulation's own ``mjData.timer`` stays zero. A clock of yours installed while a simulation
runs (``mujoco.set_mjcb_time``) is left in place when it ends.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import threading
from collections.abc import Iterator
from typing import Any

from delaytrack.plants.mujoco.capi import mujoco_library

__all__ = ["profiler_clock_stopped"]

_lock = threading.Lock()
#: Simulations running with the clock stopped, and the clock they found installed.
_running = 0
_before: int | None = None
#: The stopped clock's execution engine (kept alive with its code) and address, once compiled.
_compiled: tuple[Any, int] | None = None


def _stopped_clock() -> int:
    """The address of ``double stopped(void) { return 0.0; }``, compiled the first time (the
    caller holds ``_lock``; llvmlite's global context is numba's, so under numba's compiler
    lock)."""
    global _compiled
    if _compiled is None:
        import llvmlite.binding as llvm
        from numba.core.compiler_lock import global_compiler_lock

        with global_compiler_lock:
            llvm.initialize_native_target()
            llvm.initialize_native_asmprinter()
            module = llvm.parse_assembly("define double @stopped() {\n  ret double 0.0\n}\n")
            machine = llvm.Target.from_default_triple().create_target_machine()
            engine = llvm.create_mcjit_compiler(module, machine)
            engine.finalize_object()
            _compiled = (engine, engine.get_function_address("stopped"))
    return _compiled[1]


@contextlib.contextmanager
def profiler_clock_stopped(mujoco: Any) -> Iterator[None]:
    """MuJoCo's ``mjcb_time`` (of the library the package ``mujoco`` loaded) reads 0 while the
    ``with`` block runs (module docstring); blocks on several threads may overlap."""
    global _running, _before
    clock = ctypes.c_void_p.in_dll(mujoco_library(os.path.dirname(mujoco.__file__)), "mjcb_time")
    with _lock:
        stopped = _stopped_clock()
        if _running == 0:
            _before = clock.value
            clock.value = stopped
        _running += 1
    try:
        yield
    finally:
        with _lock:
            _running -= 1
            if _running == 0 and clock.value == stopped:
                clock.value = _before
