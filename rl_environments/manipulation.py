"""Push and pick-and-place, the parts every arm shares: object and goal sampling, vectorised
rewards and success, and object velocities from consecutive poses.

Pure functions (no ROS call, no side effect), so HER can call the reward on batches (``axis=-1``).
Fetch's conventions (Gymnasium-Robotics ``FetchPush``/``FetchPickAndPlace``): the achieved goal is
the object's position, sparse reward 0 on success and -1 otherwise, dense ``-distance``, success
within ``distance_threshold``; goals on the table for push, in the air half of the time for
pick-and-place.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rl_environments.reach import RewardType, goal_distance, goal_reward, is_success

__all__ = [
    "ObjectGoalSampler",
    "goal_distance",
    "goal_reward",
    "is_success",
    "quat_to_euler",
    "rotation_velocities",
    "rotation_velocity",
    "RewardType",
]


@dataclass(frozen=True)
class ObjectGoalSampler:
    """Object start poses and goals on (or above) a table, relative to the robot base.

    Args:
        object_low, object_high: box of the object's start ``(x, y)``.
        goal_low, goal_high: box of the goal's ``(x, y)``.
        rest_z: the object's centre height when it rests on the table.
        air_probability: chance a goal is lifted (0 for push, Fetch's 0.5 for pick-and-place).
        air_height: a lifted goal is ``rest_z + U(0, air_height)``.
        min_distance: object and goal at least this far apart (3-D).
        yaw_range: the object's yaw is the radial direction from the base plus ``U(-yaw_range, yaw_range)``.
    """

    object_low: tuple[float, float]
    object_high: tuple[float, float]
    goal_low: tuple[float, float]
    goal_high: tuple[float, float]
    rest_z: float
    air_probability: float = 0.0
    air_height: float = 0.0
    min_distance: float = 0.08
    yaw_range: float = 0.3

    def sample(self, rng: np.random.Generator, max_tries: int = 1000) -> tuple[np.ndarray, float, np.ndarray]:
        """``(object position, object yaw, goal)`` drawn with ``rng``; object and goal apart.

        Raises:
            RuntimeError: the boxes are too small for ``min_distance``.
        """
        for _ in range(max_tries):
            obj = np.array([*rng.uniform(self.object_low, self.object_high), self.rest_z])
            goal = np.array([*rng.uniform(self.goal_low, self.goal_high), self.rest_z])
            if self.air_probability > 0 and rng.uniform() < self.air_probability:
                goal[2] += rng.uniform(0.0, self.air_height)
            if np.linalg.norm(goal - obj) >= self.min_distance:
                yaw = float(np.arctan2(obj[1], obj[0]) + rng.uniform(-self.yaw_range, self.yaw_range))
                return obj, yaw, goal
        raise RuntimeError(
            f"no object/goal pair {self.min_distance} m apart in {max_tries} draws: the object and goal boxes "
            "are too small; widen them or lower min_object_goal_distance"
        )


def yaw_quat(yaw: float) -> np.ndarray:
    """Quaternion ``(w, x, y, z)`` of a rotation by ``yaw`` about z."""
    return np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def quat_to_euler(q: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (x-y-z extrinsic, as Fetch's ``mat2euler``) of ``(w, x, y, z)`` quaternions."""
    w, x, y, z = (np.asarray(q, dtype=np.float64)[..., i] for i in range(4))
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


def rotation_velocity(q0: np.ndarray, q1: np.ndarray, dt: float) -> np.ndarray:
    """World-frame angular velocity taking orientation ``q0`` to ``q1`` in ``dt`` seconds."""
    return rotation_velocities(np.asarray(q0)[None], np.asarray(q1)[None], np.array([dt]))[0]


def rotation_velocities(q0: np.ndarray, q1: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """World-frame angular velocities (N x 3) taking orientations ``q0`` to ``q1`` (N x 4, ``w, x, y,
    z``) in ``dt`` seconds (N); zero where the rotation is below 1e-12 or ``dt <= 0``."""
    q0, q1 = np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64)
    w0, v0 = q0[:, 0], -q0[:, 1:]  # conjugate of q0
    w1, v1 = q1[:, 0], q1[:, 1:]
    # q1 * conj(q0): the world-frame rotation between them
    w = w1 * w0 - np.einsum("ij,ij->i", v1, v0)
    c = np.empty_like(v1)  # v1 x v0
    c[:, 0] = v1[:, 1] * v0[:, 2] - v1[:, 2] * v0[:, 1]
    c[:, 1] = v1[:, 2] * v0[:, 0] - v1[:, 0] * v0[:, 2]
    c[:, 2] = v1[:, 0] * v0[:, 1] - v1[:, 1] * v0[:, 0]
    v = w1[:, None] * v0 + w0[:, None] * v1 + c
    flip = w < 0
    w = np.where(flip, -w, w)
    v = np.where(flip[:, None], -v, v)
    s = np.sqrt(np.einsum("ij,ij->i", v, v))
    ok = (s >= 1e-12) & (np.asarray(dt) > 0)
    out = np.zeros_like(v)
    if ok.any():
        angle = 2.0 * np.arctan2(s[ok], w[ok])
        out[ok] = v[ok] / s[ok, None] * (angle / np.asarray(dt, dtype=np.float64)[ok])[:, None]
    return out


def object_reward(achieved_goal: np.ndarray, desired_goal: np.ndarray, threshold: float,
                  reward_type: RewardType) -> np.ndarray | float:
    """Fetch's reward: sparse 0 / -1 within ``threshold``, or dense ``-distance``; vectorised."""
    return goal_reward(achieved_goal, desired_goal, threshold, reward_type)
