"""Fixtures: the two description packages processed to URDF text (xacro, no package lookup)."""

from __future__ import annotations

import pytest
from xacro_text import process

from rl_environments.robots import abb_irb120_description, rx200_description


@pytest.fixture(scope="session")
def rx200_urdf() -> str:
    return process(rx200_description.URDF_XACRO)


@pytest.fixture(scope="session")
def irb120_urdf() -> str:
    return process(abb_irb120_description.URDF_XACRO)
