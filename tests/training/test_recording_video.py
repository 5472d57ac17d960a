"""``uniros record --images``: a camera's frames written as the LeRobot v3.0 dataset's MP4 video (h264, crf 23),
read back by uniros (``read_dataset(images=True)``) close to what the env rendered, hostile videos refused in
one line, and (in ``.venv-lerobot``) loaded by LeRobot's own reader:
``.venv-lerobot/bin/python -m pytest tests/training/test_recording_video.py -p no:randomly -k lerobot``.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import json
import sys
import types
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("pyarrow")
pytest.importorskip("av")

from uniros.lerobot_dataset import DatasetFormatError, DatasetWriter
from uniros.lerobot_dataset_reader import read_dataset
from uniros.lerobot_video import VideoSettings, image_stats
from uniros.recording import main as record_main
from uniros.recording import record
from uniros.run_envs import make_env

ENV_ID = "RX200PushGoalSim-v0"
CAMERA = "observation.images.rgb"
WIDTH, HEIGHT, EPISODES = 64, 48, 2
#: Mean absolute error (of 255 levels) a decoded frame may have against the rendered one: h264 at crf 23
#: in yuv420p (colour at half resolution) measures ~3 on these 64 x 48 frames.
MAE_BOUND = 8.0


class _Frames(gym.Wrapper):  # type: ignore[type-arg]
    """Keeps every camera image the policy saw (the recorded frames)."""

    def __init__(self, env: Any) -> None:
        super().__init__(env)
        self.images: list[np.ndarray] = []

    def reset(self, **kwargs: Any) -> Any:
        obs, info = self.env.reset(**kwargs)
        self.images.append(obs["rgb"].copy())
        return obs, info

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if not (terminated or truncated):
            self.images.append(obs["rgb"].copy())
        return obs, reward, terminated, truncated, info


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    """2 scripted RX200 push episodes with a 64 x 48 camera, recorded with images, and the images seen."""
    out = tmp_path_factory.mktemp("rec") / "push_images"
    env = _Frames(make_env(ENV_ID, rgb_plus_normal_obs=True, image_width=WIDTH, image_height=HEIGHT))
    policy = env.unwrapped.task.scripted_policy()
    try:
        result = record(env, policy, EPISODES, out, env_id=ENV_ID, seed=3, progress=False, reset=policy.reset,
                        images=True)
    finally:
        env.close()
    assert result["frames"] == len(env.images)
    return out, np.stack(env.images)


def test_frames_read_back_close_to_the_rendered_ones(recorded: tuple[Path, np.ndarray]) -> None:
    out, seen = recorded
    ds = read_dataset(out, images=True)
    assert len(ds.episodes) == EPISODES
    images = np.concatenate([e.frames[CAMERA] for e in ds.episodes])
    assert images.shape == seen.shape == (len(seen), HEIGHT, WIDTH, 3) and images.dtype == np.uint8
    errors = np.abs(images.astype(np.int16) - seen).mean(axis=(1, 2, 3))
    assert errors.max() < MAE_BOUND, errors.max()
    assert seen.std() > 10  # the frames are pictures, not a blank that would match anything
    for ep in ds.episodes:
        assert len(ep.frames[CAMERA]) == len(ep) and "observation.images.rgb" not in ep.final
    # without images=True the reader does not touch the video
    assert CAMERA not in read_dataset(out).episodes[0].frames


def test_the_layout_is_lerobots(recorded: tuple[Path, np.ndarray]) -> None:
    import pyarrow.parquet as pq

    out, seen = recorded
    info = json.loads((out / "meta" / "info.json").read_text())
    feature = info["features"][CAMERA]
    assert feature["dtype"] == "video" and feature["shape"] == [HEIGHT, WIDTH, 3]
    assert feature["names"] == ["height", "width", "channels"]
    assert feature["info"] == {"video.height": HEIGHT, "video.width": WIDTH, "video.codec": "h264",
                               "video.pix_fmt": "yuv420p", "video.is_depth_map": False, "video.fps": info["fps"],
                               "video.channels": 3, "has_audio": False}
    assert info["video_path"] == "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    assert (out / "videos" / CAMERA / "chunk-000" / "file-000.mp4").is_file()
    assert CAMERA not in pq.read_schema(out / "data" / "chunk-000" / "file-000.parquet").names
    rows = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    at = 0.0
    for row in rows:  # episode after episode in one file, timestamps in seconds of that file
        assert row[f"videos/{CAMERA}/chunk_index"] == 0 and row[f"videos/{CAMERA}/file_index"] == 0
        assert row[f"videos/{CAMERA}/from_timestamp"] == pytest.approx(at)
        at += row["length"] / info["fps"]
        assert row[f"videos/{CAMERA}/to_timestamp"] == pytest.approx(at)
    stats = json.loads((out / "meta" / "stats.json").read_text())[CAMERA]
    assert np.asarray(stats["mean"]).shape == (3, 1, 1)
    np.testing.assert_allclose(np.asarray(stats["mean"]).ravel(), seen.reshape(-1, 3).mean(axis=0) / 255, atol=0.01)


def _gradient(n: int, height: int = 32, width: int = 48, shift: int = 0) -> np.ndarray:
    """``n`` smooth frames (a moving colour ramp) that h264 keeps within a few levels."""
    y, x = np.mgrid[0:height, 0:width]
    return np.stack([np.stack([np.minimum(x * 4 + 3 * (k + shift), 255), y * 6 + k, np.full_like(x, 40 + 2 * k)],
                              axis=-1).astype(np.uint8) for k in range(n)])


def test_image_stats_are_numpys() -> None:
    """The histogram statistics equal numpy's over the sampled pixels (LeRobot's layout: 3 x 1 x 1, in [0, 1])."""
    frames = np.random.default_rng(0).integers(0, 256, (130, 12, 16, 3), dtype=np.uint8)
    frames[:, :, :, 2] //= 7  # a channel of few levels: the quantiles fall between equal values
    stats = image_stats(frames)
    assert int(stats["count"][0]) == 100
    pixels = frames[np.round(np.linspace(0, 129, 100)).astype(int)].reshape(-1, 3) / 255.0
    expected = {"min": pixels.min(0), "max": pixels.max(0), "mean": pixels.mean(0), "std": pixels.std(0),
                **{f"q{round(q * 100):02d}": np.quantile(pixels, q, axis=0) for q in (0.01, 0.1, 0.5, 0.9, 0.99)}}
    for key, value in expected.items():
        assert stats[key].shape == (3, 1, 1)
        np.testing.assert_allclose(stats[key].ravel(), value, atol=1e-12, err_msg=key)


def _write(root: Path, lengths: tuple[int, ...] = (6, 9), **kwargs: Any) -> list[np.ndarray]:
    feats = {"observation.state": {"dtype": "float32", "shape": [2]},
             CAMERA: {"dtype": "video", "shape": [32, 48, 3]}}
    writer = DatasetWriter(root, 10, feats, **kwargs)
    episodes = []
    for e, n in enumerate(lengths):
        frames = _gradient(n, shift=10 * e)
        for k in range(n):
            writer.add_frame({"observation.state": np.full(2, k, np.float32), CAMERA: frames[k]})
        writer.save_episode("t")
        episodes.append(frames)
    writer.finalize()
    return episodes


def test_a_full_video_file_goes_on_in_the_next(tmp_path: Path) -> None:
    written = _write(tmp_path / "ds", (5, 7, 4), video_file_mb=1e-6, video=VideoSettings(crf=0))
    files = sorted((tmp_path / "ds" / "videos" / CAMERA / "chunk-000").iterdir())
    assert [f.name for f in files] == ["file-000.mp4", "file-001.mp4", "file-002.mp4"]
    for ep, frames in zip(read_dataset(tmp_path / "ds", images=True).episodes, written, strict=True):
        assert np.abs(ep.frames[CAMERA].astype(np.int16) - frames).mean() < 2.0


def test_a_dropped_episode_and_an_interrupted_recording_leave_no_frames(tmp_path: Path) -> None:
    feats = {"observation.state": {"dtype": "float32", "shape": [2]}, CAMERA: {"dtype": "video", "shape": [32, 48, 3]}}
    frames = _gradient(4)
    writer = DatasetWriter(tmp_path / "ds", 10, feats)
    for k in range(3):
        writer.add_frame({"observation.state": np.zeros(2), CAMERA: frames[k]})
    writer.clear_episode()  # dropped: its images with its state
    for k in range(4):
        writer.add_frame({"observation.state": np.zeros(2), CAMERA: frames[k]})
    writer.save_episode("t")
    writer.add_frame({"observation.state": np.zeros(2), CAMERA: frames[0][:16]})
    with pytest.raises(DatasetFormatError, match="an image of shape"):
        writer.save_episode("t")
    writer.abort()  # an open video file, then Ctrl-C: nothing left
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fault, expected", [
    ("garbage", "not a readable video"),
    ("missing", "file-000.mp4: missing"),
    ("size", "info.json says 40 x 32"),
    ("short", "frames, its episodes have 15"),
    ("timestamps", "is not its 9 frames at 10 fps"),
    ("outside", "lies outside the dataset"),
    ("huge", "uniros reads RGB frames of 8 to 8192 pixels"),
])
def test_bad_videos_are_refused_in_one_line(tmp_path: Path, fault: str, expected: str) -> None:
    import pyarrow.parquet as pq

    root = tmp_path / "ds"
    _write(root)
    video = root / "videos" / CAMERA / "chunk-000" / "file-000.mp4"
    info_path = root / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    episodes = root / "meta" / "episodes" / "chunk-000" / "file-000.parquet"
    if fault == "garbage":
        video.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 8)
    elif fault == "missing":
        video.unlink()
    elif fault in ("size", "huge", "outside"):
        if fault == "outside":
            info["video_path"] = "../../{video_key}/file-{file_index:03d}.mp4"
        else:
            info["features"][CAMERA]["shape"] = [32, 40, 3] if fault == "size" else [100_000, 48, 3]
        info_path.write_text(json.dumps(info))
    elif fault == "short":
        short = tmp_path / "short"
        _write(short, (6, 5))
        video.write_bytes((short / "videos" / CAMERA / "chunk-000" / "file-000.mp4").read_bytes())
    elif fault == "timestamps":
        table = pq.read_table(episodes)
        column = table.column_names.index(f"videos/{CAMERA}/to_timestamp")
        import pyarrow as pa

        table = table.set_column(column, f"videos/{CAMERA}/to_timestamp", pa.array([0.6, 1.2]))
        pq.write_table(table, episodes)
    assert len(read_dataset(root).episodes) == 2  # the state frames read without images=True
    with pytest.raises(DatasetFormatError) as exc:
        read_dataset(root, images=True)
    message = str(exc.value)
    assert expected in message and "\n" not in message, message


def test_cli_images_and_its_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ds"
    assert record_main([ENV_ID, "--policy", "scripted", "--episodes", "1", "--output", str(out), "--images",
                        "--image-size", "32x24", "--no-progress"]) == 0
    ds = read_dataset(out, images=True)
    assert ds.episodes[0].frames[CAMERA].shape == (len(ds.episodes[0]), 24, 32, 3)
    assert ds.info["uniros"]["observation_keys"][CAMERA] == "rgb"
    for argv, message in (
            (["--images", "--image-size", "33x24"], "even width and height"),
            (["--image-size", "32x24"], "give --images too"),
            (["--images", "--image-size", "big"], "WIDTHxHEIGHT"),
            (["--images", "--video-codec", "mjpeg"], "one of h264, hevc, libsvtav1")):
        capsys.readouterr()
        assert record_main([ENV_ID, "--policy", "scripted", "--episodes", "1", "--output", str(tmp_path / "x"),
                            "--no-progress", *argv]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "x").exists() and not (tmp_path / "x.partial").exists()


# -- LeRobot's own reader (in .venv-lerobot) ---------------------------------------------------------
def _torchvision_stand_in() -> None:
    """LeRobot decodes video with torchcodec or with torchvision's ``VideoReader`` (``video_backend="pyav"``).
    Neither imports in ``.venv-lerobot`` (torchcodec is not installed; torchvision for torch 2.13 is the CUDA
    build): a stand-in ``torchvision`` gives LeRobot's ``decode_video_frames_torchvision`` a ``VideoReader``
    over PyAV with torchvision's interface (frames as ``{"data": C x H x W uint8, "pts": seconds}``), so that
    LeRobot's own code picks the episode's file, shifts the timestamps and matches the frames."""
    import av
    import torch

    class VideoReader:
        def __init__(self, path: str, stream: str) -> None:
            self.container = av.open(path)
            self._from = 0.0

        def seek(self, ts: float, keyframes_only: bool = False) -> VideoReader:
            self._from = ts
            return self

        def __iter__(self) -> Any:
            for frame in self.container.decode(video=0):
                if frame.time >= self._from - 0.5:  # a key frame before, as torchvision's seek lands
                    yield {"data": torch.from_numpy(frame.to_ndarray(format="rgb24")).permute(2, 0, 1),
                           "pts": float(frame.time)}

    stand_in = types.ModuleType("torchvision")
    stand_in.__spec__ = importlib.machinery.ModuleSpec("torchvision", None)
    transforms = types.ModuleType("torchvision.transforms")
    transforms.__spec__ = importlib.machinery.ModuleSpec("torchvision.transforms", None)
    io = types.ModuleType("torchvision.io")
    io.VideoReader = VideoReader  # type: ignore[attr-defined]
    stand_in.transforms, stand_in.io = transforms, io  # type: ignore[attr-defined]
    stand_in.set_video_backend = lambda backend: None  # type: ignore[attr-defined]
    for name in [n for n in sys.modules if n == "torchvision" or n.startswith("torchvision.")]:
        del sys.modules[name]
    sys.modules.update({"torchvision": stand_in, "torchvision.transforms": transforms, "torchvision.io": io})


def test_lerobot_reads_the_video_frames(recorded: tuple[Path, np.ndarray]) -> None:
    # not importorskip("lerobot"): tests/lerobot/ is a namespace package "lerobot" on pytest's path
    if importlib.util.find_spec("lerobot") is None or importlib.util.find_spec("lerobot.datasets") is None:
        pytest.skip("LeRobot is not installed here (it runs in .venv-lerobot: docs/datasets.md)")
    try:
        import torchvision  # noqa: F401
    except (ImportError, RuntimeError):
        _torchvision_stand_in()
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    out, seen = recorded
    ds = LeRobotDataset("uniros/test_images", root=out, video_backend="pyav")
    assert ds.num_episodes == EPISODES and len(ds) == len(seen)
    assert ds.meta.video_keys == [CAMERA] and ds.meta.camera_keys == [CAMERA]
    mine = np.concatenate([e.frames[CAMERA] for e in read_dataset(out, images=True).episodes])
    for i in range(len(ds)):
        image = ds[i][CAMERA]  # C x H x W float in [0, 1]
        assert tuple(image.shape) == (3, HEIGHT, WIDTH)
        theirs = np.round(image.numpy().transpose(1, 2, 0) * 255).astype(np.int16)
        np.testing.assert_array_equal(theirs, mine[i])  # the same decoded frame: the same timestamps
        assert np.abs(theirs - seen[i]).mean() < MAE_BOUND
