"""The reach task shared by every robot: goal sampling inside the reachable workspace, vectorised
rewards and success.

Pure functions and a small sampler, so HER can call them on batches (``axis=-1``) with no ROS
call and no side effect, as ``compute_reward`` requires.
"""

from __future__ import annotations

import math
import numbers
from typing import Literal

import numpy as np
import numpy.typing as npt

from multiros.utils.kinematics import KinematicChain

RewardType = Literal["sparse", "dense"]


def goal_distance(achieved_goal: np.ndarray, desired_goal: np.ndarray) -> np.ndarray:
    """Euclidean distance over the last axis (works for single goals and batches).

    The squares are summed in axis order on both paths, so a goal scored alone (every env step, as
    plain floats: numpy's per-call cost would be most of the work) and the same goal inside a HER
    batch give the same bits.
    """
    a, b = np.asarray(achieved_goal), np.asarray(desired_goal)
    if a.ndim == 1 and a.shape == b.shape:
        total = 0.0
        for x, y in zip(a.tolist(), b.tolist()):
            d = x - y
            total += d * d
        return np.float64(math.sqrt(total))
    if a.ndim == 2 and a.shape == b.shape and len(a) <= 16:  # a few rows: the same sums, without numpy's overhead
        out = []
        for ra, rb in zip(a.tolist(), b.tolist()):
            total = 0.0
            for x, y in zip(ra, rb):
                d = x - y
                total += d * d
            out.append(math.sqrt(total))
        return np.array(out)
    diff = a.astype(np.float64) - b.astype(np.float64)
    total = np.zeros(diff.shape[:-1])
    for k in range(diff.shape[-1]):
        total += diff[..., k] * diff[..., k]
    return np.sqrt(total)


def is_success(achieved_goal: np.ndarray, desired_goal: np.ndarray, tolerance: float) -> np.ndarray:
    """True where the achieved goal is within ``tolerance`` metres of the desired goal."""
    return goal_distance(achieved_goal, desired_goal) <= tolerance


def goal_reward(
    achieved_goal: np.ndarray,
    desired_goal: np.ndarray,
    tolerance: float,
    reward_type: RewardType,
    sparse_values: tuple[float, float] = (0.0, -1.0),
) -> np.ndarray | float:
    """Sparse (``sparse_values`` = (reached, not reached)) or dense (``-distance``) reward, vectorised;
    a float32 array for batches, a float (of a float32) for one goal."""
    return reward_from_distance(goal_distance(achieved_goal, desired_goal), tolerance, reward_type, sparse_values)


def reward_from_distance(
    d: np.ndarray,
    tolerance: float | np.ndarray,
    reward_type: RewardType,
    sparse_values: tuple[float, float] = (0.0, -1.0),
) -> np.ndarray | float:
    """:func:`goal_reward` from the goal distance(s) ``d`` (:func:`goal_distance`)."""
    if not isinstance(d, np.ndarray) or d.ndim == 0:
        value = -d if reward_type == "dense" else sparse_values[0] if d <= tolerance else sparse_values[1]
        return float(np.float32(value))
    if reward_type == "dense":
        return (-d).astype(np.float32)
    if d.ndim == 1 and len(d) <= 16 and not isinstance(tolerance, np.ndarray):
        # a few goals (every env step): chosen as plain floats, a fifth of numpy's per-call time
        reached, missed = sparse_values
        return np.array([reached if x <= tolerance else missed for x in d.tolist()], dtype=np.float32)
    return np.asarray(np.where(d <= tolerance, sparse_values[0], sparse_values[1]), dtype=np.float32)


def parse_reward_type(value: str) -> RewardType:
    """``"sparse"`` or ``"dense"`` (case-insensitive, as the original configs spell them either way)."""
    v = str(value).lower()
    if v not in ("sparse", "dense"):
        raise ValueError(f"reward_type {value!r} is not 'sparse' or 'dense'")
    return v  # type: ignore[return-value]


class GoalSampler:
    """Samples goals the robot can reach, inside a box.

    Goals are forward kinematics of uniformly random joint configurations (within the joint
    limits, optionally narrowed), kept when they fall inside the goal box: every goal is reachable
    by construction, with no IK call.

    A goal is the first configuration, in the order ``rng`` draws them one row at a time, whose tip
    lands in the box; ``rng`` moves on past that row and no further. The goal is thus a function of
    the generator's state alone (a seed, or a restored state, gives the same goals whatever came
    before). The forward kinematics runs ``batch_size`` rows ahead in one pass, and the rows past
    the goal are kept for the next call while that call passes the same generator in the state this
    one left it in (a box often takes one configuration in fifty or more: a batch per goal would
    throw most of that work away).

    Args:
        chain: the arm's kinematic chain (base frame = the robot's base link).
        low, high: the goal box corners in the base frame.
        base_position: the robot base's world position (goals are returned in the world frame).
        joint_low, joint_high: optional narrower joint ranges to sample from.
        max_tries: bound on rejection sampling; the box must overlap the workspace.
        batch_size: configurations per draw; by default sized for about eight goals per batch from
            how often 1,024 configurations of a fixed probe land in the box (64 to 1,024).
    """

    def __init__(
        self,
        chain: KinematicChain,
        low: npt.ArrayLike,
        high: npt.ArrayLike,
        *,
        base_position: npt.ArrayLike = (0.0, 0.0, 0.0),
        joint_low: npt.ArrayLike | None = None,
        joint_high: npt.ArrayLike | None = None,
        max_tries: int = 10_000,
        batch_size: int | None = None,
    ) -> None:
        self.chain = chain
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        if self.low.shape != (3,) or self.high.shape != (3,) or np.any(self.low > self.high):
            raise ValueError(f"goal box low {low} / high {high} must be 3 numbers each with low <= high")
        self.base_position = np.asarray(base_position, dtype=np.float64)
        jl = chain.lower if joint_low is None else np.asarray(joint_low, dtype=np.float64)
        jh = chain.upper if joint_high is None else np.asarray(joint_high, dtype=np.float64)
        self.joint_low = np.where(np.isfinite(jl), jl, -np.pi)
        self.joint_high = np.where(np.isfinite(jh), jh, np.pi)
        self.max_tries = int(max_tries)
        if batch_size is not None and (isinstance(batch_size, bool) or not isinstance(batch_size, numbers.Integral)
                                       or batch_size < 1):
            raise ValueError(f"batch_size must be a positive integer, got {batch_size!r}")
        self.batch_size = self._probe_batch_size() if batch_size is None else int(batch_size)
        # Rows drawn ahead of the generator: their tip positions, whether each is inside, and the
        # generator and its state they start from.
        self._ahead: tuple[np.ndarray, np.ndarray, np.random.Generator, dict] | None = None

    def _positions(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tip positions of configurations ``q`` and whether each falls inside the box."""
        p = self.chain.fk_position(q)
        return p, np.all((p >= self.low) & (p <= self.high), axis=1)

    def _probe_batch_size(self, probe: int = 1024, goals_per_batch: int = 8) -> int:
        """A batch size for about ``goals_per_batch`` goals, from a fixed probe: it depends on the
        chain, the box and the joint ranges only, never on the caller's generator."""
        q = np.random.default_rng(0).uniform(self.joint_low, self.joint_high, size=(probe, self.chain.n_joints))
        hits = int(np.count_nonzero(self._positions(q)[1]))
        return int(np.clip(math.ceil(goals_per_batch * probe / max(hits, 1)), 64, probe))

    def _draw(self, rng: np.random.Generator, rows: int) -> np.ndarray:
        return rng.uniform(self.joint_low, self.joint_high, size=(rows, self.chain.n_joints))

    def _skip(self, rng: np.random.Generator, rows: int) -> None:
        """Move ``rng`` past ``rows`` rows of :meth:`_draw` (a uniform double takes one draw, whatever
        its bounds), in a tenth of the time drawing them takes."""
        rng.random(rows * self.chain.n_joints)

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """One reachable goal (world frame) drawn with ``rng``.

        Raises:
            RuntimeError: no configuration landed in the box within ``max_tries`` draws.
        """
        ahead, self._ahead = self._ahead, None
        if ahead is not None and (ahead[2] is not rng or rng.bit_generator.state != ahead[3]):
            ahead = None
        tried = 0
        while tried < self.max_tries:
            if ahead is None:
                start, rows = rng.bit_generator.state, max(1, min(self.batch_size, self.max_tries - tried))
                positions, inside = self._positions(self._draw(rng, rows))
                rng.bit_generator.state = start  # back to the first row: rows are taken one by one below
            else:
                positions, inside = ahead[0], ahead[1]
            hits = np.flatnonzero(inside)
            if not hits.size:
                self._skip(rng, len(inside))
                tried += len(inside)
                ahead = None
                continue
            row = int(hits[0])
            self._skip(rng, row + 1)  # the generator moves past the goal's row, as if drawn one at a time
            if row + 1 < len(inside):
                self._ahead = positions[row + 1:], inside[row + 1:], rng, rng.bit_generator.state
            return positions[row] + self.base_position
        raise RuntimeError(
            f"no reachable goal inside the box {self.low.tolist()}..{self.high.tolist()} after {self.max_tries} "
            "tries: the goal box does not overlap the robot's workspace"
        )
