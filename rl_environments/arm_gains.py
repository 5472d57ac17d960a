"""Servo gains for an arm's joints in simulation, from its description alone (``uniros arm add``).

A vendor's description has masses, inertias and effort limits but no gains for the simulation node's
position servos (:mod:`multiros.sim.controllers`: ``force = p (target - q) - d qdot``, the damping
integrated implicitly, the force clamped to the URDF effort). These are derived so that the arm holds
itself with gravity compensation off (the worst gravity torque over random poses sags a joint by at
most 8 mrad), every joint has at least a 4 Hz bandwidth at its largest joint-space inertia, an
explicit 4 ms step stays stable at its smallest, and the damping is critical; then checked by holding
poses in MuJoCo the way the node's servos would (no self-collision, as the node spawns robots).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ServoGains", "servo_gains", "settle_error"]

TIMESTEP = 0.004  # s: the tasks' physics step
SAG = 0.008  # rad: the most a joint may sag under gravity with gravity compensation off
BANDWIDTH = 2 * math.pi * 4.0  # rad/s: the servos' least natural frequency


@dataclass(frozen=True)
class ServoGains:
    """Gains per joint (``joints`` order) and what they were derived from."""

    p: np.ndarray
    d: np.ndarray
    gravity: np.ndarray  # N m or N: the worst gravity load over the sampled poses
    weak: tuple[str, ...]  # joints whose effort limit is below that load


def servo_gains(model: Any, joints: Sequence[str], efforts: Sequence[float], lower: np.ndarray,
                upper: np.ndarray, rng: np.random.Generator, samples: int = 200) -> ServoGains:
    """Gains for ``joints`` of a compiled ``mujoco.MjModel`` from ``samples`` random poses within the limits."""
    import mujoco

    data = mujoco.MjData(model)
    dofs = [int(model.joint(j).dofadr[0]) for j in joints]
    qadr = [int(model.joint(j).qposadr[0]) for j in joints]
    n = len(joints)
    gravity, inertia, least = np.zeros(n), np.zeros(n), np.full(n, np.inf)
    full = np.zeros((model.nv, model.nv))
    for q in rng.uniform(lower, upper, size=(samples, n)):
        data.qpos[qadr] = q
        data.qvel[:] = 0.0
        mujoco.mj_forward(model, data)
        gravity = np.maximum(gravity, np.abs(data.qfrc_bias[dofs]))
        mujoco.mj_fullM(model, data, full)
        inertia = np.maximum(inertia, full[dofs, dofs])
        least = np.minimum(least, full[dofs, dofs])
    kp = np.maximum(gravity / SAG, inertia * BANDWIDTH ** 2)
    kp = np.minimum(kp, 0.5 * np.maximum(least, 1e-4) / TIMESTEP ** 2)  # explicit stiffness stays stable
    kd = 2.0 * np.sqrt(kp * inertia)
    weak = tuple(j for j, e, g in zip(joints, efforts, gravity) if 0 < e < g)
    return ServoGains(kp, kd, gravity, weak)


def settle_error(model: Any, joints: Sequence[str], gains: ServoGains, efforts: Sequence[float],
                 poses: Sequence[np.ndarray], seconds: float = 1.0) -> float:
    """The largest error (rad or m) of servos with ``gains`` holding each pose for ``seconds``, gravity
    compensation off; infinite when the simulation diverges. Changes ``model`` (a copy of yours)."""
    import mujoco

    model.geom_contype[:], model.geom_conaffinity[:] = 2, 1  # no self-collision, as the node's robots
    model.opt.timestep = TIMESTEP
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    data = mujoco.MjData(model)
    qadr = [int(model.joint(j).qposadr[0]) for j in joints]
    dofs = [int(model.joint(j).dofadr[0]) for j in joints]
    model.dof_damping[dofs] = gains.d  # the servos' damping, integrated implicitly as the node's are
    effort = np.asarray(efforts, dtype=float)
    worst = 0.0
    for pose in poses:
        mujoco.mj_resetData(model, data)
        data.qpos[qadr] = pose
        for _ in range(int(seconds / TIMESTEP)):
            force = gains.p * (pose - data.qpos[qadr])
            data.qfrc_applied[dofs] = np.where(effort > 0, np.clip(force, -effort, effort), force)
            mujoco.mj_step(model, data)
            if not np.all(np.isfinite(data.qpos)):
                return math.inf
        worst = max(worst, float(np.max(np.abs(data.qpos[qadr] - pose))))
    return worst
