"""Fixtures: the two description packages processed to URDF text (xacro, no package lookup)."""

from __future__ import annotations

import pytest
import xacro

from rl_environments.robots import abb_irb120_description, rx200_description


def process(path, **args: str) -> str:
    """xacro file -> URDF XML text, with xacro args."""
    return xacro.process_file(str(path), mappings=dict(args)).toxml()


@pytest.fixture(scope="session")
def rx200_urdf() -> str:
    return process(rx200_description.URDF_XACRO)


@pytest.fixture(scope="session")
def irb120_urdf() -> str:
    return process(abb_irb120_description.URDF_XACRO)
