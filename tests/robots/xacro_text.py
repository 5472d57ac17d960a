"""xacro files to URDF text for the robot description tests (a module of its own: test modules
import it by name, which ``conftest`` is not safe for when several folders have one)."""

from __future__ import annotations

import xacro


def process(path, **args: str) -> str:
    """xacro file -> URDF XML text, with xacro args."""
    return xacro.process_file(str(path), mappings=dict(args)).toxml()
