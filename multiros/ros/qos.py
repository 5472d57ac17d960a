"""Quality-of-service profiles with the ROS 2 default values (``rmw/qos_profiles.h``).

Enum values equal rmw's numeric values, which rmw_zenoh writes into its liveliness tokens.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import IntEnum

__all__ = [
    "HistoryPolicy",
    "ReliabilityPolicy",
    "DurabilityPolicy",
    "LivelinessPolicy",
    "QoSProfile",
    "qos_profile_default",
    "qos_profile_system_default",
    "qos_profile_sensor_data",
    "qos_profile_services_default",
    "qos_profile_parameters",
    "qos_profile_parameter_events",
    "qos_profile_clock",
    "as_qos_profile",
    "qos_compatible",
]


class HistoryPolicy(IntEnum):
    """How many samples are kept (rmw_qos_history_policy_e)."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2


class ReliabilityPolicy(IntEnum):
    """Whether lost samples are retransmitted (rmw_qos_reliability_policy_e)."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2


class DurabilityPolicy(IntEnum):
    """Whether late joiners get past samples (rmw_qos_durability_policy_e)."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class LivelinessPolicy(IntEnum):
    """Liveliness assertion kind (rmw_qos_liveliness_policy_e)."""

    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3


@dataclass(frozen=True)
class QoSProfile:
    """A QoS profile; keyword construction like ``rclpy.qos.QoSProfile``.

    Args:
        history: keep last ``depth`` samples, or keep all.
        depth: queue depth for KEEP_LAST.
        reliability: RELIABLE or BEST_EFFORT.
        durability: VOLATILE or TRANSIENT_LOCAL (late joiners get the last ``depth`` samples).
        liveliness: kept for API compatibility; only AUTOMATIC is implemented.
    """

    history: HistoryPolicy = HistoryPolicy.KEEP_LAST
    depth: int = 10
    reliability: ReliabilityPolicy = ReliabilityPolicy.RELIABLE
    durability: DurabilityPolicy = DurabilityPolicy.VOLATILE
    liveliness: LivelinessPolicy = LivelinessPolicy.AUTOMATIC

    def __post_init__(self) -> None:
        # System defaults resolve to the rmw defaults, as every RMW does.
        if self.history == HistoryPolicy.SYSTEM_DEFAULT:
            object.__setattr__(self, "history", HistoryPolicy.KEEP_LAST)
        if self.reliability == ReliabilityPolicy.SYSTEM_DEFAULT:
            object.__setattr__(self, "reliability", ReliabilityPolicy.RELIABLE)
        if self.durability == DurabilityPolicy.SYSTEM_DEFAULT:
            object.__setattr__(self, "durability", DurabilityPolicy.VOLATILE)
        if self.liveliness == LivelinessPolicy.SYSTEM_DEFAULT:
            object.__setattr__(self, "liveliness", LivelinessPolicy.AUTOMATIC)
        object.__setattr__(self, "history", HistoryPolicy(self.history))
        object.__setattr__(self, "reliability", ReliabilityPolicy(self.reliability))
        object.__setattr__(self, "durability", DurabilityPolicy(self.durability))
        if not isinstance(self.depth, int) or self.depth < 0:
            raise ValueError(f"QoS depth must be an int >= 0, got {self.depth!r}")
        if self.history == HistoryPolicy.KEEP_LAST and self.depth == 0:
            raise ValueError("QoS depth 0 with KEEP_LAST keeps nothing: use a depth >= 1 or KEEP_ALL")

    def with_(self, **changes: object) -> QoSProfile:
        """A copy with some fields changed."""
        return replace(self, **changes)  # type: ignore[arg-type]

    @property
    def queue_size(self) -> int | None:
        """The bound of a receive queue: ``depth`` for KEEP_LAST, ``None`` (unbounded) for KEEP_ALL."""
        return self.depth if self.history == HistoryPolicy.KEEP_LAST else None


qos_profile_default = QoSProfile()
qos_profile_system_default = QoSProfile()
qos_profile_services_default = QoSProfile()
qos_profile_sensor_data = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
qos_profile_parameters = QoSProfile(depth=1000)
qos_profile_parameter_events = QoSProfile(depth=1000)
qos_profile_clock = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


def as_qos_profile(qos: QoSProfile | int) -> QoSProfile:
    """Accept a profile or a plain history depth (``10``), as rclpy does.

    Raises:
        TypeError: ``qos`` is neither.
    """
    if isinstance(qos, QoSProfile):
        return qos
    if isinstance(qos, int) and not isinstance(qos, bool):
        return QoSProfile(depth=qos)
    raise TypeError(f"qos_profile must be a QoSProfile or an int history depth, got {type(qos).__name__}")


def qos_compatible(publisher: QoSProfile, subscription: QoSProfile) -> bool:
    """Request/offer matching as DDS defines it (what rmw_zenoh also reports).

    A best-effort publisher cannot serve a reliable subscription; a volatile publisher cannot
    serve a transient-local subscription.
    """
    if (
        publisher.reliability == ReliabilityPolicy.BEST_EFFORT
        and subscription.reliability == ReliabilityPolicy.RELIABLE
    ):
        return False
    return not (
        publisher.durability == DurabilityPolicy.VOLATILE
        and subscription.durability == DurabilityPolicy.TRANSIENT_LOCAL
    )
