"""A robot from a MuJoCo model file (MJCF, or URDF read by MuJoCo's compiler) as an
Euler–Lagrange plant or nominal model.

MuJoCo computes, at any ``(q, q̇)``, the joint-space inertia ``M(q)`` (armature included), the
bias forces ``qfrc_bias = C(q, q̇) q̇ + g(q)`` and the passive forces (joint springs and
dampers), and maps actuator controls to joint forces. :class:`MujocoPlant` reads them into
the form every plant of this toolkit has (the paper's eq. (1))::

    M(q) q̈ + N(q, q̇) = G(q) u,   N = qfrc_bias - qfrc_passive,   G[:, j] = ∂qfrc_actuator/∂u_j

so the same model file serves as the simulated robot and, perturbed (``mass_scale``), as the
controller's nominal model, in every command. The compiled terms kernel calls MuJoCo's C
functions (:mod:`~delaytrack.plants.mujoco.capi`): ``mj_fwdPosition`` and ``mj_fwdVelocity``
for ``M``'s factors and the forces, ``mj_mulM`` for the columns of ``M``, and
``mj_fwdActuation`` for the columns of ``G``.

What this form leaves out is refused unless asked for: constraint forces (joint and tendon
limits, friction loss, equality constraints) and the clamping of controls and forces to their
ranges are not part of ``M q̈ + N = G u``. Contacts cannot be known from the file; a simulated
robot whose bodies touch needs MuJoCo's own stepping (``stepping="mujoco"``), which applies all
of them.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import importlib
import sys
import threading
import unicodedata
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from delaytrack._compile.jit import tick_kernel
from delaytrack._io import regular_file
from delaytrack._result_columns import trajectory_columns
from delaytrack._validation import as_spd_matrix, positive_scalar
from delaytrack.plants.base import ELPlant
from delaytrack.plants.mujoco.capi import (
    call_void2,
    call_void4,
    function_address,
    read_at,
    write_at,
)
from delaytrack.plants.mujoco.model_files import check_model_files
from delaytrack.plants.mujoco.timer import profiler_clock_stopped
from delaytrack.warning import DelaytrackWarning

__all__ = ["JointNamesWarning", "MujocoPlant", "extras_start", "mujoco_step", "mujoco_terms"]

#: Control used to read a column of ``G``: a power of two, so that dividing by it is exact.
_PROBE = 2.0**-20
#: Layout of the parameter vector (addresses as float64, exact below 2**53).
_MODEL, _DATA, _QPOS, _QVEL, _CTRL, _BIAS, _PASSIVE, _ACTUATOR = range(8)
_POSITION, _VELOCITY, _ACTUATION, _MUL_M, _VECTOR, _PRODUCT, _RESET, _STEP = range(8, 16)
_PARAMS = 16
#: Then the coordinates' places in MuJoCo's ``qpos`` (n entries) and ``qvel`` (n entries).
_INDICES = _PARAMS
#: How the simulated plant advances: this toolkit's RK4 on the terms, or MuJoCo's mj_step.
STEPPINGS = ("rk4", "mujoco")
#: MuJoCo's bound on a "bad" number (mjMAXVAL): it zeroes such a control.
_MUJOCO_LARGEST = 1e10

_INSTALL = "MuJoCo is not installed: pip install -e '.[mujoco]' (from a clone of delaytrack)"


def import_mujoco() -> Any:
    """The ``mujoco`` package, or an ImportError that says how to install it.

    MuJoCo's warnings (an unstable simulation, a full contact buffer) become Python
    ``RuntimeWarning`` s, unless a handler of yours is installed already: MuJoCo's own would
    print them and append them to a file ``MUJOCO_LOG.TXT`` in the current folder, which is the
    user's (the run's status says when it diverged)."""
    try:
        mujoco = importlib.import_module("mujoco")
    except ImportError:
        raise ImportError(_INSTALL) from None
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_warn)
    return mujoco


#: The warnings MuJoCo gave while this thread read a model file (:class:`MujocoPlant`), or None.
_reading = threading.local()
#: MuJoCo's warning that a model file holds a NaN (which it then replaces or keeps).
_NAN_READ = "XML contains a 'NaN'"


def _warn(text: str) -> None:
    """MuJoCo's warning handler: a Python warning, one line placed at MuJoCo (it comes from
    MuJoCo's C code, mostly on one of the engine's threads, not from a line of yours). Nothing
    may raise through MuJoCo's C code (the process would abort), so a warning that a filter
    turns into an error is printed. While this thread reads a model file, the warning is also
    kept for :class:`MujocoPlant` to see, which refuses a file with a NaN instead of warning of
    it (with a handler of yours installed, such a file is MuJoCo's to read)."""
    met = getattr(_reading, "met", None)
    if met is not None:
        met.append(text)
        if _NAN_READ in text:
            return
    try:
        warnings.warn_explicit(
            f"MuJoCo: {text}", RuntimeWarning, "mujoco", 0, module="delaytrack.plants.mujoco"
        )
    except Exception:  # noqa: BLE001 - "error" filters: say it, do not raise into C
        print(f"MuJoCo warning: {text}", file=sys.stderr)


@tick_kernel
def extras_start(n):
    """Where a plant built on :class:`MujocoPlant` (``n`` coordinates) may put parameters of
    its own: after MuJoCo's addresses and the coordinates' places."""
    return _INDICES + 2 * n


@tick_kernel
def mujoco_terms(t, q, qdot, params, M, N, G):
    """Terms kernel of :class:`MujocoPlant`: ``M``, ``N = qfrc_bias - qfrc_passive`` and
    ``G[:, j] = qfrc_actuator(u = δ e_j) / δ`` (δ = 2⁻²⁰) of the model at ``(q, q̇)``."""
    n = q.shape[0]
    m = G.shape[1]
    model = params[_MODEL]
    data = params[_DATA]
    for i in range(n):
        write_at(params[_QPOS], i, q[i])
        write_at(params[_QVEL], i, qdot[i])
        write_at(params[_VECTOR], i, 0.0)
    for j in range(m):
        write_at(params[_CTRL], j, 0.0)
    call_void2(params[_POSITION], model, data)
    call_void2(params[_VELOCITY], model, data)
    for i in range(n):
        N[i] = read_at(params[_BIAS], i) - read_at(params[_PASSIVE], i)
    for j in range(n):  # column j of M: M e_j
        write_at(params[_VECTOR], j, 1.0)
        call_void4(params[_MUL_M], model, data, params[_PRODUCT], params[_VECTOR])
        for i in range(n):
            M[i, j] = read_at(params[_PRODUCT], i)
        write_at(params[_VECTOR], j, 0.0)
    for j in range(m):  # column j of G: the joint forces of control δ e_j, over δ
        write_at(params[_CTRL], j, _PROBE)
        call_void2(params[_ACTUATION], model, data)
        for i in range(n):
            G[i, j] = read_at(params[_ACTUATOR], i) / _PROBE
        write_at(params[_CTRL], j, 0.0)


@tick_kernel
def mujoco_step(t, x, u, dt, params, first):
    """One ``mj_step`` of the model from ``x = [q, q̇]`` with controls ``u`` held; ``x`` gets
    the state after it. The first step of a run resets MuJoCo's data (``mj_resetData``), so that
    a run does not depend on the one before it; MuJoCo's other state (activations, the
    solver's warm start) carries over from step to step, as in MuJoCo's own loop. A control
    beyond MuJoCo's 1e10 makes ``x`` NaN (the run then stops as diverged), and MuJoCo's
    automatic reset of a bad state is turned off (:class:`MujocoPlant`), so that a diverging
    state reaches the simulator's check. ``x`` holds the plant's coordinates only: the model's
    other joints (:attr:`MujocoPlant.coordinates`) move in MuJoCo's data."""
    n = x.shape[0] // 2
    model = params[_MODEL]
    data = params[_DATA]
    if first:
        call_void2(params[_RESET], model, data)
    for j in range(u.shape[0]):
        # MuJoCo would set a control beyond 1e10 to zero and go on: a diverged run instead.
        if not abs(u[j]) <= _MUJOCO_LARGEST:
            for i in range(2 * n):
                x[i] = np.nan
            return
    for i in range(n):
        write_at(params[_QPOS], int(params[_INDICES + i]), x[i])
        write_at(params[_QVEL], int(params[_INDICES + n + i]), x[n + i])
    for j in range(u.shape[0]):
        write_at(params[_CTRL], j, u[j])
    call_void2(params[_STEP], model, data)
    for i in range(n):
        x[i] = read_at(params[_QPOS], int(params[_INDICES + i]))
        x[n + i] = read_at(params[_QVEL], int(params[_INDICES + n + i]))


_JOINT_KINDS = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}
#: The unit of a joint force by the joint's kind: a torque on a hinge, a force on a slide.
_FORCE_UNITS = {3: "N·m", 2: "N"}


def _input_units(mujoco: Any, model: Any) -> tuple[str, ...] | None:
    """Each actuator's control unit where MuJoCo's units give it for all of them: a motor of
    gain 1 and gear ±1 on a hinge joint takes N·m, on a slide joint N (its control is the joint
    force); None when any actuator's control is not a joint force (a gear g makes it a g-th of
    the force, a servo's control is a position; a ball or free joint has no one unit)."""
    joint = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
    units = []
    for j in range(model.nu):
        motor = (
            model.actuator_trntype[j] in joint
            and model.actuator_dyntype[j] == 0
            and model.actuator_gaintype[j] == 0
            and model.actuator_biastype[j] == 0
            and model.actuator_gainprm[j, 0] == 1.0
            and abs(model.actuator_gear[j, 0]) == 1.0
        )
        if not motor:  # its target may be a site, tendon or body: no joint to look up
            return None
        unit = _FORCE_UNITS.get(int(model.jnt_type[int(model.actuator_trnid[j, 0])]))
        if unit is None:
            return None
        units.append(unit)
    return tuple(units)


def _input_names(mujoco: Any, model: Any) -> tuple[str, ...] | None:
    """The actuators' names, an unnamed one as ``u<j>`` (``j`` from 1); None when none is named
    or two would share a name."""
    names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, j) or f"u{j + 1}"
        for j in range(model.nu)
    ]
    named = any(name != f"u{j + 1}" for j, name in enumerate(names))
    return tuple(names) if named and len(set(names)) == len(names) else None


@dataclass(frozen=True, eq=False)
class MujocoPlant(ELPlant):
    """A robot from a MuJoCo model file: coordinates are its joints, inputs its actuators.

    Parameters
    ----------
    path : str or Path
        An MJCF (``.xml``) or URDF file that MuJoCo's compiler reads.
    mass_scale : float
        Factor (> 0) on every body's mass and inertia: ``0.8`` makes a nominal model 20 %
        light, as a controller's model of the real robot would be.
    actuator_limits : {"refuse", "ignore"}
        A model whose actuators clamp their controls or forces (``ctrlrange``/``forcerange``
        with limits on) is refused (``"refuse"``): the clamping is not part of
        ``M q̈ + N = G u``. ``"ignore"`` uses it without the clamps (for a nominal model, or a
        plant whose commands stay in range).
    constraints : {"refuse", "ignore"}
        The same for joint limits and joint friction loss, which MuJoCo applies as constraint
        forces.
    add_motors : bool
        Put a motor (gear 1, named after its joint) on every joint that no actuator of the
        file drives: a URDF file has no actuators.
    coordinates : sequence of str, optional
        Names of the joints (hinge or slide) that are the plant's coordinates ``q``, in this
        order; all joints by default. With ``stepping="mujoco"`` only: the other joints (a
        floating base's height, pitch and roll, a caster) are MuJoCo's to move, like its
        contact state, and the controller sees the coordinates it has a model of (a wheeled
        robot's ``x, y``, heading and wheel angles).
    stepping : {"rk4", "mujoco"}
        As the simulated plant: ``"rk4"`` integrates ``M q̈ + N = G u`` with the simulator's
        RK4, split where the delayed command switches; ``"mujoco"`` steps the model with
        MuJoCo's ``mj_step`` and the integrator of its file (contacts, limits, friction loss
        and every actuator type included), holding the command in force at each step's start.
        The run's ``dt`` must then be the file's ``timestep``. As a nominal model the terms
        are used either way.
    name : str, optional
        Shown in results and reports (the model's name by default).
    contact_time_constant : float, optional
        The time constant (s) of every contact of the model (MuJoCo's ``solref``, the first
        number, of every geom and contact pair; the damping ratio is kept, or 1): how soft
        the contacts are. None keeps the file's (MuJoCo's default is 0.02 s). MuJoCo needs at
        least two timesteps; a smaller value is refused rather than raised by MuJoCo.

    Notes
    -----
    Only hinge and slide joints are coordinates: free and ball joints are refused unless
    ``coordinates`` leaves them out. A floating base, such as a wheeled robot's, is written
    with slide and hinge joints (``x``, ``y``, heading; and height, pitch, roll left out of
    ``coordinates`` when the base rests on contacts) in the file. Actuators must be direct: no
    activation dynamics (``dyntype`` none), a fixed gain and no state-dependent bias, so that
    their joint forces are ``G(q) u`` (motors with any ``gear``).

    With ``stepping="mujoco"`` none of the refusals about actuators, limits and friction loss
    apply (MuJoCo steps them), and contacts act; MuJoCo's state beyond ``q, q̇`` (the joints
    left out of ``coordinates``, activations, the solver's warm start) lives in its data, reset
    at the start of each run (the file's reference pose ``qpos0``, at rest).

    The coordinates are named after their joints in results (``ae_<joint>``, columns
    ``<joint>_rad``) when those names are different identifiers that give every column a name
    of its own; otherwise (a joint without a name, ``joint-1``, or joints ``a`` and ``a_d``,
    whose columns would share the name ``a_d_rad``) they are ``q1 .. qn``, in this order, with
    a :class:`JointNamesWarning`. When one of ``q1 .. qn`` is the name of a joint of the model,
    the prefix is repeated (``qq1 .. qqn``, then ``qqq1 ..``) until none is: a column named
    ``q1`` never holds another joint than one named ``q1``.

    The plant holds MuJoCo's ``mjData``, which every evaluation writes (``thread_safe`` is
    False): each thread of a batch runs a copy of its own (:meth:`for_worker`), made from the
    file once and kept. Run one ``simulate`` call at a time with a given plant (two threads of
    yours simulating the same plant object at once would share its data).
    """

    path: str | Path
    mass_scale: float = 1.0
    actuator_limits: str = "refuse"
    constraints: str = "refuse"
    add_motors: bool = False
    stepping: str = "rk4"
    name: str | None = None
    coordinates: tuple[str, ...] | None = None
    contact_time_constant: float | None = None
    n: int = field(init=False)
    m: int = field(init=False)
    coordinate_names: tuple[str, ...] | None = field(init=False)
    coordinate_units: tuple[str, ...] | None = field(init=False)
    input_units: tuple[str, ...] | None = field(init=False)
    input_names: tuple[str, ...] | None = field(init=False)
    _model: Any = field(init=False, repr=False)
    _data: Any = field(init=False, repr=False)
    _scratch: np.ndarray = field(init=False, repr=False)
    _params: np.ndarray = field(init=False, repr=False)
    _copies: dict[int, MujocoPlant] = field(init=False, repr=False)
    _identity: np.ndarray = field(init=False, repr=False)
    type_name: ClassVar[str] = "mujoco"
    thread_safe: ClassVar[bool] = False

    def __post_init__(self) -> None:
        mujoco = import_mujoco()
        path = Path(self.path)
        object.__setattr__(self, "path", path)
        regular_file(path, "path =")  # MuJoCo would wait on a FIFO, or read a device forever
        check_model_files(path)  # and so on a file the model includes or names
        scale = positive_scalar("mass_scale", self.mass_scale)
        object.__setattr__(self, "mass_scale", scale)
        for key in ("actuator_limits", "constraints"):
            if getattr(self, key) not in ("refuse", "ignore"):
                raise ValueError(f"{key} must be 'refuse' or 'ignore'; got {getattr(self, key)!r}")
        if self.stepping not in STEPPINGS:
            raise ValueError(f"stepping must be one of {list(STEPPINGS)}; got {self.stepping!r}")
        if not isinstance(self.add_motors, bool):
            raise TypeError(f"add_motors must be true or false; got {self.add_motors!r}")
        _reading.met = []  # what MuJoCo warns of while this thread reads the file (_warn)
        try:
            model = _load(mujoco, path, self.add_motors)
        except Exception as error:  # noqa: BLE001 - MuJoCo's own message names the problem
            message = " ".join(str(error).split())
            raise ValueError(f"path {str(path)!r}: MuJoCo could not read it: {message}") from None
        finally:
            met, _reading.met = _reading.met, None
        if any(_NAN_READ in text for text in met):
            # MuJoCo reads it and goes on: a mass from the body's density, a NaN timestep.
            raise ValueError(
                f"path {str(path)!r}: a number of the file is NaN, for which MuJoCo would put "
                "a value of its own or a NaN; give it a value"
            )
        joints = self._coordinate_joints(mujoco, model, path)
        self._check(mujoco, model, path, joints)
        if self.stepping == "mujoco":  # a diverging state must reach the simulator, not reset
            model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
        elif not np.any(model.actuator_trntype == int(mujoco.mjtTrn.mjTRN_BODY)):
            # Never stepped by MuJoCo: M, N, G only, which read no contact or constraint (but
            # an actuator pushing through its body's contacts, adhesion, reads both).
            model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT) | int(
                mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
            )
        model.body_mass[1:] *= scale
        model.body_inertia[1:] *= scale
        if self.contact_time_constant is not None:
            self._set_contact_time_constant(model)
        data = mujoco.MjData(model)
        mujoco.mj_setConst(model, data)
        names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints)
        # Slide joints move in metres, hinge joints turn in radians (MuJoCo's units).
        units = tuple("m" if model.jnt_type[j] == 2 else "rad" for j in joints)
        joint_names = _coordinate_names(
            path, names, units, int(model.nu), _model_joint_names(mujoco, model)
        )
        scratch = np.zeros((2, model.nv))
        params = np.zeros(_INDICES + 2 * len(joints))
        params[_INDICES : _INDICES + len(joints)] = model.jnt_qposadr[joints]
        params[_INDICES + len(joints) :] = model.jnt_dofadr[joints]
        params[[_MODEL, _DATA]] = model._address, data._address
        for index, array in (
            (_QPOS, data.qpos),
            (_QVEL, data.qvel),
            (_CTRL, data.ctrl),
            (_BIAS, data.qfrc_bias),
            (_PASSIVE, data.qfrc_passive),
            (_ACTUATOR, data.qfrc_actuator),
            (_VECTOR, scratch[0]),
            (_PRODUCT, scratch[1]),
        ):
            params[index] = array.ctypes.data
        for index, function in (
            (_POSITION, "mj_fwdPosition"),
            (_VELOCITY, "mj_fwdVelocity"),
            (_ACTUATION, "mj_fwdActuation"),
            (_MUL_M, "mj_mulM"),
            (_RESET, "mj_resetData"),
            (_STEP, "mj_step"),
        ):
            params[index] = function_address(mujoco, function)
        for key, value in (
            ("n", len(joints)),
            ("m", int(model.nu)),
            ("coordinate_names", joint_names),
            ("coordinate_units", units),
            ("input_units", _input_units(mujoco, model)),
            ("input_names", _input_names(mujoco, model)),
            ("_model", model),
            ("_data", data),
            ("_scratch", scratch),
            ("_params", params),
            ("_copies", {}),
            (
                "name",
                self.name
                if self.name is not None
                else (model.names.split(b"\0")[0].decode() or path.stem),
            ),
        ):
            object.__setattr__(self, key, value)
        object.__setattr__(self, "_identity", self._compiled_identity(mujoco))
        if self.coordinates is not None:
            return  # stepped by MuJoCo: no terms of the chosen joints alone
        mass, nonlinear, input_map = self.terms(np.zeros(self.n), np.zeros(self.n))
        if not all(np.all(np.isfinite(array)) for array in (mass, nonlinear, input_map)):
            raise ValueError(f"path {str(path)!r}: the model gives non-finite terms at q = 0")
        as_spd_matrix(f"the M(0) of {str(path)!r}", mass[0], self.n)

    def _coordinate_joints(self, mujoco: Any, model: Any, path: Path) -> list[int]:
        """Ids of the joints that are the coordinates: :attr:`coordinates`, or every joint."""
        if model.njnt == 0:
            raise ValueError(f"path {str(path)!r}: the model has no joints")
        if self.coordinates is None:
            return list(range(model.njnt))
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
        chosen = self.coordinates
        if isinstance(chosen, str) or not all(isinstance(name, str) for name in chosen):
            raise TypeError(f"coordinates must be a list of joint names; got {chosen!r}")
        chosen = tuple(chosen)
        object.__setattr__(self, "coordinates", chosen)
        if not chosen or len(set(chosen)) != len(chosen):
            raise ValueError(
                f"coordinates must name joints, each once; got {list(chosen)} (joints of "
                f"{str(path)!r}: {names})"
            )
        if self.stepping != "mujoco":
            raise ValueError(
                "coordinates (a part of the joints) needs stepping='mujoco': MuJoCo moves the "
                "other joints, and M q'' + N = G u of a part of the joints is not defined"
            )
        unknown = [name for name in chosen if name not in names]
        if unknown:
            raise ValueError(
                f"coordinates: {unknown} are not joints of {str(path)!r}; its joints: {names}"
            )
        return [names.index(name) for name in chosen]

    def _set_contact_time_constant(self, model: Any) -> None:
        time_constant = positive_scalar("contact_time_constant", self.contact_time_constant)
        timestep = float(model.opt.timestep)
        if time_constant < 2.0 * timestep:
            raise ValueError(
                f"contact_time_constant must be at least two of the model's timesteps, "
                f"{2.0 * timestep:g} s (MuJoCo would raise it to that); got {time_constant:g}"
            )
        object.__setattr__(self, "contact_time_constant", time_constant)
        for solref in (model.geom_solref, model.pair_solref):
            solref[:, 1] = np.where(solref[:, 0] > 0.0, solref[:, 1], 1.0)
            solref[:, 0] = time_constant

    def _check(self, mujoco: Any, model: Any, path: Path, joints: list[int]) -> None:
        """Refuse what ``M q̈ + N = G u`` cannot represent (class notes)."""
        where = f"path {str(path)!r}"
        joint = lambda j: mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"#{j}"  # noqa: E731
        actuator = lambda j: mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, j) or f"#{j}"  # noqa: E731
        for j in joints:
            kind = int(model.jnt_type[j])
            if kind not in (2, 3):
                raise ValueError(
                    f"{where}: joint {joint(j)!r} is a {_JOINT_KINDS[kind]} joint; only "
                    "hinge and slide joints can be coordinates (write a floating base as slide "
                    "and hinge joints: x, y, heading; or leave it out of coordinates)"
                )
        if model.nu == 0:
            raise ValueError(
                f"{where}: the model has no actuators (a URDF file has none); pass "
                "add_motors=True to put a motor on every joint"
            )
        for j in range(model.nu):
            if float(getattr(model, "actuator_delay", np.zeros(model.nu))[j]) > 0.0:
                raise ValueError(
                    f"{where}: actuator {actuator(j)!r} has a delay of its own (MuJoCo's "
                    "'delay'); give the delay in the scenario's [delay] table instead"
                )
        if self.stepping == "mujoco":
            return  # MuJoCo steps it: actuators, limits and contacts are its own
        if np.any(getattr(model, "jnt_actgravcomp", np.zeros(0))):
            raise ValueError(
                f"{where}: a joint takes gravity compensation through its actuators "
                "(actuatorgravcomp), which M q̈ + N = G u does not have"
            )
        for j in range(model.nu):
            direct = (
                model.actuator_dyntype[j] == 0
                and model.actuator_gaintype[j] == 0
                and model.actuator_biastype[j] == 0
            )
            if not direct:
                raise ValueError(
                    f"{where}: actuator {actuator(j)!r} has activation dynamics, a variable gain "
                    "or a bias (a position or velocity servo); only direct actuators (motors, "
                    "any gear) map controls to joint forces as G(q) u"
                )
            limited = (
                model.actuator_ctrllimited[j]
                or model.actuator_forcelimited[j]
                or (  # a joint's actuatorfrcrange (the target is a joint, not a tendon)
                    model.actuator_trntype[j] == int(mujoco.mjtTrn.mjTRN_JOINT)
                    and model.jnt_actfrclimited[int(model.actuator_trnid[j, 0])]
                )
            )
            if limited and self.actuator_limits == "refuse":
                raise ValueError(
                    f"{where}: actuator {actuator(j)!r} clamps its control or force "
                    "(ctrlrange, forcerange, or its joint's actuatorfrcrange, which a URDF "
                    "effort limit becomes), which M q̈ + N = G u does not; pass "
                    "actuator_limits='ignore' to use the model without the clamps"
                )
        if self.constraints == "refuse":
            for j in range(model.njnt):
                if model.jnt_limited[j]:
                    raise ValueError(
                        f"{where}: joint {joint(j)!r} has limits, a constraint force that "
                        "M q̈ + N = G u leaves out; pass constraints='ignore' to use the model "
                        "without them"
                    )
            others = (
                ("equality constraints", model.neq > 0),
                ("tendon limits", bool(np.any(model.tendon_limited))),
                ("tendon friction loss", bool(np.any(model.tendon_frictionloss > 0.0))),
            )
            for what, present in others:
                if present:
                    raise ValueError(
                        f"{where}: the model has {what}, constraint forces that "
                        "M q̈ + N = G u leaves out; pass constraints='ignore' to use the model "
                        "without them"
                    )
            for dof in range(model.nv):
                if model.dof_frictionloss[dof] > 0.0:
                    raise ValueError(
                        f"{where}: joint {joint(int(model.dof_jntid[dof]))!r} has friction loss, "
                        "a constraint force that M q̈ + N = G u leaves out; pass "
                        "constraints='ignore' to use the model without it"
                    )

    def __reduce__(self) -> tuple:
        # Made again from its file when copied or sent to another process: the parameter
        # vector holds addresses of this process's MuJoCo data.
        arguments = {item.name: getattr(self, item.name) for item in fields(self) if item.init}
        return (_made_again, (type(self), arguments))

    def while_running(self) -> contextlib.AbstractContextManager[None]:
        """MuJoCo's profiling clock stopped (:mod:`delaytrack.plants.mujoco.timer`): its clock
        reads cost a small model about as much as its physics."""
        return profiler_clock_stopped(import_mujoco())

    def for_worker(self, index: int) -> MujocoPlant:
        if index not in self._copies:
            twin = copy.copy(self)  # made again from the file (__reduce__)
            if not np.array_equal(twin.run_identity, self.run_identity):
                raise ValueError(
                    f"path {str(self.path)!r} changed after the plant was made: the threads of "
                    "a batch would simulate another model; make the plant again"
                )
            self._copies[index] = twin
        return self._copies[index]

    @property
    def params(self) -> np.ndarray:
        return self._params

    def terms(
        self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.coordinates is not None:
            raise ValueError(
                f"{self.name!r} has no M, N, G of its coordinates {list(self.coordinates)} "
                "alone (MuJoCo moves its other joints): it is a simulated plant only"
            )
        return super().terms(q, qdot, t)

    @property
    def terms_kernel(self):
        return mujoco_terms

    @property
    def stepper_kernel(self):
        return mujoco_step if self.stepping == "mujoco" else None

    def check_step(self, dt: float) -> None:
        """Stepped by MuJoCo, the run's ``dt`` must be the model's ``timestep``."""
        timestep = float(self._model.opt.timestep)
        if self.stepping == "mujoco" and not abs(dt - timestep) <= 1e-12 * timestep:
            raise ValueError(
                f"dt = {dt:g} s disagrees with the timestep {timestep:g} s of {str(self.path)!r}, "
                "which MuJoCo steps it with: set dt to it (or <option timestep> in the file)"
            )

    @property
    def run_identity(self) -> np.ndarray:
        """The compiled model (MuJoCo's binary ``.mjb`` of it, masses scaled) and the
        coordinates' places, as numbers: what a sweep unit's hash covers instead of the
        parameter vector's addresses."""
        return self._identity

    def _compiled_identity(self, mujoco: Any) -> np.ndarray:
        buffer = np.zeros(mujoco.mj_sizeModel(self._model), dtype=np.uint8)
        mujoco.mj_saveModel(self._model, None, buffer)
        digest = hashlib.sha256(buffer.tobytes() + self._params[_INDICES:].tobytes()).digest()
        return np.frombuffer(digest, dtype=np.uint8).astype(float)

    def to_spec(self) -> dict[str, Any]:
        spec: dict[str, Any] = {"type": self.type_name, "path": str(self.path)}
        if self.mass_scale != 1.0:
            spec["mass_scale"] = self.mass_scale
        for key in ("actuator_limits", "constraints"):
            if getattr(self, key) != "refuse":
                spec[key] = getattr(self, key)
        if self.add_motors:
            spec["add_motors"] = True
        if self.stepping != "rk4":
            spec["stepping"] = self.stepping
        if self.coordinates is not None:
            spec["coordinates"] = list(self.coordinates)
        if self.contact_time_constant is not None:
            spec["contact_time_constant"] = self.contact_time_constant
        return spec


class JointNamesWarning(DelaytrackWarning):
    """A MuJoCo model's joint names cannot name the coordinates in results, which are named
    ``q1 .. qn`` instead (:class:`MujocoPlant`); the message names the joints and why."""


def _model_joint_names(mujoco: Any, model: Any) -> set[str]:
    """The names of every joint of the model (chosen as coordinates or not), NFKC-normalised."""
    joint = mujoco.mjtObj.mjOBJ_JOINT
    named = (mujoco.mj_id2name(model, joint, j) for j in range(model.njnt))
    return {unicodedata.normalize("NFKC", name) for name in named if name}


def _names_problem(
    names: tuple[str | None, ...], identifiers: tuple[str, ...], units: tuple[str, ...], m: int
) -> str | None:
    """Why the joints' names cannot name the coordinates in results, or None when they can:
    different identifiers whose columns are all different (joints ``a`` and ``a_d`` are not:
    ``a``'s reference and ``a_d``'s angle are both ``a_d_rad``). ``identifiers`` are the
    ``names`` that are identifiers, in order."""
    if len(identifiers) < len(names):
        unnamed = [repr(name) for name in names if name not in identifiers]
        verb = "is not a name" if len(unnamed) == 1 else "are not names"
        return f"{', '.join(unnamed)} {verb} of letters, digits and '_'"
    try:
        trajectory_columns(identifiers, units, len(identifiers), None, m)
    except ValueError:
        return "two of their result columns would share a name"
    return None


def _coordinate_names(
    path: Path,
    names: tuple[str | None, ...],
    units: tuple[str, ...],
    m: int,
    taken: set[str],
) -> tuple[str, ...]:
    """The joints' ``names`` when they can name the coordinates, else ``q1 .. qn`` with the
    prefix repeated until none is one of the model's joint names ``taken``, announced with a
    :class:`JointNamesWarning` (:class:`MujocoPlant`)."""
    identifiers = tuple(name for name in names if name and name.isidentifier())
    problem = _names_problem(names, identifiers, units, m)
    if problem is None:
        return identifiers
    prefix = "q"
    while any(f"{prefix}{i}" in taken for i in range(1, len(names) + 1)):
        prefix += "q"
    fallback = tuple(f"{prefix}{i}" for i in range(1, len(names) + 1))
    avoided = "" if prefix == "q" else f" (q1 .. q{len(names)} are names of the model's joints)"
    warnings.warn(
        JointNamesWarning(
            f"MuJoCo model {str(path)!r}: the joints {list(names)} cannot name the coordinates "
            f"in results ({problem}); they are named {fallback[0]} .. {fallback[-1]} in this "
            f"order{avoided}"
        ),
        stacklevel=4,
    )
    return fallback


def _made_again(cls: type, arguments: dict[str, Any]) -> MujocoPlant:
    return cls(**arguments)


def _load(mujoco: Any, path: Path, add_motors: bool) -> Any:
    """MuJoCo's compiled model of the file, with a motor on every joint no actuator drives
    when ``add_motors``."""
    if not add_motors:
        return mujoco.MjModel.from_xml_path(str(path))
    spec = mujoco.MjSpec.from_file(str(path))
    driven = {actuator.target for actuator in spec.actuators}
    for joint in spec.joints:
        if joint.name not in driven:
            motor = spec.add_actuator()
            motor.name = joint.name
            motor.target = joint.name
            motor.trntype = mujoco.mjtTrn.mjTRN_JOINT
    return spec.compile()
