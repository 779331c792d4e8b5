"""The compile machinery: how the engine and the components' kernels are compiled by numba.

Its entries are :func:`compile_engine`, the compile stage of :func:`~delaytrack.sim.simulate`,
and :func:`interpret`, which says whether a short first run should run as plain Python instead
of waiting for that compile. Its modules, each one concept:

* :mod:`~delaytrack._compile.disk_cache`: numba's cache folder, keyed by the package's
  compiled source (imported first by :mod:`delaytrack`);
* :mod:`~delaytrack._compile.jit`: the decorators of every compiled kernel;
* :mod:`~delaytrack._compile.functions`: compiled or not, this package's or the user's;
* :mod:`~delaytrack._compile.fingerprint`: the hash of all the code a kernel of the user's
  reaches, which names its compiled code;
* :mod:`~delaytrack._compile.own_options` and :mod:`~delaytrack._compile.random_reads`: a
  user's kernel's numba options, and the random modules its code reads;
* :mod:`~delaytrack._compile.guards`: what a kernel of the user's must not do, refused;
* :mod:`~delaytrack._compile.kernel_type`: a component's kernel as a numba type;
* :mod:`~delaytrack._compile.native_call` and :mod:`~delaytrack._compile.stack_arrays`: calls
  through an address, and working arrays on the stack, in compiled code;
* :mod:`~delaytrack._compile.native_parts`: the functions the compiled engine calls through
  their address, each compiled for one component;
* :mod:`~delaytrack._compile.first_compile`, :mod:`~delaytrack._compile.stale_caches`,
  :mod:`~delaytrack._compile.helper_process`, :mod:`~delaytrack._compile.helper_ahead` and
  :mod:`~delaytrack._compile.ahead`: a first compile announced (and what waits for it called
  after it), from the source as it is now, on two cores with a helper started ahead when a
  compile is certain, with the parts and values a job will need next;
* :mod:`~delaytrack._compile.stage`: the compile stage itself;
* :mod:`~delaytrack._compile.interpret_first`: a short first run as plain Python while that is
  quicker than compiling.

The component protocol (:mod:`delaytrack.components`) and the engine use the lower modules;
the stage uses the engine.
"""

import lazy_loader

# The names of __init__.pyi, each imported from its module when first used: importing one
# module of the package runs this file, which then imports none of the others.
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
