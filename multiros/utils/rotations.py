"""Rotations as the kinematics and the envs write them: URDF roll-pitch-yaw, quaternions ``(w, x, y, z)``
(batched), and the axis-angle error between two rotations.

Hand-written for the same reason as :mod:`multiros.utils.kinematics` (a few numpy lines on small arrays;
scipy's Rotation is not a dependency and is slower on single rotations).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["matrix_from_quat", "quat_from_matrix"]


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def quat_from_matrix(rot: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` to unit quaternions ``(..., 4)`` (w, x, y, z), ``w >= 0``."""
    rot = np.asarray(rot, dtype=float)
    m00, m11, m22 = rot[..., 0, 0], rot[..., 1, 1], rot[..., 2, 2]
    # |w|,|x|,|y|,|z| from the diagonal, signs from the off-diagonal terms: branch-free and batchable.
    w = 0.5 * np.sqrt(np.maximum(0.0, 1.0 + m00 + m11 + m22))
    x = 0.5 * np.sqrt(np.maximum(0.0, 1.0 + m00 - m11 - m22))
    y = 0.5 * np.sqrt(np.maximum(0.0, 1.0 - m00 + m11 - m22))
    z = 0.5 * np.sqrt(np.maximum(0.0, 1.0 - m00 - m11 + m22))
    x = np.copysign(x, rot[..., 2, 1] - rot[..., 1, 2])
    y = np.copysign(y, rot[..., 0, 2] - rot[..., 2, 0])
    z = np.copysign(z, rot[..., 1, 0] - rot[..., 0, 1])
    quat = np.stack([w, x, y, z], axis=-1)
    quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    # Near a half turn w -> 0 and the antisymmetric terms that give the signs vanish with it, so
    # x, y, z may come out with unrelated signs: those matrices take the Shepperd conversion.
    near_half_turn = np.asarray(w < 0.25)
    if near_half_turn.any():
        flat, mats = quat.reshape(-1, 4), rot.reshape(-1, 3, 3)
        for i in np.flatnonzero(near_half_turn.reshape(-1)):
            flat[i] = _quat_single(mats[i])
        quat = flat.reshape(quat.shape)
    return quat


def _quat_single(tf: np.ndarray) -> np.ndarray:
    """Scalar Shepperd conversion for one matrix: much faster than the batched version."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = tf[:3, :3].tolist()
    trace = m00 + m11 + m22
    if trace > 0.0:
        s = 2.0 * math.sqrt(1.0 + trace)
        quat = (0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s)
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        quat = ((m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s)
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        quat = ((m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        quat = ((m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s)
    out = np.array(quat)
    return out if out[0] >= 0.0 else -out


def matrix_from_quat(quat: np.ndarray) -> np.ndarray:
    """Quaternion(s) ``(..., 4)`` (w, x, y, z), not necessarily unit, to rotation matrices."""
    q = np.asarray(quat, dtype=float)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError(f"quaternion {quat!r} has zero norm; use (1, 0, 0, 0) for the identity")
    w, x, y, z = np.moveaxis(q / norm, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=-2,
    )


def _rotation_error(rot_target: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Axis-angle vector (base frame) of ``rot_target @ rot.T``: the rotation still to be applied."""
    quat = _quat_single(rot_target.dot(rot.T))
    w, v = quat[0], quat[1:]
    s = np.linalg.norm(v)
    if s < 1e-12:
        return np.zeros(3)
    return v * (2.0 * math.atan2(s, w) / s)


# --------------------------------------------------------------------------- URDF parsing
