"""The algorithm table (``uniros.algorithms.ALGOS``): every algorithm builds from a YAML block, trains
a few steps, is recognised in its saved file, and the table alone decides what a config may ask."""

from __future__ import annotations

import gymnasium as gym
import pytest

from uniros.algorithms import ALGOS, algorithm_class, is_off_policy, takes_action_noise, takes_sde
from uniros.train_config import TrainingConfigError, parse_training_config
from uniros.trainer import algorithm_of, build_model

DISCRETE = {"dqn", "qrdqn"}
SMALL = {
    "sac": {"learning_starts": 10, "batch_size": 8}, "td3": {"learning_starts": 10, "batch_size": 8},
    "ddpg": {"learning_starts": 10, "batch_size": 8}, "tqc": {"learning_starts": 10, "batch_size": 8},
    "crossq": {"learning_starts": 10, "batch_size": 8}, "dqn": {"learning_starts": 10, "batch_size": 8},
    "qrdqn": {"learning_starts": 10, "batch_size": 8}, "ppo": {"n_steps": 16, "batch_size": 8},
    "a2c": {"n_steps": 8}, "trpo": {"n_steps": 16, "batch_size": 8}, "ars": {"n_delta": 2},
    "drq_sac": {"learning_starts": 10, "batch_size": 8},
}


@pytest.mark.parametrize("name", list(ALGOS))
def test_every_algorithm_builds_learns_and_is_recognised_in_its_file(name, tmp_path):
    env = gym.make("CartPole-v1" if name in DISCRETE else "Pendulum-v1")
    config = parse_training_config({"algorithm": name, "training_steps": 40, f"{name}_params": SMALL[name]},
                                   f"{name}.yaml")
    model = build_model(config, env)
    assert isinstance(model, algorithm_class(name))
    model.learn(40)
    model.save(tmp_path / f"{name}.zip")
    assert algorithm_of(tmp_path / f"{name}.zip") == name


def test_the_table_decides_what_a_config_may_ask():
    assert is_off_policy("tqc") and not is_off_policy("trpo")
    assert takes_action_noise("td3") and not takes_action_noise("dqn")
    assert takes_sde("tqc") and not takes_sde("td3")
    config = parse_training_config({"algorithm": "tqc", "training_steps": 5, "use_HER": True,
                                    "tqc_params": {"top_quantiles_to_drop_per_net": 2}})
    assert config.algorithm == "tqc" and config.use_her
    with pytest.raises(TrainingConfigError, match=r"use_HER needs an off-policy algorithm \(sac, .*tqc.*\), not 'trpo"):
        parse_training_config({"algorithm": "trpo", "training_steps": 5, "use_HER": True})
    with pytest.raises(TrainingConfigError, match="algorithm 'tqd' is not one of .*did you mean 'tqc'"):
        parse_training_config({"algorithm": "tqd", "training_steps": 5})
    with pytest.raises(TrainingConfigError, match=r"tqc_params: unknown key 'top_quantile'"):
        parse_training_config({"algorithm": "tqc", "training_steps": 5, "tqc_params": {"top_quantile": 2}})


def test_an_algorithm_without_a_dict_policy_is_refused_on_a_goal_env():
    from stable_baselines3.common.envs import BitFlippingEnv

    config = parse_training_config({"algorithm": "crossq", "training_steps": 5}, "crossq.yaml")
    with pytest.raises(TrainingConfigError, match="crossq has no MultiInputPolicy"):
        build_model(config, BitFlippingEnv(n_bits=4, continuous=True))
