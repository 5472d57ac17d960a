"""The camera thread's rates and its slowdown warning (multiros.sim.camera_stream), without GL; the
rendering itself is tested in test_cameras.py."""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest

from multiros.sim.camera_stream import DEFAULT_CAMERA_RATE, CameraStream, _Camera


def _stream(pacing, warnings: list[str]) -> CameraStream:
    return CameraStream(hub=None, world=None, lock=None, pacing=pacing, warn=warnings.append)


def _slow_window(stream: CameraStream, cost: float = 0.04) -> float:
    camera = stream._cameras.setdefault("rx200/zed2_left", _Camera())
    camera.busy, camera.cost = 1.0, cost
    now = time.monotonic()
    stream._window = now - 2.5
    return now


def test_one_warning_with_the_measured_cost_when_cameras_slow_real_time():
    warnings: list[str] = []
    stream = _stream(lambda: (True, 1.0, 0.6), warnings)
    stream._check_pace(_slow_window(stream))
    assert len(warnings) == 1
    assert "40 ms a frame (rx200/zed2_left 40 ms" in warnings[0] and "real-time factor 0.60 of 1.00" in warnings[0]
    assert "camera_rate" in warnings[0] and "<update_rate>" in warnings[0]
    stream._check_pace(_slow_window(stream))
    assert len(warnings) == 1, "one warning, not one per window"


@pytest.mark.parametrize("pacing", [(True, 1.0, 0.95), (False, 1.0, None), (True, 0.0, 0.1), (True, 1.0, None)])
def test_no_warning_at_pace_paused_or_as_fast_as_possible(pacing):
    warnings: list[str] = []
    stream = _stream(lambda: pacing, warnings)
    stream._check_pace(_slow_window(stream))
    assert warnings == []


def test_rates_come_from_the_camera_its_sensor_or_the_default():
    stream = _stream(lambda: (False, 0.0, None), [])
    plain, sensor = SimpleNamespace(camera="a", rate=0.0), SimpleNamespace(camera="b", rate=30.0)
    assert stream.rate_of(plain) == DEFAULT_CAMERA_RATE and stream.rate_of(sensor) == 30.0
    stream.set_rate("b", 5.0)
    assert stream.rate_of(sensor) == 5.0
    stream.set_rate("b", None)
    assert stream.rate_of(sensor) == 30.0
    with pytest.raises(ValueError, match="camera 'a': rate must be a positive number"):
        stream.set_rate("a", 0.0)
    with pytest.raises(ValueError, match="camera_rate must be a positive number"):
        CameraStream(hub=None, world=None, lock=None, rate=float("nan"))
