"""MultiROS-style ROS 2 environments on a MuJoCo simulation node.

Layers (each imports only the ones before it): ``multiros.ros`` (ROS 2 client layer),
``multiros.sim`` (the MuJoCo simulation node), ``multiros.envs`` (gymnasium base envs),
``multiros.utils`` and ``multiros.wrappers``.
"""

import os as _os
import sys as _sys

__version__ = "0.1.0"


def _default_gl_backend() -> None:
    """Pick MuJoCo's headless EGL backend when the user chose none and there is no display.

    MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, so this runs when ``multiros`` is
    imported (``uniros`` imports it first). It never overrides a user's choice.
    """
    if _os.environ.get("MUJOCO_GL") or not _sys.platform.startswith("linux"):
        return
    if _os.environ.get("DISPLAY") or _os.environ.get("WAYLAND_DISPLAY"):
        return
    if "mujoco" not in _sys.modules:
        _os.environ["MUJOCO_GL"] = "egl"


_default_gl_backend()
