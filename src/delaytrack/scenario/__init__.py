"""Scenarios: one closed-loop experiment as a frozen, serialisable spec (a TOML file).

A scenario file names the true plant, the nominal model the controller believes in, the
controller and its gains, the delay profile, the reference, and the numerical settings::

    name = "two_link_S1"        # folder name of the results: letters, digits, '.', '_', '-'
    duration = 30.0             # simulated seconds, from t = 0
    dt = 0.001                  # plant RK4 step (s)
    T_c = 0.002                 # controller period (s), an integer multiple of dt
    seed = 1                    # optional; see below
    x0 = [0.0, 0.0, 0.0, 0.0]   # optional [q, qdot] at t = 0; zeros by default
    record_every = 1            # optional; record every k-th controller tick
    error_bound = 10.0          # optional "left the path" rule: |e1_j| beyond it stops the run
    input_limits = [5.0, 2.0]   # optional actuator saturation: |u_j| applied at most this
    measurement_noise = { quantization = 0.0015, velocity = 0.01, seed = 3 }   # optional
    packet_loss = { probability = 0.05, seed = 3 }   # optional: lost command packets
    u_init = [0.0, 0.0]         # optional input before the first command arrives; zeros by default

    [plant]                     # the truth: type and parameters
    type = "two-link-arm"
    [model]                     # the nominal plant M̂, N̂ used by the controller
    type = "two-link-arm"
    fd1 = 0.0
    [controller]
    type = "arolc"
    K1 = 1.0                    # a number means K1 * I, a list a diagonal, a list of lists a matrix
    ...
    [delay]
    type = "S1"                 # or "constant", "abs-sine", "piecewise-constant", "trace", "random"
    [reference]                 # q_d(t) = offset + slope t + Σ amplitude sin(frequency t + phase)
    offset = [0.0, 0.0]         # (type = "sinusoidal" by default; "spline": waypoints)
    amplitude = [0.8, 0.5]
    frequency = [0.5, 0.7]

Every key is checked: an unknown key anywhere, a missing required key or a value of the wrong type
raises :class:`ScenarioError` naming the key in dotted form (``controller.alpha``) and what is
valid. The valid keys of each table depend on its ``type``; they are listed in the error message.

**Components of your own.** Any table's ``type`` may be ``"python:<file.py>:<function>"`` or
``"python:<module>:<function>"``: the function is called with the table's other keys as keyword
arguments (a controller's also with ``model=``) and returns the plant, controller, reference or
delay profile.

**A factory is code.** It runs with your rights when the file is loaded, and a file you were
sent could name any function (``python:os:remove``). So :meth:`Scenario.from_toml` (and every
command that reads a scenario or sweep file) allows a factory only from a ``.py`` file in the
scenario file's folder or below it, after resolving ``..`` and symbolic links, or from what you
trust: ``--trust NAME`` on the command line, ``trust=[NAME, ...]`` in Python, where NAME is a
module name (``mylab.robots``: it and its submodules) or a path with a ``/`` or ending in ``.py``
(``./robots``, ``~/lab/arm.py``: that file, or every file below that folder). No module is
trusted by default, not even this package's. Anything else is refused, naming the key, before
anything is imported. A dict given to :meth:`Scenario.from_dict` is your own code and is not
checked. The scenario as run that ``delaytrack simulate`` saves names factory files by absolute
path: loading it again from another folder needs ``--trust`` for them (the error says which).

**Seed.** ``seed`` is the scenario's random seed. Every random element without a seed of its own
takes it: today that is a ``[delay]`` of type ``"random"`` without ``seed``. Such a delay also
takes the scenario's ``duration`` when it has none. A random delay with neither its own seed nor a
scenario seed is refused (results must be reproducible). :meth:`Scenario.resolved` returns the
scenario with these defaults written in, which is what ``delaytrack simulate`` saves as
"the scenario as run".

**Paths.** A table's ``path`` (a trace or waypoint CSV file) and the file of a
``"python:<file.py>:..."`` type, in a file loaded by :meth:`Scenario.from_toml`, are taken
relative to the scenario file and stored absolute.

The modules:

- :mod:`delaytrack.scenario.scenario`: :class:`Scenario` (load, validate, dump, build, run) and
  :class:`BuiltScenario`, the objects it describes.
- :mod:`delaytrack.scenario.keys`: the keys of a scenario file and the check of each value.
- :mod:`delaytrack.scenario.files`: reading a TOML file, and the files its tables name.
- :mod:`delaytrack.scenario.toml_text`: :func:`dumps_toml`, scenario data as TOML text.
- :mod:`delaytrack.scenario.table_memory`: tables met again are neither checked nor built again
  (:func:`~delaytrack.scenario.table_memory.remembered_tables`).
- :mod:`delaytrack.scenario.batch`: :func:`run_batched`, scenarios that differ only in name,
  delay and seed as one batched simulation.
- :mod:`delaytrack.scenario.builtin`: the scenario files shipped with the package.

Running a scenario and writing its results folder (the metrics, trajectories and figures of
``delaytrack simulate``) is :func:`delaytrack.jobs.scenario_run.run_to_folder`.
"""

from delaytrack.scenario.batch import run_batched
from delaytrack.scenario.builtin import builtin_scenario_names, builtin_scenario_path, load_builtin
from delaytrack.scenario.scenario import BuiltScenario, Scenario, ScenarioError
from delaytrack.scenario.toml_text import dumps_toml

__all__ = [
    "BuiltScenario",
    "Scenario",
    "ScenarioError",
    "builtin_scenario_names",
    "builtin_scenario_path",
    "dumps_toml",
    "load_builtin",
    "run_batched",
]
