"""The stand-in's ``torchvision.transforms.v2``: imports succeed, any use raises (the package docstring)."""

from typing import Any

from torchvision import missing


def __getattr__(name: str) -> Any:
    return missing("transforms.v2.", name)
