"""Fast DDS's service request histories that free each request once taken, for a long-lived node process.

rmw_fastrtps gives every reader and writer ``PREALLOCATED_WITH_REALLOC`` history memory: a payload
buffer, once grown to the largest sample it held, stays that size in the history's pool for the life
of the entity. A service's request reader (``KEEP_ALL``: every request kept until taken) thus keeps
as many buffers as requests ever waited at once, each the size of the largest it held: after a flood
of large parameter requests (``benchmarks/bench_hostile_neighbour.py --attacks params_rclpy``:
8 MB arrays, 100,000-name gets, 50 requests in flight) the node kept about 60 MB of them for good
(74 MB of live mapped buffers where malloc was set to map every large one).

The only way to another policy is an XML profile with ``RMW_FASTRTPS_USE_QOS_FROM_XML=1``, which also
stops rmw from setting its own defaults everywhere else. So :func:`service_history_profile` writes a
profile that restates those defaults (rmw_fastrtps Humble to Rolling: ``PREALLOCATED_WITH_REALLOC``
for every reader and writer and for discovery's builtin ones, data sharing off, synchronous
publication) and gives only the readers of service requests (rmw's profile ``service``)
``DYNAMIC`` memory: a request's buffer is freed once the request is taken. It applies while the node
process creates its ROS participant (rmw_fastrtps creates it with the context's first node), then
removes the file and puts the environment back.

It steps aside wherever the user configures Fast DDS: an XML profile file named by the environment
or in the working directory, ``RMW_FASTRTPS_USE_QOS_FROM_XML`` or ``RMW_FASTRTPS_PUBLICATION_MODE``
set, another middleware, or a Fast DDS other than 2.x (the profile is checked against 2.14, which
Jazzy's rclpy loads; Kilted's 3.x reads other variable names).
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
from collections.abc import Iterator, Mapping

__all__ = ["PROFILE_XML", "profile_refusal", "service_history_profile"]

_log = logging.getLogger(__name__)

PROFILE_XML = """<?xml version="1.0" encoding="UTF-8" ?>
<!-- uniros (multiros/ros/transport/rclpy/fastdds_profile.py): rmw_fastrtps' own defaults, except that
     service request readers free each request once taken (DYNAMIC history memory). -->
<dds>
  <profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
    <participant profile_name="uniros_participant" is_default_profile="true">
      <rtps>
        <builtin>
          <readerHistoryMemoryPolicy>PREALLOCATED_WITH_REALLOC</readerHistoryMemoryPolicy>
          <writerHistoryMemoryPolicy>PREALLOCATED_WITH_REALLOC</writerHistoryMemoryPolicy>
        </builtin>
      </rtps>
    </participant>
    <data_writer profile_name="uniros_writer" is_default_profile="true">
      <qos>
        <publishMode><kind>SYNCHRONOUS</kind></publishMode>
        <data_sharing><kind>OFF</kind></data_sharing>
      </qos>
      <historyMemoryPolicy>PREALLOCATED_WITH_REALLOC</historyMemoryPolicy>
    </data_writer>
    <data_reader profile_name="uniros_reader" is_default_profile="true">
      <qos>
        <data_sharing><kind>OFF</kind></data_sharing>
      </qos>
      <historyMemoryPolicy>PREALLOCATED_WITH_REALLOC</historyMemoryPolicy>
    </data_reader>
    <data_reader profile_name="service">
      <qos>
        <data_sharing><kind>OFF</kind></data_sharing>
      </qos>
      <historyMemoryPolicy>DYNAMIC</historyMemoryPolicy>
    </data_reader>
  </profiles>
</dds>
"""

_PROFILE_ENV = ("FASTRTPS_DEFAULT_PROFILES_FILE", "RMW_FASTRTPS_USE_QOS_FROM_XML")
_USER_SETTINGS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE", "RMW_FASTRTPS_USE_QOS_FROM_XML",
                  "RMW_FASTRTPS_PUBLICATION_MODE")
_USER_FILES = ("DEFAULT_FASTRTPS_PROFILES.xml", "DEFAULT_FASTDDS_PROFILES.xml")
_FAST_DDS_2 = "libfastrtps.so.2"  # Fast DDS 2.x's library (3.x: libfastdds.so.3)


def _loaded_libraries() -> str:
    try:
        with open("/proc/self/maps") as f:
            return f.read()
    except OSError:
        return ""


def profile_refusal(env: Mapping[str, str] | None = None, cwd: str | None = None,
                    libraries: str | None = None) -> str | None:
    """Why the profile does not apply here (a sentence), or None where it does. ``env``: this process's
    environment; ``cwd``: the working directory; ``libraries``: ``/proc/self/maps`` (rclpy loaded)."""
    env = os.environ if env is None else env
    for name in _USER_SETTINGS:
        if env.get(name, "").strip():
            return f"{name} is set: Fast DDS is configured by the user"
    for name in _USER_FILES:
        if os.path.isfile(os.path.join(cwd or os.getcwd(), name)):
            return f"{name} in the working directory configures Fast DDS"
    rmw = env.get("RMW_IMPLEMENTATION", "").strip()
    if rmw and rmw not in ("rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp"):
        return f"the middleware is {rmw}"
    if _FAST_DDS_2 not in (_loaded_libraries() if libraries is None else libraries):
        return "the loaded Fast DDS is not 2.x (the profile is checked against 2.x only)"
    return None


@contextlib.contextmanager
def service_history_profile() -> Iterator[bool]:
    """Within: the participant the process creates (with its context's first node) takes the profile;
    yields whether it applies. After: the file is gone and the environment as before."""
    why = profile_refusal()
    if why is not None:
        _log.debug("Fast DDS service histories left as rmw_fastrtps sets them: %s", why)
        yield False
        return
    fd, path = tempfile.mkstemp(prefix="uniros-fastdds-", suffix=".xml")
    saved = {name: os.environ.get(name) for name in _PROFILE_ENV}
    try:
        with os.fdopen(fd, "w") as f:
            f.write(PROFILE_XML)
        os.environ.update(FASTRTPS_DEFAULT_PROFILES_FILE=path, RMW_FASTRTPS_USE_QOS_FROM_XML="1")
        yield True
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        with contextlib.suppress(OSError):
            os.unlink(path)
