"""Running a saved model on another env ID (for example a simulation-trained model on the Real twin):
the spaces stored in the model file must equal the env's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


class SpaceMismatchError(ValueError):
    """A model's observation or action space differs from the env's."""


def model_spaces(model_path: str | Path) -> tuple[Any, Any]:
    """The ``(observation_space, action_space)`` stored in a Stable-Baselines3 model file."""
    from stable_baselines3.common.save_util import load_from_zip_file

    data, _, _ = load_from_zip_file(str(model_path), load_data=True, device="cpu")
    if not data or "observation_space" not in data or "action_space" not in data:
        raise SpaceMismatchError(f"{model_path}: the model file stores no observation/action spaces")
    return data["observation_space"], data["action_space"]


def check_model_spaces(model_path: str | Path, env: Any, env_id: str = "") -> None:
    """Raise :class:`SpaceMismatchError` naming the difference unless ``env``'s spaces equal the model's."""
    from uniros.image_spaces import channel_first_space

    obs, act = model_spaces(model_path)
    problems = []
    if obs != channel_first_space(env.observation_space):  # the model holds images channel-first
        problems.append(f"observation space: model {obs}, env {env.observation_space}")
    if act != env.action_space:
        problems.append(f"action space: model {act}, env {env.action_space}")
    if problems:
        raise SpaceMismatchError(
            f"{model_path} cannot run on {env_id or 'this env'}: " + "; ".join(problems)
            + ". Evaluate it on an env with equal spaces (the Real twin of its training env, with the same "
            "task options such as ee_action_type)")
