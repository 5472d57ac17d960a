"""The stand-in's ``torchvision.transforms.functional``: imports succeed, any use raises (the package docstring)."""

from typing import Any

from torchvision import missing


def __getattr__(name: str) -> Any:
    return missing("transforms.functional.", name)
