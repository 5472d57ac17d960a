"""Safety rules applied to every joint command before it leaves the process.

:class:`SafetyRules` turns a requested joint target into a safe one, or refuses it:

1. the target must be finite and of the right length (otherwise :class:`UnsafeCommandError`, nothing is sent);
2. it is clamped to the joint limits (the intersection of the task's and the robot description's);
3. each joint moves at most ``max_joint_delta`` per command from the measured position **and** from
   the env's own previous command (which no other process can forge): a measured state that lies
   about where the robot is cannot widen what a command may ask. When the two windows do not
   overlap (the measurement is more than twice the cap away from the last command: a robot that
   does not track, or a state that is not the robot's) the command is refused (``state_mismatch``);
4. the end effector, by forward kinematics, stays inside the workspace box and above the floor: a
   target that would leave it is projected back along the joint-space segment from the measured
   position (``workspace_mode="project"``) or refused (``"refuse"``: the robot holds its last command).

What the rules do not bound: the cap is measured from a state up to ``joint_state_timeout`` old
(the env refuses older ones), so a robot moving fast can be a little further than measured; the
workspace check follows the joint-space segment at ``path_samples`` points, not the controller's
actual path. :meth:`SafetyRules.plausible` says whether a measured state can be the robot's at all
(within its limits and, given the time between two states, its velocity limits): the robot link
drops states that are not (:class:`~multiros.envs.real.robot_link.JointStateCache`).

The rules are pure numpy (no ROS), so they are unit-tested directly; :class:`SafetyDecision` says what
each rule did, and the env copies that into ``info``.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
import numpy.typing as npt

from multiros.envs.real.errors import UnsafeCommandError
from multiros.utils.kinematics import KinematicChain

WorkspaceMode = Literal["project", "refuse"]

# Events a decision may report (also the keys of ``info["safety"]``).
JOINT_LIMITS = "joint_limits"
JOINT_DELTA = "joint_delta"
WORKSPACE = "workspace"
FLOOR = "floor"
STATE_MISMATCH = "state_mismatch"
#: How far (rad or m) a measured position may lie outside the joint limits and still be the robot's.
STATE_MARGIN = 0.05


@dataclass(frozen=True)
class SafetyDecision:
    """What the rules made of one requested target.

    Attributes:
        target: the joint target to send, or ``None`` when the command is refused (send nothing).
        events: the rules that changed or refused the request (``joint_limits``, ``joint_delta``,
            ``workspace``, ``floor``), in the order they acted.
        refused: True when nothing may be sent.
        reason: a sentence for logs and ``info`` when a rule acted.
        ee_position: the target's end-effector position, when the rules computed it.
        measured: the joint positions the rules were applied against (read just before deciding).
    """

    target: np.ndarray | None
    events: tuple[str, ...] = ()
    refused: bool = False
    reason: str = ""
    ee_position: np.ndarray | None = field(default=None, repr=False)
    measured: np.ndarray | None = field(default=None, repr=False)

    def as_info(self) -> dict[str, object]:
        """The decision as ``info["safety"]``: one flag per rule, ``refused`` and ``reason``."""
        info: dict[str, object] = {name: name in self.events
                                   for name in (JOINT_LIMITS, JOINT_DELTA, WORKSPACE, FLOOR, STATE_MISMATCH)}
        info["refused"] = self.refused
        info["reason"] = self.reason
        return info


def description_joint_limits(description: str | os.PathLike[str], joints: Sequence[str],
                             xacro_args: dict[str, str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits of ``joints`` in a URDF (text, ``.urdf`` or ``.urdf.xacro`` path);
    continuous joints get infinite limits.

    Raises:
        ValueError: a joint is missing from the description.
    """
    from multiros.utils.kinematics import _load_urdf_text  # one URDF loader for FK and limits

    root = ET.fromstring(_load_urdf_text(description, xacro_args))
    found = {e.get("name"): e for e in root.findall("joint")}
    lower, upper = [], []
    for name in joints:
        elem = found.get(name)
        if elem is None:
            known = sorted(k for k in found if k)
            raise ValueError(f"joint {name!r} is not in the robot description (joints: {known})")
        limit = elem.find("limit")
        if elem.get("type") == "continuous" or limit is None:
            lower.append(-np.inf)
            upper.append(np.inf)
        else:
            lower.append(float(limit.get("lower", "-inf")))
            upper.append(float(limit.get("upper", "inf")))
    return np.array(lower), np.array(upper)


def _vector(value: npt.ArrayLike, n: int, what: str) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy() if np.ndim(value) == 0 else (
        np.asarray(value, dtype=np.float64))
    if arr.shape != (n,):
        raise ValueError(f"{what} must be one number or {n} numbers, got {np.asarray(value).tolist()}")
    return arr


class SafetyRules:
    """The safety rules of one arm (see the module docstring).

    Args:
        joint_names: the commanded joints, in command order.
        lower, upper: joint limits; combined with ``description_lower``/``description_upper`` (the
            URDF's), the tighter bound wins. Infinite values are allowed (continuous joints).
        description_lower, description_upper: the robot description's limits (optional).
        max_joint_delta: largest change per command from the measured position and from the previous
            command, per joint or one number (``None``: no cap).
        max_velocity: the joints' velocity limits in rad/s (the description's; ``None``: unknown), for
            :meth:`plausible` and the duration of long moves.
        chain: the arm's kinematic chain (``joint_names`` must be its joints) for the workspace and
            floor checks; ``None`` disables them.
        base_position: the chain base's position in the frame of the workspace box.
        workspace_min, workspace_max: the box the end effector must stay in (``None``: no box).
        floor_z: the lowest allowed end-effector height (``None``: no floor check).
        workspace_mode: ``"project"`` (move as far as allowed along the requested motion) or
            ``"refuse"`` (send nothing).
        path_samples: points checked along the joint-space segment from the measured position.
    """

    def __init__(
        self,
        joint_names: Sequence[str],
        *,
        lower: npt.ArrayLike,
        upper: npt.ArrayLike,
        description_lower: npt.ArrayLike | None = None,
        description_upper: npt.ArrayLike | None = None,
        max_joint_delta: float | Sequence[float] | np.ndarray | None = None,
        max_velocity: float | Sequence[float] | np.ndarray | None = None,
        chain: KinematicChain | None = None,
        base_position: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0),
        workspace_min: Sequence[float] | np.ndarray | None = None,
        workspace_max: Sequence[float] | np.ndarray | None = None,
        floor_z: float | None = None,
        workspace_mode: WorkspaceMode = "project",
        path_samples: int = 5,
    ) -> None:
        self.joint_names = tuple(joint_names)
        n = len(self.joint_names)
        if n == 0:
            raise ValueError("SafetyRules needs at least one joint name")
        lo, hi = _vector(lower, n, "lower"), _vector(upper, n, "upper")
        if description_lower is not None:
            lo = np.maximum(lo, _vector(description_lower, n, "description_lower"))
        if description_upper is not None:
            hi = np.minimum(hi, _vector(description_upper, n, "description_upper"))
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo > hi):
            raise ValueError(f"joint limits of {list(self.joint_names)} are empty or NaN: lower {lo.tolist()}, "
                             f"upper {hi.tolist()}")
        self.lower, self.upper = lo, hi
        # Where the joints can physically be: the description's range when given (a task's tighter
        # limits bound commands, not the arm), else the limits. The first move's duration uses it.
        self.travel_lower = lo if description_lower is None else np.minimum(
            lo, _vector(description_lower, n, "description_lower"))
        self.travel_upper = hi if description_upper is None else np.maximum(
            hi, _vector(description_upper, n, "description_upper"))
        self.max_joint_delta = None if max_joint_delta is None else _vector(max_joint_delta, n, "max_joint_delta")
        if self.max_joint_delta is not None and not np.all(self.max_joint_delta > 0):
            raise ValueError(f"max_joint_delta must be > 0, got {self.max_joint_delta.tolist()}")
        self.max_velocity = None if max_velocity is None else _vector(max_velocity, n, "max_velocity")
        if self.max_velocity is not None and not np.all(self.max_velocity > 0):
            raise ValueError(f"max_velocity must be > 0 rad/s, got {self.max_velocity.tolist()}")
        if chain is not None and tuple(chain.joint_names) != self.joint_names:
            raise ValueError(f"the kinematic chain's joints {list(chain.joint_names)} are not the commanded joints "
                             f"{list(self.joint_names)}")
        self.chain = chain
        self.base_position = np.asarray(base_position, dtype=np.float64).reshape(3)
        self.workspace_min = None if workspace_min is None else np.asarray(workspace_min, np.float64).reshape(3)
        self.workspace_max = None if workspace_max is None else np.asarray(workspace_max, np.float64).reshape(3)
        if (self.workspace_min is None) != (self.workspace_max is None):
            raise ValueError("give both workspace_min and workspace_max, or neither")
        if (self.workspace_min is not None and self.workspace_max is not None
                and np.any(self.workspace_min > self.workspace_max)):
            raise ValueError(f"workspace_min {self.workspace_min.tolist()} exceeds workspace_max "
                             f"{self.workspace_max.tolist()}")
        self.floor_z = None if floor_z is None else float(floor_z)
        if workspace_mode not in ("project", "refuse"):
            raise ValueError(f"workspace_mode {workspace_mode!r} is not 'project' or 'refuse'")
        if chain is None and (self.workspace_min is not None or self.floor_z is not None):
            raise ValueError("the workspace box and floor checks need the arm's kinematic chain (chain=...)")
        self.workspace_mode: WorkspaceMode = workspace_mode
        self.path_samples = max(1, int(path_samples))

    def with_joint_limits(self, lower: npt.ArrayLike, upper: npt.ArrayLike) -> SafetyRules:
        """These rules with a task's joint range as well: the tighter of it and the present limits wins
        (the present ones act as the description's); every other rule is the same."""
        return SafetyRules(
            self.joint_names, lower=lower, upper=upper, description_lower=self.lower, description_upper=self.upper,
            max_joint_delta=self.max_joint_delta, max_velocity=self.max_velocity, chain=self.chain,
            base_position=self.base_position, workspace_min=self.workspace_min, workspace_max=self.workspace_max,
            floor_z=self.floor_z, workspace_mode=self.workspace_mode, path_samples=self.path_samples,
        )

    # -- the checks ---------------------------------------------------------------------------
    def ee_position(self, q: np.ndarray) -> np.ndarray:
        """End-effector position(s) in the workspace frame for joint configuration(s) ``q``."""
        if self.chain is None:
            raise ValueError("no kinematic chain configured")
        return self.chain.fk_position(q) + self.base_position

    def violation(self, q: np.ndarray) -> np.ndarray:
        """How far (metres, summed over axes) the end effector at ``q`` is outside the allowed region."""
        if self.chain is None or (self.workspace_min is None and self.floor_z is None):
            return np.zeros(np.shape(q)[:-1])
        p = self.ee_position(q)
        out = np.zeros(p.shape[:-1])
        if self.workspace_min is not None:
            out = out + np.sum(np.maximum(self.workspace_min - p, 0.0) + np.maximum(p - self.workspace_max, 0.0),
                               axis=-1)
        if self.floor_z is not None:
            out = out + np.maximum(self.floor_z - p[..., 2], 0.0)
        return out

    def _region_events(self, q: np.ndarray) -> tuple[str, ...]:
        p = self.ee_position(q)
        events = []
        if self.workspace_min is not None and (np.any(p < self.workspace_min) or np.any(p > self.workspace_max)):
            events.append(WORKSPACE)
        if self.floor_z is not None and p[2] < self.floor_z:
            events.append(FLOOR)
        return tuple(events)

    def check(self, target: Sequence[float] | np.ndarray, current: Sequence[float] | np.ndarray,
              previous: Sequence[float] | np.ndarray | None = None) -> SafetyDecision:
        """Apply every rule to ``target`` given the measured joint positions ``current`` and the
        env's own previous command ``previous`` (``None`` before the first).

        Raises:
            UnsafeCommandError: ``target`` or ``current`` has the wrong length or a NaN/infinite value.
        """
        n = len(self.joint_names)
        req = np.asarray(target, dtype=np.float64)
        cur = np.asarray(current, dtype=np.float64)
        if req.shape != (n,):
            raise UnsafeCommandError(f"joint target has shape {req.shape}, expected ({n},) for "
                                     f"{list(self.joint_names)}; nothing was sent")
        if not np.all(np.isfinite(req)):
            raise UnsafeCommandError(f"joint target {req.tolist()} contains NaN or infinite values; nothing was sent")
        if cur.shape != (n,) or not np.all(np.isfinite(cur)):
            raise UnsafeCommandError(f"measured joint positions {cur.tolist()} are unusable for "
                                     f"{list(self.joint_names)}; nothing was sent")
        prev = None if previous is None else np.asarray(previous, dtype=np.float64)
        if prev is not None and (prev.shape != (n,) or not np.all(np.isfinite(prev))):
            raise UnsafeCommandError(f"previous command {prev.tolist()} is unusable for {list(self.joint_names)}")
        return replace(self._decide(req, cur, prev), measured=cur.copy())

    def plausible(self, positions: npt.ArrayLike, previous: npt.ArrayLike | None = None,
                  seconds: float | npt.ArrayLike | None = None, *, index: Sequence[int] | None = None) -> str | None:
        """Why measured joint positions cannot be the robot's (outside the joint limits by more than
        ``STATE_MARGIN``; or, ``seconds`` after ``previous``, further than the velocity limits allow),
        or ``None`` when they can be.

        ``index``: ``positions`` are those of the joints ``joint_names[i] for i in index`` (part of
        the arm); ``seconds`` may give one age per joint; a NaN in ``previous`` skips that joint's
        velocity check (no recent value to bound it)."""
        sel = np.arange(len(self.joint_names)) if index is None else np.asarray(index, dtype=np.intp)
        q = np.asarray(positions, dtype=np.float64).reshape(-1)
        if q.shape != sel.shape:
            return f"{q.size} positions for {sel.size} joints"
        names = [self.joint_names[i] for i in sel]
        lo, hi = self.lower[sel], self.upper[sel]
        out = (q < lo - STATE_MARGIN) | (q > hi + STATE_MARGIN)
        if np.any(out):
            j = int(np.flatnonzero(out)[0])
            return f"{names[j]} at {q[j]:.4g} is outside its limits [{lo[j]:.4g}, {hi[j]:.4g}]"
        if previous is not None and seconds is not None and self.max_velocity is not None:
            prev = np.asarray(previous, dtype=np.float64).reshape(-1)
            secs = np.broadcast_to(np.maximum(np.asarray(seconds, dtype=np.float64), 0.0), q.shape)
            vmax = self.max_velocity[sel]
            reach = vmax * secs * 1.5 + STATE_MARGIN
            jump = np.abs(q - prev) > reach  # False where prev is NaN
            if np.any(jump):
                j = int(np.flatnonzero(jump)[0])
                return (f"{names[j]} jumped {abs(q[j] - prev[j]):.4g} rad in {secs[j]:.4g} s (its "
                        f"velocity limit is {vmax[j]:.4g} rad/s)")
        return None

    def worst_case_distance(self, target: npt.ArrayLike) -> np.ndarray:
        """Per joint, the furthest ``target`` can be from anywhere the joint can be (its travel
        range, ``STATE_MARGIN`` beyond): how far a move to ``target`` may have to go whatever a
        measured state says. Infinite for a joint without finite limits (a continuous joint)."""
        t = np.asarray(target, dtype=np.float64)
        lo, hi = self.travel_lower - STATE_MARGIN, self.travel_upper + STATE_MARGIN
        return np.maximum(np.abs(t - lo), np.abs(hi - t))

    def _decide(self, req: np.ndarray, cur: np.ndarray, prev: np.ndarray | None = None) -> SafetyDecision:
        events: list[str] = []
        reasons: list[str] = []
        safe = np.minimum(np.maximum(req, self.lower), self.upper)
        if np.any(safe != req):
            events.append(JOINT_LIMITS)
            bad = [self.joint_names[i] for i in np.flatnonzero(safe != req)]
            reasons.append(f"clamped to the joint limits: {bad}")
        start = cur  # where the motion of this command starts, as far as the rules know
        if self.max_joint_delta is not None:
            d = self.max_joint_delta
            low, high = cur - d, cur + d
            if prev is not None:  # the env's own last command: no other process can forge it
                low, high = np.maximum(low, prev - d), np.minimum(high, prev + d)
                if np.any(low > high):
                    j = int(np.flatnonzero(low > high)[0])
                    return SafetyDecision(None, (STATE_MISMATCH,), True, (
                        f"refused: {self.joint_names[j]} is measured at {cur[j]:.4g}, {abs(cur[j] - prev[j]):.4g} rad "
                        f"from the last command {prev[j]:.4g} (more than twice the per-command cap {d[j]:.4g}): the "
                        "robot does not track its commands, or the state is not the robot's"))
                start = np.minimum(np.maximum(cur, low), high)
            capped = np.minimum(np.maximum(safe, low), high)
            if np.any(capped != safe):
                events.append(JOINT_DELTA)
                reasons.append(f"per-command change capped at {d.tolist()} rad")
            # A measured position beyond a limit must not drag the target past it.
            safe = np.minimum(np.maximum(capped, self.lower), self.upper)
            start = np.minimum(np.maximum(start, self.lower), self.upper)
        if self.chain is None or (self.workspace_min is None and self.floor_z is None):
            return SafetyDecision(safe, tuple(events), False, "; ".join(reasons))
        return self._check_region(safe, start, cur, events, reasons)

    def _check_region(self, safe: np.ndarray, start: np.ndarray, cur: np.ndarray, events: list[str],
                      reasons: list[str]) -> SafetyDecision:
        # Allowed: configurations no further outside than the measured one (a robot that starts
        # outside may move back in, never further out). The motion is checked from ``start`` (the
        # measured position, brought inside the per-command windows), so a projected target stays
        # inside them too.
        allowed = float(self.violation(cur)) + 1e-9
        ts = np.linspace(0.0, 1.0, self.path_samples + 1)[1:]
        path = start + ts[:, None] * (safe - start)
        viol = self.violation(path)
        bad = np.flatnonzero(viol > allowed)
        if bad.size == 0:
            return SafetyDecision(safe, tuple(events), False, "; ".join(reasons), self.ee_position(safe))
        region = self._region_events(path[bad[0]])
        events.extend(region or (WORKSPACE,))
        where = " and ".join(region) if region else "workspace"
        if self.workspace_mode == "refuse":
            reasons.append(f"refused: the end effector would leave the {where} limits")
            return SafetyDecision(None, tuple(events), True, "; ".join(reasons))
        # Project: bisect for the largest fraction of the motion that stays allowed.
        lo = 0.0 if bad[0] == 0 else float(ts[bad[0] - 1])
        hi = float(ts[bad[0]])
        for _ in range(20):
            mid = 0.5 * (lo + hi)
            if float(self.violation(start + mid * (safe - start))) <= allowed:
                lo = mid
            else:
                hi = mid
        if lo <= 1e-6:
            reasons.append(f"refused: the end effector is at the {where} limit in the requested direction")
            return SafetyDecision(None, tuple(events), True, "; ".join(reasons))
        projected = start + lo * (safe - start)
        reasons.append(f"projected to {lo:.0%} of the motion to stay inside the {where} limits")
        return SafetyDecision(projected, tuple(events), False, "; ".join(reasons), self.ee_position(projected))

    def check_move(self, target: Sequence[float] | np.ndarray, current: Sequence[float] | np.ndarray,
                   samples: int = 20) -> SafetyDecision:
        """Rules for a long move (an episode's initial pose): joint limits clamp; the workspace and floor
        are checked along the whole joint-space path and a violation refuses the move (no projection);
        the per-command cap does not apply (the move is slowed down instead)."""
        n = len(self.joint_names)
        req = np.asarray(target, dtype=np.float64)
        cur = np.asarray(current, dtype=np.float64)
        if req.shape != (n,) or not np.all(np.isfinite(req)) or cur.shape != (n,) or not np.all(np.isfinite(cur)):
            raise UnsafeCommandError(f"move target {req.tolist()} / measured {cur.tolist()} unusable for "
                                     f"{list(self.joint_names)}; nothing was sent")
        return replace(self._decide_move(req, cur, samples), measured=cur.copy())

    def _decide_move(self, req: np.ndarray, cur: np.ndarray, samples: int) -> SafetyDecision:
        safe = np.minimum(np.maximum(req, self.lower), self.upper)
        events = (JOINT_LIMITS,) if np.any(safe != req) else ()
        if self.chain is None or (self.workspace_min is None and self.floor_z is None):
            return SafetyDecision(safe, events, False, "clamped to the joint limits" if events else "")
        allowed = float(self.violation(cur)) + 1e-9
        ts = np.linspace(0.0, 1.0, max(2, int(samples)) + 1)[1:]
        path = cur + ts[:, None] * (safe - cur)
        bad = np.flatnonzero(self.violation(path) > allowed)
        if bad.size:
            region = self._region_events(path[bad[0]]) or (WORKSPACE,)
            where = np.round(self.ee_position(path[bad[0]]), 3).tolist()
            return SafetyDecision(None, events + region, True,
                                  f"refused: on the way to {np.round(safe, 4).tolist()} the end effector would leave "
                                  f"the {' and '.join(region)} limits at {where}")
        return SafetyDecision(safe, events, False, "clamped to the joint limits" if events else "",
                              self.ee_position(safe))

    def __repr__(self) -> str:
        box = None if self.workspace_min is None or self.workspace_max is None else (
            self.workspace_min.tolist(), self.workspace_max.tolist())
        cap = None if self.max_joint_delta is None else self.max_joint_delta.tolist()
        return (f"SafetyRules(joints={list(self.joint_names)}, max_joint_delta={cap}, workspace={box}, "
                f"floor_z={self.floor_z}, mode={self.workspace_mode!r})")
