"""Top-down inverse kinematics of the VX300S, UR5e and Ned2: joint targets that put the gripper's
grasp point at a position with the gripper pointing straight down and its fingers closing along a
chosen horizontal direction.

* :class:`VX300STopDownIK` is closed form: the ViperX 300 S is the RX200's geometry (waist, three
  parallel pitch joints, the gripper on the pitch plane) plus a forearm roll, held at 0. The same
  solution as :class:`rl_environments.manipulation.RX200TopDownIK`, from the VX300S's lengths, and
  the sixth joint (wrist_rotate) turns the fingers to any yaw.
* :class:`UR5eTopDownIK` and :class:`NED2TopDownIK` are numeric (damped least squares on the
  description's :class:`~multiros.utils.kinematics.KinematicChain`, full 6-D pose): the UR5e's
  shoulder-to-wrist lateral offset and the Ned2's jaws sitting 11.5 mm off the tool axis make a
  closed form a page of special cases, and 6 joints meet the full pose. Each solve starts from the
  caller's ``q0`` (the current joints: a few iterations along a trajectory) or from the arm's
  top-down seed, never from random restarts, so consecutive targets stay on one elbow/wrist branch.

All positions are in the robot's base frame. ``yaw`` is the direction (rad, about +z) along which
the fingers close; None closes them across the radial direction from the base, as the RX200's IK
does. A parallel gripper is symmetric under half a turn, so the solution closest to ``q0`` (or the
seed) of ``yaw`` and ``yaw + pi`` is used.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from multiros.utils.kinematics import KinematicChain, quat_from_matrix

__all__ = ["NED2TopDownIK", "NumericTopDownIK", "TopDownIK", "UR5eTopDownIK", "VX300STopDownIK", "solve_each",
           "top_down_ik"]


class TopDownIK(Protocol):
    """What every arm's top-down IK offers."""

    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def solve(self, target: Sequence[float] | np.ndarray, yaw: float | None = None,
              q0: Sequence[float] | None = None) -> np.ndarray:
        """Joint targets (``joint_names`` order, within the limits) for the grasp point at ``target``."""
        ...

    def solve_rows(self, targets: np.ndarray, yaws: Sequence[float] | None = None,
                   q0: np.ndarray | None = None) -> np.ndarray:
        """:meth:`solve` for N targets (N x 3), seeds ``q0`` (N x joints); N x joints."""
        ...


def solve_each(ik: TopDownIK, targets: np.ndarray, yaws: Sequence[float] | None = None,
               q0: np.ndarray | None = None) -> np.ndarray:
    """``solve_rows`` of an IK that solves one target at a time (iterative ones): row by row."""
    return np.array([ik.solve(t, None if yaws is None else yaws[j], None if q0 is None else q0[j])
                     for j, t in enumerate(np.asarray(targets, dtype=np.float64))])


def _wrap(angle: float) -> float:
    return float((angle + math.pi) % (2 * math.pi) - math.pi)


def _closing_yaw(x: float, y: float, yaw: float | None) -> float:
    """The fingers' closing direction: ``yaw``, or across the radial direction to ``(x, y)``."""
    if yaw is not None:
        return float(yaw)
    return float(math.atan2(y, x) + math.pi / 2) if math.hypot(x, y) > 1e-6 else math.pi / 2


class VX300STopDownIK:
    """Closed-form top-down IK of the ViperX 300 S (joints ``vx300s_description.ARM_JOINTS``).

    The waist aims at the target, shoulder and elbow place the wrist_angle axis above it,
    wrist_angle makes the gripper vertical, forearm_roll stays 0 and wrist_rotate sets the yaw.
    Lengths from ``vx300s.urdf.xacro`` (Interbotix'): shoulder axis 0.12705 m above the base,
    upper arm (0.05955, 0.3), forearm 0.2 + 0.1 to the wrist_angle axis, from there 0.176944 m
    along the gripper to ``ee_gripper_link``. A target out of reach is pulled in to the edge.

    Args:
        lower, upper: joint limits to clip to (default the URDF's, ``vx300s_description``).
    """

    SHOULDER_Z = 0.079 + 0.04805
    UPPER = (0.05955, 0.3)
    FOREARM = 0.2 + 0.1
    TIP = 0.069744 + 0.042825 + 0.025875 + 0.0385

    def __init__(self, lower: Sequence[float] | None = None, upper: Sequence[float] | None = None) -> None:
        from rl_environments.robots import vx300s_description as pkg

        self.joint_names: tuple[str, ...] = tuple(pkg.ARM_JOINTS)
        self.lower = np.asarray(pkg.JOINT_LOWER if lower is None else lower, dtype=np.float64)
        self.upper = np.asarray(pkg.JOINT_UPPER if upper is None else upper, dtype=np.float64)
        self._a = float(np.hypot(*self.UPPER))
        self._alpha0 = float(np.arctan2(self.UPPER[1], self.UPPER[0]))

    def solve_rows(self, targets: np.ndarray, yaws: Sequence[float] | None = None,
                   q0: np.ndarray | None = None) -> np.ndarray:
        """:meth:`solve` for N targets, row by row."""
        return solve_each(self, targets, yaws, q0)

    def solve(self, target: Sequence[float] | np.ndarray, yaw: float | None = None,
              q0: Sequence[float] | None = None) -> np.ndarray:
        x, y, z = (float(v) for v in target)
        r = float(np.hypot(x, y))
        waist = float(np.arctan2(y, x)) if r > 1e-6 else 0.0
        dr, dz = r, z + self.TIP - self.SHOULDER_Z
        a, b = self._a, self.FOREARM
        dist = float(np.hypot(dr, dz))
        dist_c = min(max(dist, abs(a - b) + 1e-6), a + b - 1e-6)
        if dist_c != dist and dist > 1e-9:
            dr, dz = dr * dist_c / dist, dz * dist_c / dist
        cos_rel = (dist_c**2 - a * a - b * b) / (2 * a * b)
        rel = -float(np.arccos(np.clip(cos_rel, -1.0, 1.0)))  # elbow up: the forearm folds down
        phi1 = float(np.arctan2(dz, dr) - np.arctan2(b * np.sin(rel), a + b * np.cos(rel)))
        shoulder = self._alpha0 - phi1
        elbow = -(phi1 + rel) - shoulder
        wrist = np.pi / 2 - shoulder - elbow
        # With the gripper pointing down, wrist_rotate = 0 closes the fingers along waist + pi/2;
        # turning it by +t turns the closing direction by -t about +z.
        rotate = _wrap(waist + math.pi / 2 - _closing_yaw(x, y, yaw))
        if abs(rotate) > math.pi / 2:  # the other of the two equivalent grasps turns the wrist less
            rotate = _wrap(rotate + math.pi)
        if q0 is not None:
            prev = float(np.asarray(q0, dtype=np.float64)[5])
            alt = _wrap(rotate + math.pi)
            if abs(alt - prev) < abs(rotate - prev) and self.lower[5] <= alt <= self.upper[5]:
                rotate = alt
        q = np.array([waist, shoulder, elbow, 0.0, wrist, rotate])
        return np.clip(q, self.lower, self.upper)


@functools.lru_cache(maxsize=8)
def _chain(package: str, base: str, tip: str) -> KinematicChain:
    from importlib import import_module

    pkg = import_module(f"rl_environments.robots.{package}")
    return KinematicChain.from_urdf(pkg.URDF_XACRO, base, tip)


class NumericTopDownIK:
    """Top-down IK by damped least squares on a 6-joint chain (full pose: position, gripper down,
    fingers along the yaw).

    Args:
        chain: base -> grasp-frame chain of the arm's six joints.
        approach_axis: the grasp frame's axis (``"x"``, ``"y"`` or ``"z"``) pointing out of the gripper.
        closing_axis: its axis along which the fingers close.
        seed: a top-down configuration to start from when the caller gives no ``q0``.
        lower, upper: joint limits (default the chain's).
        tol: position tolerance (m); the orientation tolerance is ``tol * 10`` rad.
    """

    _AXES = {"x": 0, "y": 1, "z": 2}

    def __init__(self, chain: KinematicChain, approach_axis: str, closing_axis: str, seed: Sequence[float], *,
                 lower: Sequence[float] | None = None, upper: Sequence[float] | None = None,
                 tol: float = 1e-4) -> None:
        if chain.n_joints != 6:
            raise ValueError(f"NumericTopDownIK needs a 6-joint chain, got {chain.n_joints}: {chain.joint_names}")
        if approach_axis == closing_axis or {approach_axis, closing_axis} - set(self._AXES):
            raise ValueError(f"approach and closing axes must be two of x, y, z; got {approach_axis}, {closing_axis}")
        self.chain = chain
        self.joint_names = chain.joint_names
        self.lower = np.asarray(chain.lower if lower is None else lower, dtype=np.float64)
        self.upper = np.asarray(chain.upper if upper is None else upper, dtype=np.float64)
        self.seed = np.clip(np.asarray(seed, dtype=np.float64), self.lower, self.upper)
        self._approach, self._closing = self._AXES[approach_axis], self._AXES[closing_axis]
        self.tol = float(tol)

    def orientation(self, yaw: float) -> np.ndarray:
        """The grasp frame's rotation (base frame) pointing down with the fingers closing along ``yaw``."""
        rot = np.zeros((3, 3))
        rot[:, self._approach] = (0.0, 0.0, -1.0)
        rot[:, self._closing] = (math.cos(yaw), math.sin(yaw), 0.0)
        third = 3 - self._approach - self._closing
        a, c = rot[:, self._approach], rot[:, self._closing]
        # a right-handed frame: x = y cross z, y = z cross x, z = x cross y
        rot[:, third] = np.cross(a, c) if (self._approach + 1) % 3 == self._closing else np.cross(c, a)
        return rot

    def solve_rows(self, targets: np.ndarray, yaws: Sequence[float] | None = None,
                   q0: np.ndarray | None = None) -> np.ndarray:
        """:meth:`solve` for N targets, row by row."""
        return solve_each(self, targets, yaws, q0)

    def solve(self, target: Sequence[float] | np.ndarray, yaw: float | None = None,
              q0: Sequence[float] | None = None) -> np.ndarray:
        target = np.asarray(target, dtype=np.float64)
        yaw = _closing_yaw(float(target[0]), float(target[1]), yaw)
        start = self.seed if q0 is None else np.clip(np.asarray(q0, dtype=np.float64), self.lower, self.upper)
        # Of yaw and yaw + pi (the same grasp), try first the one closer to the start's closing
        # direction; the other when that one is out of the joints' reach; the seed last.
        current = self.chain.fk_matrix(start)[:3, self._closing]
        if current[0] * math.cos(yaw) + current[1] * math.sin(yaw) < 0:
            yaw += math.pi
        attempts = [(start, yaw), (start, yaw + math.pi)]
        if q0 is not None:
            attempts += [(self.seed, yaw), (self.seed, yaw + math.pi)]
        best = None
        for q_start, aim in attempts:
            quat = quat_from_matrix(self.orientation(aim))
            result = self.chain.ik(target, quat, q_start, tol=self.tol, rot_tol=10 * self.tol, restarts=0,
                                   max_iters=100)
            if best is None or result.error < best.error:
                best = result
            if result.converged:
                break
        assert best is not None  # attempts is never empty
        return np.clip(best.q, self.lower, self.upper)


class UR5eTopDownIK(NumericTopDownIK):
    """Top-down IK of the UR5e to ``grasp_link`` (joints ``ur5e_description.ARM_JOINTS``): elbow up,
    wrist 2 at -pi/2 from its seed ``ur5e_description.HOME_POSE``."""

    def __init__(self, lower: Sequence[float] | None = None, upper: Sequence[float] | None = None) -> None:
        from rl_environments.robots import ur5e_description as pkg

        super().__init__(_chain("ur5e_description", pkg.BASE_LINK, pkg.EE_LINK), "z", "x", pkg.HOME_POSE,
                         lower=lower, upper=upper)


class NED2TopDownIK(NumericTopDownIK):
    """Top-down IK of the Ned2 to ``grasp_link`` (joints ``ned2_description.ARM_JOINTS``), from a
    seed with the wrist bent down (joint_5 -1.5)."""

    SEED = (0.0, 0.1, -0.3, 0.0, -1.4, 0.0)

    def __init__(self, lower: Sequence[float] | None = None, upper: Sequence[float] | None = None) -> None:
        from rl_environments.robots import ned2_description as pkg

        super().__init__(_chain("ned2_description", pkg.BASE_LINK, pkg.EE_LINK), "x", "y", self.SEED,
                         lower=lower, upper=upper)


_IK: dict[str, Callable[[], TopDownIK]] = {"vx300s": VX300STopDownIK, "ur5e": UR5eTopDownIK, "ned2": NED2TopDownIK}


def top_down_ik(arm: str) -> TopDownIK:
    """The top-down IK of ``arm`` (``"vx300s"``, ``"ur5e"`` or ``"ned2"``)."""
    try:
        return _IK[arm]()
    except KeyError:
        raise ValueError(f"no top-down IK for arm {arm!r}; arms: {sorted(_IK)}") from None
