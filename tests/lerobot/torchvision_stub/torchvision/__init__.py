"""A stand-in for torchvision, for LeRobot 0.4.4 next to the CPU torch 2.13 (tests/lerobot, .ci/lerobot).

PyPI's only torchvision for torch 2.13 is the CUDA build, whose ``_C.so`` needs ``libc10_cuda.so``: it
cannot be imported next to the CPU torch (``RuntimeError: operator torchvision::nms does not exist``).
LeRobot imports torchvision at the top of its dataset, processor and some policy modules, and uses it
for image transforms, video decoding and vision backbones: none of which a state-only dataset or the
uniros env plugin with a policy without a vision backbone reaches. This package, put first on
``PYTHONPATH``, lets those imports succeed; any use of a name from it raises, naming the stand-in.
"""

from typing import Any


class _Missing:
    """A torchvision name that was imported but must not be used."""

    def __init__(self, name: str) -> None:
        self._name = name

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise RuntimeError(f"torchvision.{self._name} was used, but torchvision is the tests' stand-in "
                           "(tests/lerobot/torchvision_stub): LeRobot reached an image transform or video decoder")

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        return _Missing(f"{self._name}.{attr}")

    def __mro_entries__(self, bases: tuple[Any, ...]) -> tuple[type, ...]:
        return (object,)  # ``class X(torchvision.transforms.v2.Transform)`` still defines X


def missing(module: str, name: str) -> Any:
    """The module-level ``__getattr__`` of the stand-in's modules."""
    if name.startswith("__"):
        raise AttributeError(name)
    return _Missing(f"{module}{name}")


__version__ = "0.0.0+uniros.stand.in"


def __getattr__(name: str) -> Any:
    return missing("", name)
