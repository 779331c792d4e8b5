"""Compiling on two cores: a helper process compiles part of what a first run needs.

numba compiles one function at a time, in one thread, and a first run of a new combination needs
several: the engine and the functions it calls through their address
(:mod:`delaytrack.sim.native_parts`), each compiled on its own and kept in numba's disk cache.
When there are two or more to compile and two cores or more, :func:`start` hands some of them to
a helper process, chosen so that the two processes finish at about the same time
(:func:`share`). Both write the disk cache; this process compiles its own share, waits for the
helper (:meth:`Helper.wait`), and then loads the helper's share from the cache.

The helper imports each function and kernel by its module and name, and checks that a kernel of
the user's has the same fingerprint as here (:attr:`delaytrack.components.Kernel.key`); a
function it cannot import (defined in ``__main__`` or inside another function) stays in this
process. Whatever the helper does not deliver, because it failed or was stopped, this process
compiles as it would without it, so results and error messages do not depend on the helper.

The helper is for a core with nothing to do: it is started when the load average of the last
minute is below the number of cores less one half (so not in a batch of processes already
using every core, such as pytest or dask workers, where it would only compete with them). Set
the environment variable ``DELAYTRACK_COMPILE_HELPER`` to ``0`` to compile in one process, or to
``1`` to start the helper whenever there are two cores, whatever the load.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import pickle
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from typing import IO, Any

from delaytrack._numba_cache import cache_directory
from delaytrack.components import Kernel

__all__ = ["ENVIRONMENT", "CompileJob", "Helper", "main", "share", "spare_core", "start"]

#: The environment variable that turns the helper off (``0``) or on whatever the load (``1``).
ENVIRONMENT = "DELAYTRACK_COMPILE_HELPER"

#: Rough seconds a helper takes to start (importing numba and delaytrack), in the units of
#: :attr:`CompileJob.cost`.
START_UP = 2.5

#: What the helper runs: it sets its module search path to this process's before importing
#: delaytrack, so that it imports the same package and the user's modules.
_BOOTSTRAP = (
    "import pickle, sys\n"
    "with open(sys.argv[1], 'rb') as file:\n"
    "    sys.path[:] = pickle.load(file)\n"
    "    from delaytrack.sim.compile_helper import main\n"
    "    code = main(file)\n"
    "sys.exit(code)\n"
)


@dataclass(frozen=True)
class CompileJob:
    """One function to compile for one signature.

    Parameters
    ----------
    function : numba dispatcher
        The function, with numba's disk cache.
    signature : tuple of numba types
        Its argument types.
    kernels : tuple of Kernel
        The components' kernels named in ``signature``
        (:class:`~delaytrack.components.KernelType`), which the helper makes again.
    cost : float
        Rough seconds its compile takes, relative to the others (to share the work).
    """

    function: Any
    signature: tuple
    kernels: tuple
    cost: float


def _cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def spare_core() -> bool:
    """Whether a helper may run beside this process (:data:`ENVIRONMENT`, the cores, the load)."""
    setting = os.environ.get(ENVIRONMENT, "").strip()
    cores = _cores()
    if setting == "0" or cores < 2:
        return False
    if setting == "1":
        return True
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):  # no load average (Windows): assume a core is free
        return True
    return load < cores - 0.5


def _name(function: Any) -> tuple[str, str] | None:
    """``(module, name)`` under which another process imports ``function`` (a numba dispatcher
    or a plain function): its qualified name, or a name its module gives it (a dispatcher made
    from another function, such as ``run_batch_compiled``); None when there is none."""
    python = getattr(function, "py_func", function)
    module_name = getattr(python, "__module__", None)
    module = sys.modules.get(module_name) if module_name != "__main__" else None
    if module is None:
        return None
    found: Any = module
    for attribute in getattr(python, "__qualname__", "").split("."):
        found = getattr(found, attribute, None)
    if found is function:
        return (module_name, python.__qualname__)
    names = [name for name, value in vars(module).items() if value is function]
    return (module_name, names[0]) if names else None


def _kernel_recipe(kernel: Kernel) -> tuple | None:
    """How the helper makes ``kernel`` again: its key and the names of its functions."""
    functions = (kernel.function, kernel.command_map, kernel.stepper)
    names = tuple(None if function is None else _name(function) for function in functions)
    pairs = zip(names, functions, strict=True)
    if any(name is None and function is not None for name, function in pairs):
        return None
    return (kernel.key, names, kernel.identity_mass, kernel.sizes)


def _recipe(job: CompileJob) -> tuple | None:
    """What the helper needs to compile ``job`` (pickled), or None when it cannot."""
    function = _name(job.function)
    kernels = tuple(_kernel_recipe(kernel) for kernel in job.kernels)
    if function is None or None in kernels:
        return None
    recipe = (function, job.signature, kernels)
    try:
        pickle.dumps(recipe)
    except Exception:  # noqa: BLE001 - a type that does not pickle: compiled here
        return None
    return recipe


def share(costs: Sequence[float], movable: Sequence[bool]) -> list[int]:
    """Which jobs go to the helper: the positions of ``costs`` that it compiles.

    Longest first, each job goes to the process that would finish it first (the helper starts
    :data:`START_UP` late); a job that is not ``movable`` stays here. Returns no position when
    the helper would not finish before this process alone.
    """
    order = sorted(range(len(costs)), key=lambda i: -costs[i])
    here, helper, given = 0.0, START_UP, []
    for i in order:
        if movable[i] and helper < here:
            helper += costs[i]
            given.append(i)
        else:
            here += costs[i]
    if not given or max(here, helper) >= sum(costs):
        return []
    return sorted(given)


class Helper:
    """A helper process compiling its share of the jobs (made by :func:`start`)."""

    def __init__(self, process: subprocess.Popen, files: Sequence[str]) -> None:
        self.process = process
        self._files = files

    def wait(self) -> bool:
        """Wait for the helper to finish; whether it compiled its whole share."""
        try:
            return self.process.wait() == 0
        finally:
            self._remove_files()

    def stop(self) -> None:
        """End the helper if it still runs (this process failed or was interrupted)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        self._remove_files()

    def _remove_files(self) -> None:
        for path in self._files:
            with contextlib.suppress(OSError):
                os.remove(path)


def start(jobs: Sequence[CompileJob]) -> tuple[Helper | None, list[int]]:
    """Start a helper for its share of ``jobs`` (:func:`share`).

    Returns the helper and the positions of the jobs it compiles; ``(None, [])`` when there is
    no helper: fewer than two jobs, no spare core (:func:`spare_core`), no job the helper can
    import, or a helper that could not be started.
    """
    if len(jobs) < 2 or not spare_core():
        return None, []
    recipes = [_recipe(job) for job in jobs]
    given = share([job.cost for job in jobs], [recipe is not None for recipe in recipes])
    if not given:
        return None, []
    try:
        with tempfile.NamedTemporaryFile("wb", suffix=".pickle", delete=False) as file:
            pickle.dump(list(sys.path), file)
            pickle.dump((str(cache_directory()), [recipes[i] for i in given]), file)
        process = subprocess.Popen(
            [sys.executable, "-c", _BOOTSTRAP, file.name],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    except Exception:  # noqa: BLE001 - no helper: everything is compiled here
        with contextlib.suppress(Exception):
            os.remove(file.name)
        return None, []
    return Helper(process, [file.name]), given


def _imported(name: tuple[str, str]) -> Any:
    found: Any = importlib.import_module(name[0])
    for attribute in name[1].split("."):
        found = getattr(found, attribute)
    return found


def _make_kernel(recipe: tuple) -> None:
    """Make the kernel of ``recipe`` (:func:`_kernel_recipe`) known to numba in this process;
    refuse one whose code differs from the one the other process asked for."""
    key, names, identity_mass, sizes = recipe
    function, command_map, stepper = (None if name is None else _imported(name) for name in names)
    kernel = Kernel.of(function, command_map, identity_mass, sizes, stepper)
    if kernel.key != key:
        raise RuntimeError(f"the kernel {key} changed on disk")
    kernel.numba_type  # noqa: B018 - registers the kernel under its key for the compiler


def main(file: IO[bytes]) -> int:
    """The helper: compile the jobs pickled in ``file`` after the module search path.

    Returns 0 when every job compiled, 1 when one failed (the other process compiles it and
    reports the error), 2 when this process's cache folder is not the other's.
    """
    cache, recipes = pickle.load(file)
    if str(cache_directory()) != cache:
        return 2
    failed = 0
    for function, signature, kernels in recipes:
        try:
            for kernel in kernels:
                _make_kernel(kernel)
            _imported(function).compile(signature)
        except Exception:  # noqa: BLE001 - left to the other process
            failed = 1
    return failed
