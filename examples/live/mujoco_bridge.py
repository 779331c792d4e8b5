"""A robot bridge to copy: MuJoCo stands in for the firmware of the arm of examples/mujoco_arm.

    delaytrack live run examples/mujoco_arm/arm3_S1.toml --duration 10 \\
        --bridge examples/live/mujoco_bridge.py:make_bridge --out results/live_arm3_bridge

The robot node of the live loop talks to a robot through a ``RobotBridge``: at every step ``dt``
it calls ``read_state(t)`` for ``(q, q̇)`` and ``write_command(t, u)`` with the input in force
(docs/live.md, "Your robot: the bridge"). Here the robot is ``arm3.xml`` stepped by
``mujoco.mj_step`` in a thread of its own, at the model's timestep and on its own clock, whatever
the node does, as a robot's firmware runs. The lines marked ``DRIVER`` are where a real robot's
driver reads its encoders and sends its torques.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from delaytrack.live.bridge import RobotBridge
from delaytrack.plants.mujoco import import_mujoco

# MuJoCo with its warnings as Python warnings: no MUJOCO_LOG.TXT in the folder it runs from.
mujoco = import_mujoco()

MODEL = Path(__file__).resolve().parent.parent / "mujoco_arm" / "arm3.xml"
#: The joints, in the order of the scenario's plant coordinates (and of its inputs).
JOINTS = ("shoulder", "elbow", "wrist")


class MujocoArm(RobotBridge):
    """The arm: joint angles (rad) and rates (rad/s) in, motor controls (N·m before the gear)
    out, one per joint, as the scenario's plant ``type = "mujoco"`` reads the same file."""

    def __init__(self, x0: np.ndarray) -> None:
        # DRIVER: open the connection to the robot here, or in start().
        self.model = mujoco.MjModel.from_xml_path(str(MODEL))
        self.data = mujoco.MjData(self.model)
        self.qpos = [int(self.model.joint(name).qposadr[0]) for name in JOINTS]
        self.qvel = [int(self.model.joint(name).dofadr[0]) for name in JOINTS]
        n = len(JOINTS)
        self.data.qpos[self.qpos] = x0[:n]
        self.data.qvel[self.qvel] = x0[n:]
        mujoco.mj_forward(self.model, self.data)
        self.lock = threading.Lock()  # the firmware thread and the node's calls share data
        self.brakes = True  # the joints are held until the first command
        self.stopped = threading.Event()
        self.firmware = threading.Thread(target=self._run, name="arm3 firmware", daemon=True)

    def start(self) -> None:
        self.firmware.start()

    def read_state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        with self.lock:  # DRIVER: the latest encoder reading, in the plant's coordinates
            return self.data.qpos[self.qpos], self.data.qvel[self.qvel]  # (index lists: copies)

    def write_command(self, t: float, u: np.ndarray) -> None:
        with self.lock:  # DRIVER: send the motor commands; the robot holds them until the next
            self.data.ctrl[:] = u
            self.brakes = False

    def close(self) -> None:
        with self.lock:  # DRIVER: zero torque, brakes on, disconnect
            self.data.ctrl[:] = 0.0
            self.brakes = True
        self.stopped.set()
        if self.firmware.is_alive():
            self.firmware.join(timeout=1.0)

    def _run(self) -> None:
        """The firmware: one ``mj_step`` per model timestep of this thread's own clock (steps
        owed after a late wake-up are taken at once, so the physics keeps real time)."""
        step = self.model.opt.timestep
        start, done = time.monotonic(), 0
        while not self.stopped.is_set():
            owed = int((time.monotonic() - start) / step)
            while done < owed:
                with self.lock:
                    if not self.brakes:
                        mujoco.mj_step(self.model, self.data)
                done += 1
            time.sleep(max(0.0, start + (done + 1) * step - time.monotonic()))


def make_bridge(scenario, dt: float) -> MujocoArm:
    """The factory ``--bridge`` names: called once by the robot node with the scenario and its
    step ``dt`` (a driver may set its rate from it). It refuses a scenario for another robot."""
    built = scenario.build()
    names = tuple(built.plant.coordinate_names or ())
    if names != JOINTS:
        has = ", ".join(names) if names else f"{built.plant.n} unnamed coordinates"
        raise ValueError(
            f"this bridge drives the joints {', '.join(JOINTS)}; the scenario's plant has "
            f"{has}: run it with examples/mujoco_arm/arm3_S1.toml"
        )
    return MujocoArm(built.x0)  # the arm starts where the simulation would
