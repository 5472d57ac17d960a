"""Third-party imports made quiet: gymnasium_robotics prints an AdroitHand version notice on import."""

from __future__ import annotations


def _import_gymnasium_robotics_quietly() -> None:
    """Import gymnasium_robotics without its AdroitHand version notice (printed to stderr on import,
    about envs uniros does not use). Only that notice is withheld: farama_notifications' entry for
    gymnasium_robotics is removed for the import and put back after."""
    import sys

    if "gymnasium_robotics" in sys.modules:
        return
    try:
        from farama_notifications import notifications
    except ImportError:
        notifications = {}
    saved = notifications.pop("gymnasium_robotics", None)
    try:
        import gymnasium_robotics  # noqa: F401
    finally:
        if saved is not None:
            notifications["gymnasium_robotics"] = saved


_import_gymnasium_robotics_quietly()
