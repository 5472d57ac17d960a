"""GoalSampler: a goal is the first configuration in the box of the generator's row stream, whatever
the batches its forward kinematics runs ahead in."""

from __future__ import annotations

import numpy as np
import pytest

from multiros.utils.kinematics import KinematicChain
from rl_environments.reach import GoalSampler
from rl_environments.robots import rx200_description as rx200

LOW, HIGH = [0.15, -0.15, 0.05], [0.3, 0.15, 0.25]


@pytest.fixture(scope="module")
def chain() -> KinematicChain:
    return KinematicChain.from_urdf(rx200.URDF_XACRO, "rx200/base_link", "rx200/ee_gripper_link")


def _sampler(chain: KinematicChain, **kwargs) -> GoalSampler:
    return GoalSampler(chain, LOW, HIGH, base_position=[1.0, 2.0, 0.0], **kwargs)


class _Counting:
    """A chain that counts the configurations it is asked about."""

    def __init__(self, chain: KinematicChain) -> None:
        self.chain, self.configurations = chain, 0

    def __getattr__(self, name: str):
        return getattr(self.chain, name)

    def fk_position(self, q: np.ndarray) -> np.ndarray:
        self.configurations += len(q)
        return self.chain.fk_position(q)


def test_the_default_batch_holds_several_goals_and_is_used_up_before_the_next(chain):
    sampler = _sampler(chain)
    probe = np.random.default_rng(0).uniform(sampler.joint_low, sampler.joint_high, size=(1024, 5))
    rate = np.count_nonzero(sampler._positions(probe)[1]) / 1024
    assert 64 <= sampler.batch_size <= 1024
    assert sampler.batch_size == pytest.approx(8 / rate, abs=1)  # about eight goals per batch
    counting = _Counting(chain)
    sampler.chain = counting
    rng = np.random.default_rng(1)
    goals = np.array([sampler.sample(rng) for _ in range(40)])
    assert counting.configurations <= 20 * sampler.batch_size  # one batch per goal would be 40
    local = goals - [1.0, 2.0, 0.0]
    assert np.all(local >= LOW) and np.all(local <= HIGH)
    assert len(np.unique(goals, axis=0)) == 40


def test_a_seed_gives_the_same_goals_whatever_came_before(chain):
    fresh = _sampler(chain)
    rng = np.random.default_rng(7)
    expected = [fresh.sample(rng) for _ in range(12)]
    used = _sampler(chain)
    other = np.random.default_rng(99)
    for _ in range(5):
        used.sample(other)  # goals left over from this generator's batch must not leak into the next
    rng = np.random.default_rng(7)
    np.testing.assert_array_equal([used.sample(rng) for _ in range(12)], expected)


def _one_row_at_a_time(sampler: GoalSampler, rng: np.random.Generator) -> np.ndarray:
    """The plain rejection sampler the batches must reproduce."""
    while True:
        q = rng.uniform(sampler.joint_low, sampler.joint_high, size=(1, 5))
        p = sampler.chain.fk_matrix(q[0])[:3, 3]
        if np.all(p >= sampler.low) and np.all(p <= sampler.high):
            return p + sampler.base_position


@pytest.mark.parametrize("batch_size", [None, 1, 7, 64])
def test_goals_and_the_generator_follow_the_row_stream(chain, batch_size):
    sampler, plain = _sampler(chain, batch_size=batch_size), _sampler(chain, batch_size=1)
    rng, twin = np.random.default_rng(11), np.random.default_rng(11)
    for _ in range(12):
        np.testing.assert_allclose(sampler.sample(rng), _one_row_at_a_time(plain, twin), rtol=0, atol=1e-12)
        assert rng.bit_generator.state == twin.bit_generator.state  # moved past the goal's row, no further
    assert rng.uniform() == twin.uniform()


def test_a_generator_used_in_between_or_rewound_gets_the_goals_of_its_state(chain):
    sampler, reference = _sampler(chain), _sampler(chain)
    rng = np.random.default_rng(3)
    sampler.sample(rng)
    assert sampler._ahead is not None  # the batch left rows for the next call
    rng.uniform()  # the generator moved on: its next goal is the one of the state it is in now
    twin = np.random.default_rng(3)
    twin.bit_generator.state = rng.bit_generator.state
    np.testing.assert_array_equal(sampler.sample(rng), reference.sample(twin))
    state = rng.bit_generator.state
    first = [sampler.sample(rng) for _ in range(3)]
    rng.bit_generator.state = state  # rewound: the same goals again
    np.testing.assert_array_equal([sampler.sample(rng) for _ in range(3)], first)


def test_batch_size_is_checked_and_bounded_by_max_tries(chain):
    for bad in (0, -3, 2.5, "8", True):
        with pytest.raises(ValueError, match="batch_size must be a positive integer"):
            _sampler(chain, batch_size=bad)
    assert _sampler(chain, batch_size=np.int64(32)).batch_size == 32
    counting = _Counting(chain)
    outside = GoalSampler(counting, [5, 5, 5], [6, 6, 6], max_tries=100, batch_size=64)
    assert outside.batch_size == 64
    with pytest.raises(RuntimeError, match="does not overlap"):
        outside.sample(np.random.default_rng(0))
    assert counting.configurations == 100  # 64, then the 36 tries left; no probe when batch_size is given
    assert GoalSampler(chain, [5, 5, 5], [6, 6, 6]).batch_size == 1024  # nothing in the box: the largest batch
