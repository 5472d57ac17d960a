"""Which torch device a model trains and runs on: ``auto``, ``cpu``, ``cuda`` or ``cuda:N``.

``auto`` (the default) puts a policy that sees camera images on the GPU when CUDA is present and
every other policy on the CPU. SB3's small MLPs (two layers of 256) gain nothing on a GPU: each
update moves a 256-sample batch to the device and back, and the kernel launches cost more than the
arithmetic, so they train at least as fast on the CPU (SB3's own advice for MLP policies). A CNN on
84 x 84 images is the opposite: 13-20 ms per env step on an H200 against 74 ms on a 2-core CPU
(issue 37, ``benchmarks/bench_pixel_learning.py --runs pixels_strict``). Asking for ``cuda``
without CUDA is a one-line error, never a silent fall-back to the CPU.
"""

from __future__ import annotations

import re
from typing import Any

from uniros.errors import TrainingConfigError

__all__ = ["DEVICE_CHOICES", "check_device", "has_image", "resolve_device"]

#: What ``--device`` and ``<algo>_params.device`` take (``cuda:N`` too).
DEVICE_CHOICES = ("auto", "cpu", "cuda")
_DEVICE = re.compile(r"^(auto|cpu|cuda(:[0-9]{1,2})?)$")


def check_device(value: Any, where: str = "device") -> str:
    """``value`` as a device choice (lower-case).

    Raises:
        TrainingConfigError: not ``auto``, ``cpu``, ``cuda`` or ``cuda:N``.
    """
    name = value.strip().lower() if isinstance(value, str) else value
    if not isinstance(name, str) or not _DEVICE.match(name):
        raise TrainingConfigError(f"{where} must be auto, cpu, cuda or cuda:N (a GPU's index), got {value!r}")
    return name


def has_image(space: Any) -> bool:
    """Whether an observation space holds a camera image (so the policy is a CNN)."""
    from gymnasium import spaces

    from uniros.image_spaces import is_image

    parts = space.spaces.values() if isinstance(space, spaces.Dict) else [space]
    return any(is_image(s) for s in parts)


def _cuda_count() -> int:
    import torch

    return int(torch.cuda.device_count()) if torch.cuda.is_available() else 0


def resolve_device(choice: Any, observation_space: Any = None, where: str = "device") -> str:
    """The torch device for ``choice`` and a policy on ``observation_space``.

    ``auto``: ``cuda`` for a policy that sees images when CUDA is present, else ``cpu``.

    Raises:
        TrainingConfigError: a bad choice, or ``cuda``/``cuda:N`` asked for where torch finds no
            such GPU.
    """
    name = check_device("auto" if choice is None else choice, where)
    if name == "cpu":
        return "cpu"
    count = _cuda_count()
    if name == "auto":
        return "cuda" if count and observation_space is not None and has_image(observation_space) else "cpu"
    index = int(name.partition(":")[2] or 0)
    if count == 0:
        import torch

        build = f"torch {torch.__version__}" + ("" if torch.version.cuda else ", a CPU-only build")
        raise TrainingConfigError(f"{where} {name!r} asked for, but torch finds no CUDA GPU ({build}): "
                                  "use --device cpu or auto")
    if index >= count:
        raise TrainingConfigError(f"{where} {name!r} asked for, but torch finds {count} CUDA GPU(s) "
                                  f"(cuda:0{f' to cuda:{count - 1}' if count > 1 else ''})")
    return name
