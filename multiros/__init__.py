"""MultiROS-style ROS 2 environments on a MuJoCo simulation node.

Layers (each imports only the ones before it): ``multiros.ros`` (ROS 2 client layer),
``multiros.sim`` (the MuJoCo simulation node), ``multiros.envs`` (gymnasium base envs),
``multiros.utils`` and ``multiros.wrappers``.
"""

__version__ = "0.1.0"


def _default_gl_backend() -> None:
    """Pick MuJoCo's OpenGL backend when the user chose none (:mod:`multiros.gl_backend`: EGL on an
    NVIDIA GPU when its EGL vendor is installed, else software).

    MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, so this runs when ``multiros`` is
    imported (``uniros`` imports it first). It never overrides a user's choice.
    """
    from multiros import gl_backend

    gl_backend.apply()


_default_gl_backend()
