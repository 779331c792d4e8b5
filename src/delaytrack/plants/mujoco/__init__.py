"""Robots from MuJoCo model files (the optional extra ``delaytrack[mujoco]``)."""

from __future__ import annotations

from delaytrack.plants.mujoco.plant import MujocoPlant, import_mujoco

__all__ = ["MujocoPlant", "import_mujoco"]
