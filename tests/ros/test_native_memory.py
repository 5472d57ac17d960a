"""A node process's native memory: glibc's malloc in one arena, given back after large requests
(``multiros/ros/native_memory.py``), and the Fast DDS profile whose service histories free each request
(``multiros/ros/transport/rclpy/fastdds_profile.py``; the node over real rclpy: tests/ros2_rclpy)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
import time
import xml.etree.ElementTree as ET

import pytest

from multiros.ros import native_memory
from multiros.ros.native_memory import _glibc, _Trimmer
from multiros.ros.transport.rclpy import fastdds_profile
from multiros.ros.transport.rclpy.fastdds_profile import PROFILE_XML, profile_refusal, service_history_profile

glibc_only = pytest.mark.skipif(_glibc() is None, reason="glibc's malloc only")


def _trims_counted() -> tuple[_Trimmer, list[float], threading.Event]:
    times: list[float] = []
    done = threading.Event()

    def fake_trim() -> None:
        times.append(time.monotonic())
        done.set()

    return _Trimmer(fake_trim, quiet=0.1, longest=0.6), times, done


def test_a_burst_of_large_requests_is_trimmed_once_after_it_stops() -> None:
    trimmer, times, done = _trims_counted()
    start = time.monotonic()
    for _ in range(5):
        trimmer.note()
    assert done.wait(5.0)
    assert len(times) == 1 and times[0] - start >= 0.1
    done.clear()
    trimmer.note()  # a later one: trimmed again
    assert done.wait(5.0) and len(times) == 2


def test_an_endless_stream_of_large_requests_is_trimmed_now_and_then() -> None:
    trimmer, times, done = _trims_counted()
    end = time.monotonic() + 1.5
    while time.monotonic() < end:  # a note every 20 ms: never quiet for 0.1 s
        trimmer.note()
        done.wait(0.02)
    assert len(times) >= 2  # at least every 0.6 s


def _run(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "MALLOC_ARENA_MAX": ""})
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


_ARENAS = """
    import ctypes, re, tempfile, threading
    from multiros.ros import native_memory
    if {configure}:
        assert native_memory.configure_node_process()
    def work():
        for _ in range(200):
            bytes(bytearray(4000))
    threads = [threading.Thread(target=work) for _ in range(6)]
    for t in threads: t.start()
    for t in threads: t.join()
    libc = ctypes.CDLL(None)
    libc.fopen.restype, libc.fopen.argtypes = ctypes.c_void_p, [ctypes.c_char_p, ctypes.c_char_p]
    libc.malloc_info.argtypes, libc.fclose.argtypes = [ctypes.c_int, ctypes.c_void_p], [ctypes.c_void_p]
    with tempfile.NamedTemporaryFile(suffix=".xml") as out:
        f = libc.fopen(out.name.encode(), b"w")
        libc.malloc_info(0, f)
        libc.fclose(f)
        print(len(re.findall("<heap nr=", open(out.name).read())))
"""


@glibc_only
def test_a_node_process_allocates_in_one_arena() -> None:
    """Six threads allocating: one arena in a configured process, one per thread otherwise."""
    assert _run(_ARENAS.format(configure=True)) == "1"
    assert int(_run(_ARENAS.format(configure=False))) > 1


_GIVE_BACK = """
    import time
    from multiros.ros import native_memory
    if {configure}:
        native_memory.configure_node_process()
    def rss():
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:")) / 1024
    buffers = [bytearray(100_000) for _ in range(600)]  # 60 MB in 100 KB buffers (under the mmap threshold)
    base = rss()
    del buffers[::2]  # 30 MB freed, each buffer between two live ones: glibc keeps them
    native_memory.release_soon()
    deadline = time.monotonic() + {wait}
    while rss() > base - 20 and time.monotonic() < deadline:
        time.sleep(0.05)
    print(round(base - rss()))
"""


@glibc_only
def test_freed_memory_is_given_back_after_large_requests() -> None:
    assert int(_run(_GIVE_BACK.format(configure=True, wait=5.0))) >= 20
    # elsewhere release_soon() does nothing: three times the quiet time a trim waits, and still kept
    assert int(_run(_GIVE_BACK.format(configure=False, wait=3 * native_memory.QUIET_SEC))) < 5


def test_the_fast_dds_profile_restates_rmw_s_defaults_but_for_service_requests() -> None:
    root = ET.fromstring(PROFILE_XML)
    ns = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    policies = {(e.tag.split("}")[1], e.get("profile_name")): e.findtext("p:historyMemoryPolicy", namespaces=ns)
                for e in root.find("p:profiles", ns)}
    assert policies.pop(("data_reader", "service")) == "DYNAMIC"
    assert set(policies.values()) - {None} == {"PREALLOCATED_WITH_REALLOC"}
    assert root.findtext(".//p:publishMode/p:kind", namespaces=ns) == "SYNCHRONOUS"  # rmw's default since Humble
    builtin = root.find(".//p:participant/p:rtps/p:builtin", ns)
    assert [e.text for e in builtin] == ["PREALLOCATED_WITH_REALLOC"] * 2


FAST_DDS_2 = "7f00-7f01 r-xp 0 08:01 1 /opt/ros/lib/libfastrtps.so.2.14.5\n"


@pytest.mark.parametrize("setting", ["FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE",
                                     "RMW_FASTRTPS_USE_QOS_FROM_XML", "RMW_FASTRTPS_PUBLICATION_MODE"])
def test_the_profile_steps_aside_for_the_user_s_fast_dds_settings(setting, tmp_path) -> None:
    assert profile_refusal({}, str(tmp_path), FAST_DDS_2) is None
    assert setting in profile_refusal({setting: "x"}, str(tmp_path), FAST_DDS_2)
    (tmp_path / "DEFAULT_FASTRTPS_PROFILES.xml").write_text("<dds/>")
    assert "working directory" in profile_refusal({}, str(tmp_path), FAST_DDS_2)


def test_the_profile_applies_to_fast_dds_2_only(tmp_path) -> None:
    assert "rmw_cyclonedds_cpp" in profile_refusal({"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}, str(tmp_path),
                                                   FAST_DDS_2)
    assert profile_refusal({"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}, str(tmp_path), FAST_DDS_2) is None
    assert "not 2.x" in profile_refusal({}, str(tmp_path), "/opt/ros/lib/libfastdds.so.3.2.2\n")


def test_the_profile_holds_while_the_participant_is_created_and_leaves_nothing(monkeypatch, tmp_path) -> None:
    for name in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE", "RMW_FASTRTPS_USE_QOS_FROM_XML",
                 "RMW_FASTRTPS_PUBLICATION_MODE", "RMW_IMPLEMENTATION"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(fastdds_profile, "_loaded_libraries", lambda: FAST_DDS_2)
    with service_history_profile() as applied:
        assert applied and os.environ["RMW_FASTRTPS_USE_QOS_FROM_XML"] == "1"
        path = os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"]
        with open(path) as f:
            assert f.read() == PROFILE_XML
    assert not os.path.exists(path)
    assert "FASTRTPS_DEFAULT_PROFILES_FILE" not in os.environ and "RMW_FASTRTPS_USE_QOS_FROM_XML" not in os.environ
    monkeypatch.setattr(fastdds_profile, "_loaded_libraries", lambda: "")
    with service_history_profile() as applied:
        assert not applied and "FASTRTPS_DEFAULT_PROFILES_FILE" not in os.environ


def test_release_soon_does_nothing_in_a_process_that_did_not_ask() -> None:
    if native_memory._trimmer:  # configured by another test of this process: nothing to check here
        pytest.skip("this process configured itself as a node process")
    native_memory.release_soon()
    assert not native_memory._trimmer
