"""The rmw_zenoh_cpp-compatible transport (see ``transport.py``)."""

from multiros.ros.transport.zenoh.config import ZenohSettings
from multiros.ros.transport.zenoh.transport import ZenohTransport

__all__ = ["ZenohTransport", "ZenohSettings"]
