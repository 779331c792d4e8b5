"""The decorators of every compiled kernel, so that all of them share one set of numba options.

* ``cache=True``: compiled code is kept on disk (see :mod:`delaytrack._compile.disk_cache`), each
  entry saved under a file lock so that processes compiling at once keep each other's entries
  (:func:`compiled` makes every compiled kernel of the package, the engine included).
* ``error_model="numpy"``: a floating-point division by zero gives ``inf``/``NaN`` as in NumPy
  instead of raising. The simulator turns non-finite values into a ``diverged`` status for that
  run alone, whereas an exception would end the whole batch; it also drops a branch per division
  from the inner loop (about a third of the wheeled robot's right-hand side).

:data:`kernel` compiles a function on its own (callable from Python, compiled, or as plain
Python within :func:`as_python`: a run interpreted first compiles nothing);
:data:`inline_kernel` registers a plain Python function that compiles into the kernels that call
it and stays plain Python otherwise (the path of user plants given as Python callables).

:data:`hot_kernel` and :data:`hot_inline_kernel` are the same, but inlined into their compiled
callers at the numba IR level (``inline="always"``). They are for the innermost loop: the RK4
sub-step, the plant's right-hand side (evaluated four times per step) and the controller's model.
A numba call passes arrays by reference count (an atomic increment and decrement per array
argument and call), which cost more than the arithmetic of the robot's right-hand side; inlined,
the counts cancel at compile time. The delay kernels stay out-of-line: inlined (numba 0.68) they
broke the applied-input test of the two-link arm. Both are ``njit`` functions that numba inlines
into the untyped code of their callers, which is then typed once: a ``register_jitable`` function
with ``inline="always"`` is inlined after typing instead, compiled alone first and typed again in
every caller, which took the paper job's first compile from 28 s to 50 s at the same speed.
:data:`hot_inline_kernel` functions take a component's kernel and run as plain Python when it
is one (the plain-Python engine).

:func:`inline_part` is inlined into its compiled callers before typing, like them, but runs as
plain Python whenever it is called from Python: for the engine's run of one closed loop, which
allocates the run's working memory, so that numba does not compile it as a function of its own
(with the tick loop linked into it) inside the engine's compile.

:data:`tick_kernel` is :data:`kernel` compiled without numba's runtime (``_nrt=False``): the
functions called once a controller tick (the controllers' steps, the references, the plant's
integrator :func:`delaytrack.sim.integrator.integrate_tick`). They only
work in arrays their callers own (a copy into a slice is written as a loop, since numba's slice
copy needs the runtime); with the runtime, the reference counts of the views they make (about
fifty atomic operations a tick) took more than half of the time of a tick's compiled code, and
a 60 s robot run went from 20 ms to 18.7 ms without them.

:data:`borrowing_kernel` is :data:`inline_kernel` compiled without numba's runtime
(``_nrt=False``): no reference counts at all, so it may neither allocate nor return an array
(numba refuses to compile it if it does), only work in arrays its caller owns. Inlining does not
remove every count: a loop over sub-steps kept about 30 atomic operations per RK4 step, a third of
the step's time, in the plant's step; the engine's tick loop
(:func:`delaytrack.sim.engine.run_closed_loop`'s) is therefore one.

:data:`shared_kernel` is for the functions that every plant's integrator and every controller's
step call whatever the plant: the delay profile's pieces and crossings, the tick times, the small
linear algebra. An :data:`inline_kernel` is compiled again inside every compile that calls it,
and kept on disk only inside its caller's code; a :data:`shared_kernel` is compiled once for
each argument type, without numba's runtime, kept on disk on its own and loaded from there by
the next compile that calls it, whose code it is linked into (where LLVM may inline it, or
call it). The integrator of a
second plant on a machine then compiles in about half the time (the first simulation of a
pendulum of the user's after another: 2.9 s instead of 5.4 s). Called from Python, it runs as
plain Python, as an :data:`inline_kernel` does.
"""

from __future__ import annotations

import contextlib
import functools
import threading
from collections.abc import Iterator

import numba
from numba import njit
from numba.core.registry import CPUDispatcher
from numba.extending import register_jitable

from delaytrack._compile.disk_cache import locked_cache

__all__ = [
    "KERNEL_OPTIONS",
    "as_python",
    "borrowing_kernel",
    "compiled",
    "hot_inline_kernel",
    "hot_kernel",
    "inline_kernel",
    "inline_part",
    "kernel",
    "shared_kernel",
    "tick_kernel",
]

# njit would give plain functions, which the engine cannot call (numba.config sets its settings
# from the environment at run time: its typing lists none of them)
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    raise ImportError(
        "delaytrack cannot be imported with NUMBA_DISABLE_JIT=1: its engine and kernels are "
        "compiled by numba. Unset it; to step through a kernel of yours in Python, run "
        "simulate(..., engine='python'), which runs every kernel's Python function"
    )

#: numba options of every compiled kernel.
KERNEL_OPTIONS = {"cache": True, "error_model": "numpy"}


def compiled(function=None, **options):
    """``njit`` with :data:`KERNEL_OPTIONS` and ``options``, its disk cache written under a lock
    (:func:`~delaytrack._compile.disk_cache.locked_cache`); a decorator when ``function`` is
    None."""
    if function is None:
        return functools.partial(compiled, **options)
    # numba's runtime on unless turned off, and no fastmath: left unset, a function first
    # compiled inside another compile takes that compile's settings (the engine's callees run
    # without the runtime, and would fail to compile a view or an array they make; a kernel of
    # yours compiled with fastmath would change the package's numbers), and keeps them on disk
    options.setdefault("_nrt", True)
    options.setdefault("fastmath", False)
    dispatcher = locked_cache(njit(**KERNEL_OPTIONS, **options)(function))
    dispatcher.__class__ = _PackageKernel
    return dispatcher


#: Whether, on this thread, this package's compiled functions called from Python run as plain
#: Python (:func:`as_python`).
_MODE = threading.local()


@contextlib.contextmanager
def as_python() -> Iterator[None]:
    """Within it, on this thread, every compiled function of this package called from Python
    runs its plain Python function, and so do the functions it calls: a run interpreted first
    (:mod:`delaytrack._compile.interpret_first`) then compiles nothing (else numba compiles
    about a dozen small functions the plain-Python engine calls: about 2 s from an empty
    cache). A function of the user's is left as it is."""
    before = _MODE.__dict__.get("python", False)
    _MODE.python = True
    try:
        yield
    finally:
        _MODE.python = before


#: numba's call of a compiled function from Python.
_CALL_COMPILED = CPUDispatcher.__call__


class _PackageKernel(CPUDispatcher):
    """A compiled function of this package: compiled when called from Python, but as plain
    Python within :func:`as_python`. The check costs about 0.27 µs a call from Python (a small
    kernel 0.41 µs against 0.14 µs; written with ``super()`` and an attribute lookup on the
    flag, 0.65 µs): the plain-Python engine's run of the robot takes 3 % longer; compiled
    simulations call from Python once a chunk."""

    def __call__(self, *args, **kwargs):
        if _MODE.__dict__.get("python"):
            return self.py_func(*args, **kwargs)
        return _CALL_COMPILED(self, *args, **kwargs)


kernel = compiled()
inline_kernel = register_jitable(error_model=KERNEL_OPTIONS["error_model"])
hot_kernel = compiled(inline="always")
borrowing_kernel = register_jitable(error_model=KERNEL_OPTIONS["error_model"], _nrt=False)
tick_kernel = compiled(_nrt=False)


class _PythonOrCompiled(_PackageKernel):
    """A compiled function that runs as plain Python when handed a plain-Python kernel.

    Called from Python with an argument that says ``runs_as_python`` (a
    :class:`~delaytrack.components.Kernel` of a Python function), it runs its ``py_func``, whose
    calls of other such functions do the same; otherwise it runs compiled. In compiled code it
    is an ordinary ``njit`` function.
    """

    def __call__(self, *args, **kwargs):
        if _MODE.__dict__.get("python") or any(
            getattr(argument, "runs_as_python", False) for argument in args
        ):
            return self.py_func(*args, **kwargs)
        return _CALL_COMPILED(self, *args, **kwargs)


class _PythonFromPython(_PackageKernel):
    """A compiled function that runs as plain Python when called from Python (its compiled code
    is for its compiled callers)."""

    def __call__(self, *args, **kwargs):
        return self.py_func(*args, **kwargs)


def shared_kernel(function):
    """A kernel compiled on its own, without numba's runtime, kept on disk and linked into each
    compiled caller (module docstring); called from Python it runs as plain Python
    (:class:`_PythonFromPython`). It may neither allocate nor return an array."""
    dispatcher = compiled(function, _nrt=False)
    dispatcher.__class__ = _PythonFromPython
    return dispatcher


def inline_part(function):
    """A part of a compiled function inlined into it before typing (``njit(inline="always")``),
    that runs as plain Python when called from Python (:class:`_PythonFromPython`), whatever its
    arguments: for a part that allocates, so that it cannot be a :func:`shared_kernel`, or
    whose loops should be compiled for sizes its caller knows when it is compiled (a linked
    :func:`shared_kernel` is compiled without them), and that only compiled code and Python (the
    plain-Python engine, a short first run interpreted) call. Inlined, it takes its caller's
    numba settings (runtime, error model) and is kept on disk only inside its caller's code:
    settings given to it have no effect. An :data:`inline_kernel` is compiled as a function of
    its own inside each caller's compile, and LLVM optimises and generates machine code for it
    and for everything linked into it once there and again in the caller (the engine's
    :func:`~delaytrack.sim.engine.run_closed_loop`, with its tick loop linked, cost about
    0.5–1 s of every first compile of the engine)."""
    dispatcher = compiled(function, inline="always")
    dispatcher.__class__ = _PythonFromPython
    return dispatcher


def hot_inline_kernel(function):
    """A kernel inlined into its compiled callers before typing (``njit(inline="always")``),
    that runs as plain Python in the plain-Python engine (:class:`_PythonOrCompiled`).

    numba inlines an ``njit`` function with ``inline="always"`` into the untyped code of its
    caller, which then types it once; a ``register_jitable`` one is inlined after typing, compiled
    alone first and typed again inside each caller, which cost most of the compile time.
    """
    dispatcher = compiled(function, inline="always")
    dispatcher.__class__ = _PythonOrCompiled
    return dispatcher
