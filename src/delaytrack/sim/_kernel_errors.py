"""What an error of a kernel of the user's is told as: one line that names the kernel."""

from __future__ import annotations

import re

from delaytrack._compile.fingerprint import compiled_functions_reached
from delaytrack.components import Kernel

__all__ = ["could_not_compile", "numba_cause", "raised_during_the_run", "raised_in_code_of"]

_NUMBA_CAUSES = ("Error: ", "Untyped global name", "Unknown attribute", "Cannot unify")
#: What numba says of an array made (``np.zeros``, array arithmetic, a copy) in code compiled
#: without its runtime, as the simulator's loop is.
_ALLOCATION = (
    "Only accept returning of array passed into the function as argument",
    "NRT required but not enabled",
)


#: The colour and bold codes numba writes into its messages.
_TERMINAL_CODES = re.compile(r"\x1b\[[0-9;]*m")


def raised_during_the_run(error: Exception, yours: list, when: str = "during the run") -> str:
    """The one-line message for ``error``, raised by one of the user's kernels ``yours``
    (:class:`~delaytrack.components.Kernel`) while the closed loop ran (or ``when`` it did)."""
    names = sorted({name for kernel in yours for name in kernel.callable_names})
    which = (
        f"your kernel {names[0]}"
        if len(names) == 1
        else f"one of your kernels ({', '.join(names)})"
    )
    hint = (
        " (a kernel compiled with numba.njit(error_model='numpy') divides by zero into inf or "
        "nan instead, which ends only that run, with the status 'diverged')"
        if isinstance(error, ZeroDivisionError)
        else ""
    )
    return f"{which} raised {type(error).__name__} {when}: {error}{hint}"


def raised_in_code_of(kernel: Kernel, error: Exception) -> bool:
    """Whether ``error`` was raised in the code of the user's ``kernel``: a frame of its traceback
    lies in a file of the kernel's functions or of the compiled functions they call (numba gives
    the ``raise`` of compiled code a frame of its own)."""
    functions = [
        reached
        for root in kernel.roots
        if root is not None
        for reached in (root, *compiled_functions_reached(root))
    ]
    files = {
        code.co_filename
        for function in functions
        if (code := getattr(getattr(function, "py_func", function), "__code__", None))
    }
    frame = error.__traceback__
    while frame is not None:
        if frame.tb_frame.f_code.co_filename in files:
            return True
        frame = frame.tb_next
    return False


def numba_cause(error: Exception) -> str:
    """What to tell of a numba error in compiling a kernel of the user's: an array made by code
    inlined into the simulator's loop, named as such; else the innermost cause in numba's
    message (``NameError: name 'x' is not defined``), or its first line, and where to see the
    whole message."""
    text = _TERMINAL_CODES.sub("", str(error))  # numba colours its messages for a terminal
    if any(marker in text for marker in _ALLOCATION):
        return (
            "code of yours inlined into the simulator's loop (inline='always') makes a new "
            "array (np.zeros, array arithmetic, a copy), which the loop, compiled without "
            "numba's runtime, cannot free: do not inline it, or write into the arrays it is "
            "given"
        )
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    causes = [
        line
        for line in lines
        if any(marker in line for marker in _NUMBA_CAUSES)
        and not line.startswith(("Failed in", "During", "File", "raised from"))
    ]
    cause = causes[-1] if causes else f"{type(error).__name__}: {lines[0] if lines else ''}"
    return f"{cause} (call a kernel of yours alone, compiled, to see numba's whole message)"


def could_not_compile(error: Exception, what: str, kernels: tuple) -> ValueError:
    """The error for numba's ``error`` in compiling ``what`` (a part or the engine) for the
    ``kernels`` (:class:`~delaytrack.components.Kernel`) of a batch: numba could not compile a
    kernel of the user's."""
    return ValueError(
        f"numba could not compile {what} for the kernels {[k.key for k in kernels]}: "
        f"{numba_cause(error)}"
    )
