"""Camera images in Stable-Baselines3 models: SB3's CNNs take images channel-first (C x H x W) and
uniros' camera observations are H x W x C, as ROS' ``sensor_msgs/Image`` and the renderers give them;
normalisation scales vectors only. The training env, the evaluation env and the check of a model's
spaces all use these, so a camera env trains, resumes and evaluates like any other.
"""

from __future__ import annotations

from typing import Any

__all__ = ["channel_first_space", "images_channel_first", "is_image", "vector_keys"]


def is_image(space: Any) -> bool:
    """Whether ``space`` is a camera image to SB3 (uint8, 3 dimensions, either channel order). Depth
    maps are float: SB3's extractors, and these helpers, treat them as vectors."""
    from stable_baselines3.common.preprocessing import is_image_space

    return is_image_space(space, check_channels=False)


def images_channel_first(venv: Any) -> Any:
    """``venv`` with its camera images (uint8, H x W x C) transposed channel-first, as SB3's CNNs
    take them (unchanged without images)."""
    from gymnasium import spaces
    from stable_baselines3.common.preprocessing import is_image_space_channels_first
    from stable_baselines3.common.vec_env import VecTransposeImage, is_vecenv_wrapped

    space = venv.observation_space
    parts = space.spaces.values() if isinstance(space, spaces.Dict) else [space]
    if is_vecenv_wrapped(venv, VecTransposeImage) or not any(
            is_image(s) and not is_image_space_channels_first(s) for s in parts):
        return venv
    return VecTransposeImage(venv)


def channel_first_space(space: Any) -> Any:
    """``space`` with its images channel-first (what a model trained on it saved)."""
    from gymnasium import spaces
    from stable_baselines3.common.preprocessing import is_image_space_channels_first
    from stable_baselines3.common.vec_env import VecTransposeImage

    def one(s: Any) -> Any:
        return VecTransposeImage.transpose_space(s) if is_image(s) and not is_image_space_channels_first(s) else s

    if isinstance(space, spaces.Dict):
        return spaces.Dict({k: one(s) for k, s in space.spaces.items()})
    return one(space)


def vector_keys(space: Any) -> list[str] | None:
    """The keys of a dict observation that normalisation may scale: all but images (``None``: all)."""
    from gymnasium import spaces

    if not isinstance(space, spaces.Dict) or not any(is_image(s) for s in space.spaces.values()):
        return None
    return [k for k, s in space.spaces.items() if not is_image(s)]
