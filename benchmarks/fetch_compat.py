"""Run gymnasium-robotics 1.4.2's Fetch envs under mujoco >= 3.12, for side-by-side baselines.

Since mujoco 3.12, ``mujoco_enum == np.int32(x)`` is False while ``np.int32(x) == mujoco_enum`` is
True, so ``gymnasium_robotics.utils.mujoco_utils``'s ``joint_type in (mjJNT_HINGE, mjJNT_SLIDE)``
asserts fail (fixed upstream after 1.4.2). This gives that module a ``mujoco`` whose joint enums
are plain ints; everything else is the real module. Benchmarks only: the library never uses it.
"""

from __future__ import annotations

import types

import mujoco


class _JointTypes:
    mjJNT_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
    mjJNT_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
    mjJNT_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
    mjJNT_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)


class _MujocoWithIntJoints(types.ModuleType):
    mjtJoint = _JointTypes

    def __getattr__(self, name: str):
        return getattr(mujoco, name)


def patch_gymnasium_robotics() -> None:
    """Make gymnasium-robotics' MuJoCo helpers compare joint types as ints (idempotent)."""
    from gymnasium_robotics.utils import mujoco_utils

    if not isinstance(mujoco_utils.mujoco, _MujocoWithIntJoints):
        mujoco_utils.mujoco = _MujocoWithIntJoints("mujoco")


def make_fetch_reach():
    """``FetchReach-v4`` with the patch applied."""
    import gymnasium as gym
    import gymnasium_robotics

    patch_gymnasium_robotics()
    gym.register_envs(gymnasium_robotics)
    return gym.make("FetchReach-v4")
