"""Forward kinematics, geometric Jacobian and damped-least-squares inverse kinematics from a URDF.

A :class:`KinematicChain` is the serial chain of joints between two links of a URDF. It replaces the
KDL / trac_ik helpers the original MultiROS envs used (``pykdl_utils``, ``Kinematics_pyrobot``) with
pure numpy, so end-effector actions and goal sampling work without ROS or a MuJoCo model.

Example:
    >>> chain = KinematicChain.from_urdf(urdf_text, "rx200/base_link", "rx200/ee_gripper_link")
    >>> pos, quat_wxyz = chain.fk(np.zeros(chain.n_joints))
    >>> q, converged, err = chain.ik(pos + [0.0, 0.05, 0.0])

Why hand-written: the URDF is parsed with ``xml.etree`` because only ``<joint>`` elements are
needed; yourdfpy would build a scene graph and load meshes, and robotics libraries with a chain
solver (ikpy, pinocchio, KDL) are not dependencies of this project. Everything is a few 4x4 products
per joint; FK accepts batches of configurations (``q`` of shape ``(..., n)``).

Conventions: poses are expressed in the ``base_link`` frame; quaternions are ``(w, x, y, z)``; the
Jacobian is the 6 x n geometric Jacobian ``[v; w]`` with both parts in base-frame axes and the linear
part taken at the tip origin. A mimic joint inside a chain is an ordinary chain variable (its
``<mimic>`` relation is not applied; the RX200 and IRB120 arm chains contain none).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from multiros.utils.rotations import (
    _quat_single,
    _rotation_error,
    _rpy_matrix,
    _skew,
    matrix_from_quat,
    quat_from_matrix,
)

# quat_from_matrix and matrix_from_quat live in multiros.utils.rotations; named here too, their earlier home.
__all__ = ["IKResult", "KinematicChain", "quat_from_matrix", "matrix_from_quat"]

_MOVING = ("revolute", "continuous", "prismatic")
_STALL_ITERS = 30  # IK iterations without a 1 % improvement before an attempt gives up
_DAMPING_SCALE = 0.05  # residual (m + rad) below which the IK damping is scaled down
_I1 = np.array([1, 2, 0])  # cross-product index permutations (np.cross is slow on small arrays)
_I2 = np.array([2, 0, 1])
_KNOWN = (*_MOVING, "fixed", "floating", "planar")


class IKResult(NamedTuple):
    """Inverse-kinematics outcome; unpacks as ``q, converged, error``.

    Attributes:
        q: Joint configuration, shape ``(n,)``, within the joint limits when they were enforced.
        converged: True when the position error is below ``tol`` (and the orientation error below
            ``rot_tol`` for pose targets).
        error: Position error in metres for position-only targets; for pose targets the norm of
            ``[position error (m), orientation error (rad)]``.
    """

    q: np.ndarray
    converged: bool
    error: float


@dataclass(frozen=True)
class _Joint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray  # 4x4
    axis: np.ndarray  # unit 3-vector in the joint frame
    lower: float
    upper: float
    velocity: float


def _floats(text: str | None, default: tuple[float, ...], what: str) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = [float(v) for v in text.split()]
    except ValueError as exc:
        raise ValueError(f"URDF {what}: {text!r} is not a list of numbers") from exc
    if len(values) != len(default):
        raise ValueError(f"URDF {what}: expected {len(default)} numbers, got {text!r}")
    return np.array(values, dtype=float)


def _parse_joint(elem: ET.Element) -> _Joint:
    name = elem.get("name", "")
    jtype = elem.get("type", "")
    if jtype not in _KNOWN:
        raise ValueError(f"URDF joint {name!r}: unknown type {jtype!r} (expected one of {_KNOWN})")
    parent, child = elem.find("parent"), elem.find("child")
    if parent is None or child is None:
        raise ValueError(f"URDF joint {name!r} needs <parent link=...> and <child link=...>")
    origin = elem.find("origin")
    xyz = _floats(origin.get("xyz") if origin is not None else None, (0.0, 0.0, 0.0), f"joint {name!r} xyz")
    rpy = _floats(origin.get("rpy") if origin is not None else None, (0.0, 0.0, 0.0), f"joint {name!r} rpy")
    tf = np.eye(4)
    tf[:3, :3] = _rpy_matrix(*rpy)
    tf[:3, 3] = xyz
    axis_elem = elem.find("axis")
    axis = _floats(axis_elem.get("xyz") if axis_elem is not None else None, (1.0, 0.0, 0.0), f"joint {name!r} axis")
    if jtype in _MOVING:
        norm = np.linalg.norm(axis)
        if norm < 1e-12:
            raise ValueError(f"URDF joint {name!r}: axis {axis.tolist()} has zero length")
        axis = axis / norm
    limit = elem.find("limit")
    lower, upper, velocity = -math.inf, math.inf, math.inf
    if limit is not None:
        velocity = float(limit.get("velocity", "inf"))
        if jtype in ("revolute", "prismatic"):
            lower = float(limit.get("lower", "0"))
            upper = float(limit.get("upper", "0"))
    if jtype in ("revolute", "prismatic") and limit is None:
        raise ValueError(f"URDF joint {name!r} ({jtype}) has no <limit>; the URDF spec requires one")
    return _Joint(
        name=name,
        type=jtype,
        parent=parent.get("link", ""),
        child=child.get("link", ""),
        origin=tf,
        axis=axis,
        lower=lower,
        upper=upper,
        velocity=velocity,
    )


def _load_urdf_text(source: str | os.PathLike[str], xacro_args: dict[str, str] | None) -> str:
    if isinstance(source, str) and source.lstrip().startswith("<"):
        return source
    if isinstance(source, str) and ("\n" in source or len(source) > 4096):  # text, not a path: never echo it whole
        raise ValueError(f"URDF text is not XML: it starts with {source.lstrip()[:40]!r}")
    path = Path(source)
    if not path.is_file():
        raise FileNotFoundError(f"URDF file {str(path)!r} not found (pass a path or the URDF XML text)")
    if path.name.endswith(".xacro"):
        import xacro  # imported here: only needed for xacro sources

        return xacro.process_file(str(path), mappings=dict(xacro_args or {})).toxml()
    return path.read_text()


# --------------------------------------------------------------------------- the chain
class KinematicChain:
    """Serial chain between two URDF links: FK, Jacobian and damped-least-squares IK.

    Build it with :meth:`from_urdf`. Moving joints are revolute, continuous and prismatic; fixed
    joints are folded into the neighbouring transforms. Continuous joints have infinite limits.
    """

    def __init__(self, joints: list[_Joint], base_link: str, tip_link: str,
                 tip_offset: Sequence[float] | np.ndarray | None = None) -> None:
        self.base_link = base_link
        self.tip_link = tip_link
        offset = np.zeros(3) if tip_offset is None else np.asarray(tip_offset, dtype=float).reshape(-1)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise ValueError(f"tip_offset must be 3 finite numbers (metres in the tip link's frame), "
                             f"got {tip_offset!r}")
        self.tip_offset = offset
        self._joints = list(joints)
        # Fold fixed joints: pre[i] goes before moving joint i, tip after the last.
        pre: list[np.ndarray] = []
        moving: list[_Joint] = []
        acc = np.eye(4)
        for j in joints:
            if j.type in _MOVING:
                pre.append(acc.dot(j.origin))
                moving.append(j)
                acc = np.eye(4)
            elif j.type == "fixed":
                acc = acc.dot(j.origin)
            else:
                raise ValueError(
                    f"joint {j.name!r} of type {j.type!r} between {base_link!r} and {tip_link!r} is not "
                    "supported; chains may contain revolute, continuous, prismatic and fixed joints"
                )
        n = len(moving)
        acc = acc.copy()
        acc[:3, 3] += acc[:3, :3].dot(offset)  # a point fixed in the tip link (a tool centre point)
        self._tip = acc
        self._names = tuple(j.name for j in moving)
        self._lower = np.array([j.lower for j in moving], dtype=float)
        self._upper = np.array([j.upper for j in moving], dtype=float)
        self._velocity = np.array([j.velocity for j in moving], dtype=float)
        self._prismatic = np.array([j.type == "prismatic" for j in moving], dtype=bool)
        self._rev_f = (~self._prismatic).astype(float)[:, None]
        self._pris_f = self._prismatic.astype(float)[:, None]
        pre_arr = np.array(pre).reshape(n, 4, 4)
        axes = np.array([j.axis for j in moving]).reshape(n, 3)
        # Local transform of joint i is  P0 + u_i P1 + v_i P2  with (u, v) = (sin q, 1 - cos q) for
        # revolute joints (Rodrigues folded into the origin) and (q, 0) for prismatic ones.
        self._p0 = pre_arr
        self._p1 = np.zeros((n, 4, 4))
        self._p2 = np.zeros((n, 4, 4))
        for i, j in enumerate(moving):
            rot = pre_arr[i, :3, :3]
            if j.type == "prismatic":
                self._p1[i, :3, 3] = rot.dot(j.axis)
            else:
                k = _skew(j.axis)
                self._p1[i, :3, :3] = rot.dot(k)
                self._p2[i, :3, :3] = rot.dot(k).dot(k)
        # Each joint's three matrices side by side, transposed: a batch of points (rows) goes
        # through all three in one product (see fk_position).
        self._point_maps = np.concatenate([self._p0, self._p1, self._p2], axis=1).transpose(0, 2, 1).copy()
        # Joint axis and origin in the frame of the previous joint's motion (for the Jacobian).
        self._pre_axis = np.einsum("nij,nj->ni", pre_arr[:, :3, :3], axes)
        self._pre_origin = pre_arr[:, :3, 3].copy()

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_urdf(
        cls,
        urdf: str | os.PathLike[str],
        base_link: str,
        tip_link: str,
        *,
        xacro_args: dict[str, str] | None = None,
        tip_offset: Sequence[float] | np.ndarray | None = None,
    ) -> KinematicChain:
        """Build the chain from ``base_link`` to ``tip_link``.

        Args:
            urdf: URDF XML text, or a path to a ``.urdf`` file or a ``.urdf.xacro`` file.
            base_link: Link whose frame poses are expressed in.
            tip_link: End link (for example ``rx200/ee_gripper_link`` or ``tool0``).
            xacro_args: ``$(arg ...)`` values when ``urdf`` is a xacro file.
            tip_offset: a point fixed in ``tip_link``'s frame (metres) that is the chain's tip instead
                of the link's origin: a tool centre point the description has no link for.

        Raises:
            ValueError: A link is not in the URDF, or ``tip_link`` is not a descendant of ``base_link``.
        """
        text = _load_urdf_text(urdf, xacro_args)
        try:
            root = ET.fromstring(text)
        except ET.ParseError as exc:
            raise ValueError(f"URDF is not valid XML: {exc}") from exc
        if root.tag != "robot":
            raise ValueError(f"URDF root element is <{root.tag}>, expected <robot>")
        links = {e.get("name") for e in root.findall("link")}
        joints = [_parse_joint(e) for e in root.findall("joint")]
        by_child = {j.child: j for j in joints}
        links |= {j.child for j in joints} | {j.parent for j in joints}
        for role, link in (("base_link", base_link), ("tip_link", tip_link)):
            if link not in links:
                close = sorted(name for name in links if name and link.split("/")[-1] in name)
                hint = f"; similar: {close}" if close else f"; links: {sorted(n for n in links if n)}"
                raise ValueError(f"{role} {link!r} is not a link of robot {root.get('name')!r}{hint}")
        path: list[_Joint] = []
        link = tip_link
        while link != base_link:
            joint = by_child.get(link)
            if joint is None:
                raise ValueError(
                    f"no kinematic chain from {base_link!r} to {tip_link!r}: {tip_link!r} is not a "
                    f"descendant of {base_link!r} (the path up from the tip ends at {link!r})"
                )
            path.append(joint)
            link = joint.parent
        return cls(path[::-1], base_link, tip_link, tip_offset)

    def with_tip_offset(self, tip_offset: Sequence[float] | np.ndarray | None) -> KinematicChain:
        """The same chain whose tip is ``tip_offset`` (metres, in the tip link's frame) from the tip link's
        origin (instead of this chain's offset)."""
        return type(self)(self._joints, self.base_link, self.tip_link, tip_offset)

    # ------------------------------------------------------------------ properties
    @property
    def n_joints(self) -> int:
        """Number of moving joints (the length of ``q``)."""
        return len(self._names)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Moving joints from base to tip."""
        return self._names

    @property
    def lower(self) -> np.ndarray:
        """Lower position limits (rad or m); ``-inf`` for continuous joints."""
        return self._lower.copy()

    @property
    def upper(self) -> np.ndarray:
        """Upper position limits (rad or m); ``+inf`` for continuous joints."""
        return self._upper.copy()

    @property
    def velocity_limits(self) -> np.ndarray:
        """Velocity limits (rad/s or m/s); ``inf`` where the URDF gives none."""
        return self._velocity.copy()

    # ------------------------------------------------------------------ forward kinematics
    def _check_q(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape[-1:] != (self.n_joints,):
            raise ValueError(
                f"q has shape {q.shape}; expected (..., {self.n_joints}) for joints {list(self._names)}"
            )
        return q

    def _weights(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each joint's ``(u, v)``: its transform is ``P0 + u P1 + v P2``, shapes ``(..., n)``."""
        return np.where(self._prismatic, q, np.sin(q)), np.where(self._prismatic, 0.0, 1.0 - np.cos(q))

    def _local(self, q: np.ndarray) -> np.ndarray:
        """Per-joint transforms, shape ``(..., n, 4, 4)``."""
        u, v = self._weights(q)
        return self._p0 + u[..., None, None] * self._p1 + v[..., None, None] * self._p2

    def _chain(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One configuration: transforms before each joint's origin ``(n, 4, 4)`` and the tip ``(4, 4)``."""
        local = self._local(q)
        before = np.empty_like(local)
        acc = np.eye(4)
        for i in range(self.n_joints):
            before[i] = acc
            acc = acc.dot(local[i])
        return before, acc.dot(self._tip)

    def fk_matrix(self, q: np.ndarray) -> np.ndarray:
        """Homogeneous transform(s) of the tip in the base frame.

        Args:
            q: Joint positions, shape ``(n,)`` or a batch ``(..., n)``.

        Returns:
            Array of shape ``(..., 4, 4)``.
        """
        q = self._check_q(q)
        local = self._local(q)
        if q.ndim == 1:
            acc = np.eye(4)
            for i in range(self.n_joints):
                acc = acc.dot(local[i])
            return acc.dot(self._tip)
        acc = np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4))
        for i in range(self.n_joints):
            acc = np.matmul(acc, local[..., i, :, :])
        return np.matmul(acc, self._tip)

    def fk(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip position ``(..., 3)`` and orientation quaternion ``(..., 4)`` (w, x, y, z) in the base frame."""
        tf = self.fk_matrix(q)
        if tf.ndim == 2:
            return tf[:3, 3].copy(), _quat_single(tf)
        return tf[..., :3, 3].copy(), quat_from_matrix(tf[..., :3, :3])

    def fk_position(self, q: np.ndarray) -> np.ndarray:
        """Tip position(s) only, shape ``(..., 3)``.

        A batch carries the tip point back to the base, one joint at a time (``P0 x + u P1 x + v P2 x``,
        see ``_weights``), instead of multiplying 4x4 transforms: a quarter of the work, and a third of
        :meth:`fk_matrix`'s time for a goal sampler's 512 configurations. The results equal
        ``fk_matrix``'s to rounding (about 1e-16 m), not bit for bit.
        """
        q = self._check_q(q)
        if q.ndim == 1:
            return self.fk_matrix(q)[:3, 3].copy()
        u, v = self._weights(q)
        x = np.broadcast_to(self._tip[:, 3], (*q.shape[:-1], 4))
        for i in range(self.n_joints - 1, -1, -1):
            y = x @ self._point_maps[i]  # (..., 12): P0 x, P1 x and P2 x of joint i
            x = y[..., 0:4] + u[..., i, None] * y[..., 4:8] + v[..., i, None] * y[..., 8:12]
        return x[..., :3].copy()

    # ------------------------------------------------------------------ differential kinematics
    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian ``(6, n)``: rows 0-2 tip linear velocity, rows 3-5 angular velocity.

        Both parts are in base-frame axes; the linear part is at the tip origin.
        """
        q = self._check_q(q)
        if q.ndim != 1:
            raise ValueError(f"jacobian takes one configuration of shape ({self.n_joints},), got {q.shape}")
        before, tip = self._chain(q)
        return self._jacobian_from(before, tip)

    def _jacobian_from(self, before: np.ndarray, tip: np.ndarray) -> np.ndarray:
        rot = before[:, :3, :3]
        axes = np.matmul(rot, self._pre_axis[:, :, None])[:, :, 0]
        origins = np.matmul(rot, self._pre_origin[:, :, None])[:, :, 0] + before[:, :3, 3]
        lever = tip[:3, 3] - origins
        cross = axes[:, _I1] * lever[:, _I2] - axes[:, _I2] * lever[:, _I1]
        linear = self._rev_f * cross + self._pris_f * axes
        return np.concatenate([linear, self._rev_f * axes], axis=1).T

    # ------------------------------------------------------------------ inverse kinematics
    def clip(self, q: np.ndarray) -> np.ndarray:
        """``q`` clipped to the joint limits."""
        return np.clip(q, self._lower, self._upper)

    def ik(
        self,
        target_pos: np.ndarray,
        target_quat: np.ndarray | None = None,
        q0: np.ndarray | None = None,
        *,
        damping: float = 0.05,
        max_iters: int = 200,
        tol: float = 1e-4,
        rot_tol: float = 1e-3,
        joint_limits: bool = True,
        max_step: float = 0.3,
        restarts: int = 8,
        rng: np.random.Generator | None = None,
    ) -> IKResult:
        """Damped-least-squares IK: ``dq = J^T (J J^T + damping^2 I)^-1 e``, clamped to the limits.

        Position-only when ``target_quat`` is None (uses the 3 linear Jacobian rows), else full pose.

        Args:
            target_pos: Target tip position (3,) in the base frame.
            target_quat: Target orientation (w, x, y, z), or None for position only.
            q0: Start configuration (default: the middle of the finite limits, 0 for continuous joints).
            damping: The DLS damping factor lambda; larger is steadier near singularities, slower.
            max_iters: Iterations per attempt.
            tol: Position tolerance (m) for ``converged``.
            rot_tol: Orientation tolerance (rad) for ``converged`` (pose targets only).
            joint_limits: Clamp every iterate to the joint limits.
            max_step: Largest joint change per iteration (rad or m, infinity norm).
            restarts: Extra attempts from random configurations if the first does not converge.
            rng: Generator for the restart configurations (default: a fixed seed, so IK is repeatable).

        Returns:
            :class:`IKResult` ``(q, converged, error)``: the best attempt.
        """
        target_pos = np.asarray(target_pos, dtype=float).reshape(-1)
        if target_pos.shape != (3,) or not np.all(np.isfinite(target_pos)):
            raise ValueError(f"target_pos must be 3 finite numbers, got {target_pos!r}")
        rot_target = None if target_quat is None else matrix_from_quat(np.asarray(target_quat, dtype=float))
        if q0 is None:
            q = self._default_q()
        else:
            q = self._check_q(np.array(q0, dtype=float).reshape(-1)).copy()
        best = self._solve(q, target_pos, rot_target, damping, max_iters, tol, rot_tol, joint_limits, max_step)
        if best.converged or restarts <= 0:
            return best
        gen = rng if rng is not None else np.random.default_rng(0)
        for _ in range(restarts):
            start = self.sample_configurations(gen, 1)[0]
            result = self._solve(
                start, target_pos, rot_target, damping, max_iters, tol, rot_tol, joint_limits, max_step
            )
            if result.converged:
                return result
            if result.error < best.error:
                best = result
        return best

    def _default_q(self) -> np.ndarray:
        finite = np.isfinite(self._lower) & np.isfinite(self._upper)
        q = np.zeros(self.n_joints)
        q[finite] = 0.5 * (self._lower[finite] + self._upper[finite])
        return q

    def _solve(
        self,
        q: np.ndarray,
        target_pos: np.ndarray,
        rot_target: np.ndarray | None,
        damping: float,
        max_iters: int,
        tol: float,
        rot_tol: float,
        joint_limits: bool,
        max_step: float,
    ) -> IKResult:
        if joint_limits:
            q = self.clip(q)
        rows = 3 if rot_target is None else 6
        eye = np.eye(rows)
        pos_err = rot_err = math.inf
        best_err, best_iter = math.inf, 0
        for it in range(max_iters + 1):
            before, tip = self._chain(q)
            e_pos = target_pos - tip[:3, 3]
            pos_err = float(np.linalg.norm(e_pos))
            if rot_target is None:
                err = e_pos
                rot_err = 0.0
            else:
                e_rot = _rotation_error(rot_target, tip[:3, :3])
                rot_err = float(np.linalg.norm(e_rot))
                err = np.concatenate([e_pos, e_rot])
            if pos_err < tol and rot_err < rot_tol:
                break
            total = pos_err + rot_err
            if total < 0.99 * best_err:
                best_err, best_iter = total, it
            elif it - best_iter > _STALL_ITERS:
                break  # stuck (joint limit or local minimum): leave it to a restart
            jac = self._jacobian_from(before, tip)[:rows]
            # Damping shrinks near the target (errors below _DAMPING_SCALE) so the last steps are
            # Gauss-Newton steps and converge fast; far away the full damping keeps steps steady.
            lam = damping * min(1.0, total / _DAMPING_SCALE)
            dq = jac.T.dot(np.linalg.solve(jac.dot(jac.T) + (lam * lam) * eye, err))
            largest = float(np.max(np.abs(dq))) if dq.size else 0.0
            if largest > max_step:
                dq *= max_step / largest
            q = q + dq
            if joint_limits:
                q = self.clip(q)
        converged = pos_err < tol and rot_err < rot_tol
        error = pos_err if rot_target is None else math.hypot(pos_err, rot_err)
        return IKResult(q, bool(converged), error)

    # ------------------------------------------------------------------ sampling
    def sample_configurations(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` configurations uniform within the limits (continuous joints in [-pi, pi]), ``(n, dof)``."""
        low = np.where(np.isfinite(self._lower), self._lower, -math.pi)
        high = np.where(np.isfinite(self._upper), self._upper, math.pi)
        return rng.uniform(low, high, size=(n, self.n_joints))

    def sample_reachable(
        self, rng: np.random.Generator, n: int, *, return_q: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Tip positions ``(n, 3)`` of random configurations within the limits: reachable goals.

        Args:
            rng: The caller's generator (for example the env's ``np_random``).
            n: Number of samples.
            return_q: Also return the configurations, as ``(q, positions)``.
        """
        qs = self.sample_configurations(rng, n)
        pos = self.fk_position(qs)
        return (qs, pos) if return_q else pos

    def __repr__(self) -> str:
        offset = f", tip_offset={self.tip_offset.tolist()}" if np.any(self.tip_offset) else ""
        return f"KinematicChain({self.base_link!r} -> {self.tip_link!r}, joints={list(self._names)}{offset})"
