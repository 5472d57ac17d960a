"""Top-down inverse kinematics of any arm: joint targets that put the gripper's grasp point at a
position with the gripper pointing straight down and its fingers closing along a chosen horizontal
direction (push and pick-and-place, and their scripted policies).

* :class:`ChainTopDownIK` serves every arm file (:mod:`rl_environments.arm_file`): any serial chain
  of 4 to 7 joints of the description's :class:`~multiros.utils.kinematics.KinematicChain`, by
  task-priority damped least squares (position and approach first, the fingers' yaw next, the
  home pose last: a 7-joint arm's redundancy). Joint limits hold at every iterate.
* :class:`NumericTopDownIK` is its 6-joint case: the full 6-D pose (6 joints meet it exactly).
  Each solve starts from the caller's ``q0`` (the current joints: a few iterations along a
  trajectory) or from the arm's top-down seed, never from random restarts, so consecutive targets
  stay on one elbow/wrist branch.

* :class:`PlanarWristTopDownIK` is closed form for arms whose pitch joints are parallel (the RX200),
  from lengths the arm file gives (``arm.top_down_ik``).

All positions are in the robot's base frame. ``yaw`` is the direction (rad, about +z) along which
the fingers close; None closes them across the radial direction from the base, as the RX200's IK
does. A parallel gripper is symmetric under half a turn, so the solution closest to ``q0`` (or the
seed) of ``yaw`` and ``yaw + pi`` is used.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from multiros.utils.kinematics import KinematicChain
from multiros.utils.rotations import quat_from_matrix

__all__ = ["ChainTopDownIK", "NumericTopDownIK", "PlanarWristTopDownIK", "TopDownIK", "solve_each"]


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


def _limits_and_seed(chain: KinematicChain, seed: Sequence[float] | np.ndarray,
                     lower: Sequence[float] | np.ndarray | None,
                     upper: Sequence[float] | np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joint limits (default the chain's) and ``seed`` clipped into them, as float64 arrays."""
    low = np.asarray(chain.lower if lower is None else lower, dtype=np.float64)
    high = np.asarray(chain.upper if upper is None else upper, dtype=np.float64)
    return low, high, np.clip(np.asarray(seed, dtype=np.float64), low, high)


def _nearer_yaw(chain: KinematicChain, closing: int, start: np.ndarray, yaw: float) -> float:
    """Of ``yaw`` and ``yaw + pi`` (the same grasp), the one nearer the fingers' closing direction
    (the grasp frame's axis ``closing``) at the joints ``start``."""
    current = chain.fk_matrix(start)[:3, closing]
    if current[0] * math.cos(yaw) + current[1] * math.sin(yaw) < 0:
        yaw += math.pi
    return yaw


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

    def __init__(self, chain: KinematicChain, approach_axis: str, closing_axis: str,
                 seed: Sequence[float] | np.ndarray, *, lower: Sequence[float] | np.ndarray | None = None,
                 upper: Sequence[float] | np.ndarray | None = None, tol: float = 1e-4) -> None:
        if chain.n_joints != 6:
            raise ValueError(f"NumericTopDownIK needs a 6-joint chain, got {chain.n_joints}: {chain.joint_names}")
        if approach_axis == closing_axis or {approach_axis, closing_axis} - set(self._AXES):
            raise ValueError(f"approach and closing axes must be two of x, y, z; got {approach_axis}, {closing_axis}")
        self.chain = chain
        self.joint_names = chain.joint_names
        self.lower, self.upper, self.seed = _limits_and_seed(chain, seed, lower, upper)
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
        yaw = _nearer_yaw(self.chain, self._closing, start, yaw)
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


class PlanarWristTopDownIK:
    """Closed-form top-down IK of an arm whose pitch joints are parallel: a waist, a shoulder, an
    elbow and a wrist pitch in one vertical plane, then a wrist rotate (the Interbotix ReactorX /
    WidowX family: the RX200). The waist aims at the target, shoulder and elbow place the wrist
    pitch axis above it (elbow up), the wrist pitch makes the gripper vertical and the wrist rotate
    sets the yaw. An unreachable target is pulled in to the reachable edge. An arm file chooses it
    with ``arm.top_down_ik: {solver: planar_wrist, ...}`` and the lengths below.

    Args:
        shoulder_height: the shoulder axis above the base (m).
        upper_arm: the shoulder-to-elbow offset (along the arm at zero, up), m.
        forearm: the elbow-to-wrist-pitch distance (m).
        tip: the wrist pitch axis to the end-effector frame, along the gripper (m).
        joint_names: the five joints, in command order.
        lower, upper: joint limits.
    """

    def __init__(self, shoulder_height: float, upper_arm: Sequence[float], forearm: float, tip: float,
                 joint_names: Sequence[str], lower: Sequence[float] | np.ndarray,
                 upper: Sequence[float] | np.ndarray) -> None:
        if len(joint_names) != 5:
            raise ValueError(f"the planar-wrist IK serves 5 joints (waist, shoulder, elbow, wrist pitch, wrist "
                             f"rotate), got {list(joint_names)}")
        self.joint_names = tuple(joint_names)
        self.lower = np.asarray(lower, dtype=np.float64)
        self.upper = np.asarray(upper, dtype=np.float64)
        self.shoulder_height, self.forearm, self.tip = float(shoulder_height), float(forearm), float(tip)
        self.upper_arm = (float(upper_arm[0]), float(upper_arm[1]))
        self._a = float(np.hypot(*self.upper_arm))
        self._alpha0 = float(np.arctan2(self.upper_arm[1], self.upper_arm[0]))

    def solve(self, target: Sequence[float] | np.ndarray, yaw: float | None = None,
              q0: Sequence[float] | None = None) -> np.ndarray:
        """Joint targets (clipped into the limits) for the end-effector frame at ``target`` (base
        frame), gripper vertical. ``yaw``: the direction the fingers close along; None closes them
        across the radial direction (wrist rotate 0). ``q0`` is not needed (closed form)."""
        return self.solve_rows(np.asarray(target, dtype=np.float64)[None], None if yaw is None else [yaw])[0]

    def solve_rows(self, targets: np.ndarray, yaws: Sequence[float] | None = None,
                   q0: np.ndarray | None = None) -> np.ndarray:
        """:meth:`solve` for N targets (N x 3) at once, in one numpy pass (N x 5)."""
        t = np.asarray(targets, dtype=np.float64)
        x, y, z = t[:, 0], t[:, 1], t[:, 2]
        r = np.hypot(x, y)
        waist = np.where(r > 1e-6, np.arctan2(y, x), 0.0)
        dr, dz = r, z + self.tip - self.shoulder_height
        a, b = self._a, self.forearm
        dist = np.hypot(dr, dz)
        dist_c = np.minimum(np.maximum(dist, abs(a - b) + 1e-6), a + b - 1e-6)
        scale = (dist_c != dist) & (dist > 1e-9)
        ratio = np.divide(dist_c, dist, out=np.ones_like(dist), where=scale)
        dr, dz = np.where(scale, dr * ratio, dr), np.where(scale, dz * ratio, dz)
        cos_rel = (dist_c**2 - a * a - b * b) / (2 * a * b)
        rel = -np.arccos(np.clip(cos_rel, -1.0, 1.0))  # elbow up: the forearm folds down
        phi1 = np.arctan2(dz, dr) - np.arctan2(b * np.sin(rel), a + b * np.cos(rel))
        phi2 = phi1 + rel
        shoulder = self._alpha0 - phi1
        elbow = -phi2 - shoulder
        wrist = np.pi / 2 - shoulder - elbow
        rotate = np.zeros_like(waist)
        if yaws is not None:  # wrist rotate 0 closes along waist + pi/2; +t turns that by -t about +z
            rotate = (waist + np.pi / 2 - np.asarray(yaws, dtype=np.float64) + np.pi) % (2 * np.pi) - np.pi
            # the same grasp half a turn round turns the wrist less
            rotate = np.where(np.abs(rotate) > np.pi / 2, (rotate + 2 * np.pi) % (2 * np.pi) - np.pi, rotate)
        return np.clip(np.stack([waist, shoulder, elbow, wrist, rotate], axis=1), self.lower, self.upper)


#: A solution from the current pose within this error (metres, plus a tenth of the approach error in
#: radians) is kept: restarting from the seed reaches a tenth of a millimetre nearer, but often in
#: another configuration of the arm, a jump across its redundancy in one step that throws a held cube
#: (a 7-joint arm's elbow moved 0.8 rad in 40 ms) and that a robot's safety rules would refuse.
_KEEP_NEAR = 2e-3


def _dls(jac: np.ndarray, damping: float) -> np.ndarray:
    """The damped least-squares inverse ``J^T (J J^T + lambda^2 I)^-1``."""
    return jac.T.dot(np.linalg.inv(jac.dot(jac.T) + (damping * damping) * np.eye(jac.shape[0])))


class ChainTopDownIK:
    """Top-down IK for any serial chain of 4 to 7 joints (an arm file's arm), by task-priority
    damped least squares on the description's :class:`~multiros.utils.kinematics.KinematicChain`.

    Priorities, each in the null space of the ones before: (1) the grasp point at the target and the
    approach axis pointing down; (2) the fingers closing along the yaw; (3) the joints toward the
    pose the solve starts from when it is given one (``q0``, the arm's current pose: a 7-joint arm's
    redundancy then stays where it is, step after step, instead of jumping to the configuration
    nearest home), else toward ``home`` (a 4- or 5-joint arm may not meet (2) exactly, and then comes
    as close as (1) allows). Every iterate is clamped to the joint limits. A 6-joint chain is solved
    as :class:`NumericTopDownIK` does (the full pose), so the shipped 6-joint arms keep their solutions.

    Args:
        chain: base -> grasp-frame chain.
        approach_axis, closing_axis: the grasp frame's axes out of the gripper and along the fingers.
        seed: a top-down configuration to start from when the caller gives no ``q0``.
        home: the pose the redundancy is resolved toward (default ``seed``).
        lower, upper: joint limits (default the chain's).
        tol: position tolerance (m); the approach tolerance is ``tol * 10`` rad.
    """

    _AXES = {"x": 0, "y": 1, "z": 2}

    def __init__(self, chain: KinematicChain, approach_axis: str, closing_axis: str, seed: Sequence[float], *,
                 home: Sequence[float] | None = None, lower: Sequence[float] | None = None,
                 upper: Sequence[float] | None = None, tol: float = 1e-4) -> None:
        if not 4 <= chain.n_joints <= 7:
            raise ValueError(f"top-down IK serves chains of 4 to 7 joints, got {chain.n_joints}: {chain.joint_names}")
        self.chain = chain
        self.joint_names = chain.joint_names
        self.lower, self.upper, self.seed = _limits_and_seed(chain, seed, lower, upper)
        self.home = self.seed if home is None else np.clip(np.asarray(home, dtype=np.float64), self.lower, self.upper)
        self.tol = float(tol)
        self._six = (NumericTopDownIK(chain, approach_axis, closing_axis, self.seed, lower=self.lower,
                                      upper=self.upper, tol=tol) if chain.n_joints == 6 else None)
        self._approach, self._closing = self._AXES[approach_axis], self._AXES[closing_axis]

    def solve_rows(self, targets: np.ndarray, yaws: Sequence[float] | None = None,
                   q0: np.ndarray | None = None) -> np.ndarray:
        """:meth:`solve` for N targets, row by row."""
        return solve_each(self, targets, yaws, q0)

    def solve(self, target: Sequence[float] | np.ndarray, yaw: float | None = None,
              q0: Sequence[float] | None = None) -> np.ndarray:
        if self._six is not None:
            return self._six.solve(target, yaw, q0)
        target = np.asarray(target, dtype=np.float64)
        yaw = _closing_yaw(float(target[0]), float(target[1]), yaw)
        start = self.seed if q0 is None else np.clip(np.asarray(q0, dtype=np.float64), self.lower, self.upper)
        yaw = _nearer_yaw(self.chain, self._closing, start, yaw)
        # From the current pose, the redundancy stays where it is (a step of the arm, not a jump to the
        # configuration nearest home); from the seed it is resolved toward home.
        best_q, best_err = self._iterate(start, target, yaw, rest=None if q0 is None else start)
        if q0 is not None and best_err > _KEEP_NEAR:  # from the seed only when the current pose cannot get there
            q, err = self._iterate(self.seed, target, yaw)
            if err < best_err:
                best_q, best_err = q, err
        return np.clip(best_q, self.lower, self.upper)

    def _iterate(self, q: np.ndarray, target: np.ndarray, yaw: float, iters: int = 150,
                 rest: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        down = np.array([0.0, 0.0, -1.0])
        along = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        n = q.shape[0]
        eye = np.eye(n)
        q = np.clip(q, self.lower, self.upper)
        err = math.inf
        pull = math.inf  # the last step toward home: resolving the redundancy goes on until it is small
        for _ in range(iters):
            tf = self.chain.fk_matrix(q)
            approach, closing = tf[:3, self._approach], tf[:3, self._closing]
            e_pos = target - tf[:3, 3]
            e_app = np.cross(approach, down)  # rotation taking the approach axis down
            err = float(np.linalg.norm(e_pos)) + 0.1 * float(np.linalg.norm(e_app))
            if np.linalg.norm(e_pos) < self.tol and np.linalg.norm(e_app) < 10 * self.tol and (
                    rest is not None or pull < 1e-3):
                break
            jac = self.chain.jacobian(q)
            jv, jw = jac[:3], jac[3:]
            # (1) position and approach: the angular rows across the approach axis only
            across = np.eye(3) - np.outer(approach, approach)
            j1 = np.vstack([jv, across.dot(jw)])
            e1 = np.concatenate([e_pos, e_app])
            p1 = _dls(j1, 0.02)
            dq = p1.dot(e1)
            null1 = eye - np.linalg.pinv(j1, rcond=1e-4).dot(j1)  # exact: a damped one leaks into (1)
            # (2) the yaw: the rotation about the approach axis that turns the fingers along the yaw
            e_yaw = float(np.dot(np.cross(closing, along), approach))
            j2 = approach.dot(jw)[None, :].dot(null1)
            p2 = _dls(j2, 0.05)
            dq = dq + null1.dot(p2.dot(np.array([e_yaw]) - approach.dot(jw).dot(dq)[None]))
            # (3) toward the rest pose (the start when solving from the current pose, else home), in what is left
            null2 = null1.dot(eye - np.linalg.pinv(j2, rcond=1e-4).dot(j2))
            toward = null2.dot(0.1 * ((self.home if rest is None else rest) - q))
            pull = float(np.max(np.abs(toward)))
            dq = dq + toward
            step = float(np.max(np.abs(dq)))
            if step > 0.3:
                dq *= 0.3 / step
            q = np.clip(q + dq, self.lower, self.upper)
        return q, err
