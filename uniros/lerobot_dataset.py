"""LeRobot's v3.0 dataset format, written and read with pyarrow alone (no torch, LeRobot or pandas).

Why not LeRobot's own ``LeRobotDataset`` writer: LeRobot 0.4.4 (the newest on PyPI) pins ``torch<2.11``
and its dataset modules import ``torchvision`` at the top; the only torchvision for torch 2.13 on PyPI
is the CUDA build, whose ``_C.so`` needs ``libc10_cuda.so`` and so cannot be imported next to the CPU
torch these machines have (and it has no sdist to build). Its writer also costs ~1 ms a frame
(``datasets`` per episode), as much as the simulation's step. This module writes the same files, which
LeRobot's reader loads (``docs/datasets.md`` says how that is checked)::

    DIR/meta/info.json                          codebase_version v3.0, fps, features, paths, totals
    DIR/meta/stats.json                         per feature min/max/mean/std/count/q01..q99
    DIR/meta/tasks.parquet                      task_index, indexed by the task string (pandas layout)
    DIR/meta/episodes/chunk-000/file-000.parquet  one row per episode: length, tasks, data file, from/to
                                                  index, per-episode stats; uniros adds ``success`` and
                                                  ``final/<feature>`` (the observation after the last step)
    DIR/data/chunk-000/file-000.parquet         one row per frame: the features, timestamp, frame_index,
                                                episode_index, index, task_index
    DIR/videos/<feature>/chunk-000/file-000.mp4 a camera's frames (features of dtype ``video``), episode
                                                after episode; the episodes' rows say where
                                                (``videos/<feature>/from_timestamp``; :mod:`uniros.lerobot_video`)

A dataset is written under ``DIR.partial`` and renamed to ``DIR`` by :meth:`DatasetWriter.finalize`:
an interrupted recording leaves no half dataset behind. :func:`uniros.lerobot_dataset_reader.read_dataset`
reads one back.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from uniros.lerobot_video import (
    QUANTILES,
    VideoFileWriter,
    VideoFormatError,
    VideoSettings,
    image_stats,
)

__all__ = ["CODEBASE_VERSION", "DATA_PATH", "DatasetFormatError", "DatasetWriter", "pyarrow_module"]

CODEBASE_VERSION = "v3.0"
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
#: Files a chunk folder holds (info.json's ``chunks_size``) and a video file's size before the next one
#: begins (``video_files_size_in_mb``): LeRobot's defaults.
CHUNKS_SIZE = 1000
VIDEO_FILE_MB = 200
#: Bytes of decoded images :func:`read_dataset` holds at most (``images=True``).
MAX_IMAGE_BYTES = 8 << 30
EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
#: Bytes of ``info.json`` read at most.
MAX_INFO_BYTES = 1 << 20
#: Bytes of one parquet file read at most (the writer keeps the data in one file).
MAX_PARQUET_BYTES = 4 << 30
#: The frame columns LeRobot adds to every dataset.
INDEX_FEATURES: dict[str, dict[str, Any]] = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}
#: Frames buffered before they are written as one row group of the data file.
ROW_GROUP_FRAMES = 5000
_DTYPES = {"float32", "float64", "int64", "int32", "bool", "uint8"}
_IMAGE_NAMES = ["height", "width", "channels"]


class DatasetFormatError(ValueError):
    """A dataset that is not a readable LeRobot v3.0 dataset: the message names the file and the fault."""


def pyarrow_module() -> Any:
    """pyarrow with its parquet module loaded; a one-line error naming the extra where it is missing."""
    try:
        import pyarrow as pa
        import pyarrow.parquet  # noqa: F401 - pa.parquet
    except ImportError as exc:  # pragma: no cover - the extra is missing
        raise DatasetFormatError("LeRobot datasets need pyarrow: pip install 'uniros[datasets]'") from exc
    return pa


def _arrow_type(pa: Any, feature: dict[str, Any]) -> Any:
    """A feature's arrow column type: a scalar for shape [1], else a fixed-size list (LeRobot's layout)."""
    scalar = {"float32": pa.float32(), "float64": pa.float64(), "int64": pa.int64(), "int32": pa.int32(),
              "bool": pa.bool_(), "uint8": pa.uint8()}[feature["dtype"]]
    shape = list(feature["shape"])
    if shape == [1]:
        return scalar
    t = scalar
    for n in reversed(shape):
        t = pa.list_(t, int(n))
    return t


def _hf_type(feature: dict[str, Any]) -> dict[str, Any]:
    """The feature as Hugging Face ``datasets`` describes it in the parquet metadata."""
    value: dict[str, Any] = {"dtype": feature["dtype"], "_type": "Value"}
    if list(feature["shape"]) == [1]:
        return value
    for n in reversed(list(feature["shape"])):
        value = {"feature": value, "length": int(n), "_type": "List"}
    return value


def _episode_stats(cols: dict[str, np.ndarray],
                   features: dict[str, dict[str, Any]]) -> dict[str, dict[str, np.ndarray]]:
    """One episode's statistics of every feature (LeRobot's ``compute_episode_stats`` keys), over its frames:
    all features side by side in one matrix, so that each statistic is one numpy call (a frame's worth of
    Python per episode, not per feature)."""
    n = len(next(iter(cols.values())))
    parts = [cols[k].reshape(n, -1) for k in features]
    mat = np.concatenate([p.astype(np.float64) for p in parts], axis=1)
    lo, hi = mat.min(axis=0), mat.max(axis=0)
    mean, std = mat.mean(axis=0), mat.std(axis=0)
    quantiles = np.quantile(mat, QUANTILES, axis=0)
    out: dict[str, dict[str, np.ndarray]] = {}
    at = 0
    for (key, ft), part in zip(features.items(), parts, strict=True):
        cut = slice(at, at + part.shape[1])
        at += part.shape[1]
        dtype = np.dtype(ft["dtype"])
        st = {"min": lo[cut].astype(dtype), "max": hi[cut].astype(dtype), "mean": mean[cut], "std": std[cut],
              "count": np.array([n], np.int64)}
        for q, value in zip(QUANTILES, quantiles, strict=True):
            st[f"q{round(q * 100):02d}"] = value[cut]
        out[key] = st
    return out


def _aggregate(per_episode: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Episode statistics pooled (counts weight the means, variances and quantiles, as LeRobot's do)."""
    counts = np.array([int(s["count"][0]) for s in per_episode], np.float64)
    w = counts / counts.sum()
    mean = sum(wi * s["mean"] for wi, s in zip(w, per_episode, strict=True))
    var = sum(wi * (s["std"] ** 2 + (s["mean"] - mean) ** 2) for wi, s in zip(w, per_episode, strict=True))
    out = {"min": np.min([s["min"] for s in per_episode], axis=0),
           "max": np.max([s["max"] for s in per_episode], axis=0), "mean": mean, "std": np.sqrt(var),
           "count": np.array([int(counts.sum())], np.int64)}
    for key in per_episode[0]:
        if key.startswith("q"):
            out[key] = sum(wi * s[key] for wi, s in zip(w, per_episode, strict=True))
    return out


def _jsonable(value: np.ndarray) -> list[Any]:
    return np.asarray(value).tolist()  # type: ignore[no-any-return]


class DatasetWriter:
    """Writes episodes frame by frame into a new LeRobot v3.0 dataset (see the module docstring).

    Args:
        root: the dataset's folder; it must not exist (the writer fills ``root.partial`` and renames it).
        fps: frames per second (``info.json``'s ``fps``; timestamps are ``frame_index / fps``).
        features: ``{name: {"dtype", "shape", "names"}}`` of the recorded features (LeRobot's spelling);
            the index columns are added. A feature of dtype ``video`` (shape ``[height, width, 3]``, uint8 RGB
            frames) is written as the video ``videos/<name>/chunk-XXX/file-XXX.mp4``, not in the parquet file.
        robot_type: ``info.json``'s ``robot_type``.
        extra_info: more keys for ``info.json`` (uniros writes ``"uniros": {...}``: the env ID and spaces).
        video: how the videos are encoded (default: h264, crf 23, a key frame every 2 frames).
        video_file_mb: a video file's size (MB) after which the next episode begins a new file (LeRobot's 200).

    A video feature's frames are kept in memory until their episode is saved (an episode can still be
    dropped with :meth:`clear_episode`), then encoded: 1,000 frames of 640 x 480 hold 0.9 GB.
    """

    def __init__(self, root: Path | str, fps: int, features: dict[str, dict[str, Any]], *,
                 robot_type: str | None = None, extra_info: dict[str, Any] | None = None,
                 video: VideoSettings | None = None, video_file_mb: float = VIDEO_FILE_MB) -> None:
        self.pa = pyarrow_module()
        self.root = Path(root)
        if self.root.exists():
            raise DatasetFormatError(f"{self.root} exists: record into a new folder")
        if fps <= 0:
            raise DatasetFormatError(f"fps must be positive, got {fps}")
        for name, ft in features.items():
            video_shape = ft.get("dtype") == "video" and len(ft.get("shape", [])) == 3 and ft["shape"][2] == 3
            if (ft.get("dtype") not in _DTYPES and not video_shape) or not all(int(n) > 0 for n in ft.get("shape", [])):
                raise DatasetFormatError(f"feature {name!r}: unsupported dtype or shape {ft}")
        self.fps = int(fps)
        self.features = {k: {"dtype": v["dtype"], "shape": [int(n) for n in v["shape"]], "names": v.get("names")}
                         for k, v in features.items() if v["dtype"] != "video"}
        self.video_features: dict[str, dict[str, Any]] = {
            k: {"dtype": "video", "shape": [int(n) for n in v["shape"]], "names": _IMAGE_NAMES}
            for k, v in features.items() if v["dtype"] == "video"}
        for name, ft in self.video_features.items():
            if ft["shape"][0] % 2 or ft["shape"][1] % 2:
                raise DatasetFormatError(f"feature {name!r}: images of {ft['shape'][1]} x {ft['shape'][0]}: video "
                                         "needs an even width and height (e.g. --image-size 64x48)")
        self.all_features = {**self.features, **INDEX_FEATURES}
        self.robot_type, self.extra_info = robot_type, dict(extra_info or {})
        self.partial = self.root.with_name(self.root.name + ".partial")
        if self.partial.exists():
            shutil.rmtree(self.partial)
        (self.partial / "data" / "chunk-000").mkdir(parents=True)
        self.schema = self._schema()
        self._writer: Any = None
        self._frames: dict[str, list[np.ndarray]] = {k: [] for k in self.features}
        self._episodes: list[dict[str, Any]] = []
        self._stats: list[dict[str, dict[str, np.ndarray]]] = []
        self._tasks: dict[str, int] = {}
        self._total = 0
        self._pending: list[Any] = []  # episodes' tables not written yet (one row group per ROW_GROUP_FRAMES)
        self._pending_rows = 0
        self.video = video or VideoSettings()
        self._video_file_bytes = int(video_file_mb * (1 << 20))
        self._images: dict[str, list[np.ndarray]] = {k: [] for k in self.video_features}
        self._videos: dict[str, VideoFileWriter] = {}
        self._video_at: dict[str, tuple[int, int]] = {}  # the (chunk, file) each camera writes now
        self._video_info: dict[str, dict[str, Any]] = {}

    def _schema(self) -> Any:
        pa = self.pa
        hf = json.dumps({"info": {"features": {k: _hf_type(v) for k, v in self.all_features.items()}}})
        return pa.schema([pa.field(k, _arrow_type(pa, v)) for k, v in self.all_features.items()],
                         metadata={"huggingface": hf})

    @property
    def num_episodes(self) -> int:
        return len(self._episodes)

    def add_frame(self, frame: dict[str, Any]) -> None:
        """Buffer one frame (every feature, numpy-convertible to its dtype and shape); nothing is written
        until :meth:`save_episode`."""
        for key, buf in self._frames.items():
            buf.append(frame[key])
        for key, images in self._images.items():
            images.append(np.asarray(frame[key]))

    def clear_episode(self) -> None:
        """Drop the frames buffered since the last saved episode."""
        for buf in self._frames.values():
            buf.clear()
        for images in self._images.values():
            images.clear()

    def save_episode(self, task: str, *, success: bool | None = None,
                     final: dict[str, Any] | None = None) -> None:
        """Write the buffered frames as one episode of ``task``; ``final``: the observation features after the
        last step (kept in the episode's metadata, for replay buffers), ``success``: the episode's outcome."""
        pa = self.pa
        n = len(next(iter(self._frames.values()))) if self._frames else 0
        if n == 0:
            raise DatasetFormatError("an episode needs at least one frame")
        images = {key: self._episode_images(key, n) for key in self.video_features}  # checked before anything is kept
        ep = len(self._episodes)
        task_index = self._tasks.setdefault(task, len(self._tasks))
        cols: dict[str, np.ndarray] = {}
        for key, ft in self.features.items():
            arr = np.asarray(self._frames[key], dtype=ft["dtype"])
            if arr.shape[1:] != tuple(ft["shape"]) and arr.reshape(n, -1).shape[1:] != (math.prod(ft["shape"]),):
                raise DatasetFormatError(f"feature {key!r}: frames of shape {arr.shape[1:]}, declared {ft['shape']}")
            cols[key] = arr.reshape((n, *ft["shape"]))
        frame_index = np.arange(n, dtype=np.int64)
        cols["timestamp"] = (frame_index / self.fps).astype(np.float32)
        cols["frame_index"] = frame_index
        cols["episode_index"] = np.full(n, ep, np.int64)
        cols["index"] = np.arange(self._total, self._total + n, dtype=np.int64)
        cols["task_index"] = np.full(n, task_index, np.int64)
        arrays = []
        for key, ft in self.all_features.items():
            flat = cols[key].reshape(-1)
            arr = pa.array(flat, type=_arrow_type(pa, {"dtype": ft["dtype"], "shape": [1]}))
            for size in reversed(ft["shape"] if ft["shape"] != [1] else []):
                arr = pa.FixedSizeListArray.from_arrays(arr, int(size))
            arrays.append(arr)
        self._pending.append(pa.Table.from_arrays(arrays, schema=self.schema))
        self._pending_rows += n
        if self._pending_rows >= ROW_GROUP_FRAMES:
            self._flush()
        stats = _episode_stats(cols, self.all_features)
        row: dict[str, Any] = {"episode_index": ep, "tasks": [task], "length": n, "data/chunk_index": 0,
                               "data/file_index": 0, "dataset_from_index": self._total,
                               "dataset_to_index": self._total + n}
        for key, frames in images.items():
            row.update(self._write_video(key, frames))
            stats[key] = image_stats(frames)
        self._stats.append(stats)
        for key, st in stats.items():
            for name, value in st.items():
                row[f"stats/{key}/{name}"] = _jsonable(value)
        row["meta/episodes/chunk_index"], row["meta/episodes/file_index"] = 0, 0
        row["success"] = None if success is None else bool(success)
        for key, value in (final or {}).items():
            row[f"final/{key}"] = np.asarray(value, dtype=np.float64).reshape(-1).tolist()
        self._episodes.append(row)
        self._total += n
        self.clear_episode()

    def _episode_images(self, key: str, n: int) -> np.ndarray:
        shape = tuple(self.video_features[key]["shape"])
        images = self._images[key]
        if len(images) != n or any(im.shape != shape or im.dtype != np.uint8 for im in images):
            odd = next((im for im in images if im.shape != shape or im.dtype != np.uint8), None)
            raise DatasetFormatError(f"feature {key!r}: {len(images)} frames for {n} steps" if odd is None else
                                     f"feature {key!r}: an image of shape {odd.shape} ({odd.dtype}), declared "
                                     f"uint8 {list(shape)}")
        return np.stack(images)

    def _write_video(self, key: str, images: np.ndarray) -> dict[str, Any]:
        """Encode one episode's frames of the camera ``key`` (a new file when the current one is full); returns
        the episode's ``videos/<key>/...`` columns."""
        current = self._videos.get(key)
        if current is not None and current.size_bytes() >= self._video_file_bytes:
            self._close_video(key)
            chunk, file = self._video_at[key]
            self._video_at[key] = (chunk + 1, 0) if file + 1 >= CHUNKS_SIZE else (chunk, file + 1)
            current = None
        if current is None:
            chunk, file = self._video_at.setdefault(key, (0, 0))
            height, width = (int(n) for n in self.video_features[key]["shape"][:2])
            path = self.partial / VIDEO_PATH.format(video_key=key, chunk_index=chunk, file_index=file)
            try:
                current = self._videos[key] = VideoFileWriter(path, width, height, self.fps, self.video)
            except VideoFormatError as exc:
                raise DatasetFormatError(f"feature {key!r}: {exc}") from None
        start = current.frames
        current.write(images)
        chunk, file = self._video_at[key]
        return {f"videos/{key}/chunk_index": chunk, f"videos/{key}/file_index": file,
                f"videos/{key}/from_timestamp": start / self.fps,
                f"videos/{key}/to_timestamp": current.frames / self.fps}

    def _close_video(self, key: str) -> None:
        writer = self._videos.pop(key)
        writer.close()
        self._video_info.setdefault(key, writer.info())

    def _flush(self) -> None:
        """Write the episodes buffered since the last flush as one row group of the data file."""
        if not self._pending:
            return
        pa = self.pa
        if self._writer is None:
            self._writer = pa.parquet.ParquetWriter(str(self.partial / DATA_PATH.format(chunk_index=0, file_index=0)),
                                                    self.schema)
        self._writer.write_table(pa.concat_tables(self._pending))
        self._pending, self._pending_rows = [], 0

    def finalize(self) -> Path:
        """Write the metadata, close the data file and move the dataset to ``root``; returns ``root``."""
        pa = self.pa
        if not self._episodes:
            self.abort()
            raise DatasetFormatError("no episode was recorded: nothing written")
        self._flush()
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        for key in list(self._videos):
            self._close_video(key)
        meta = self.partial / "meta"
        (meta / "episodes" / "chunk-000").mkdir(parents=True)
        pa.parquet.write_table(pa.Table.from_pylist(self._episodes), str(self.partial / EPISODES_PATH))
        names = list(self._tasks)
        pandas_meta = {"index_columns": ["__index_level_0__"], "column_indexes": [], "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
             "metadata": None},
            {"name": None, "field_name": "__index_level_0__", "pandas_type": "unicode", "numpy_type": "object",
             "metadata": None}], "creator": {"library": "pyarrow", "version": pa.__version__},
            "pandas_version": "2.2.0"}
        tasks = pa.table({"task_index": pa.array([self._tasks[t] for t in names], pa.int64()),
                          "__index_level_0__": pa.array(names, pa.string())})
        tasks = tasks.replace_schema_metadata({"pandas": json.dumps(pandas_meta)})
        pa.parquet.write_table(tasks, str(meta / "tasks.parquet"))
        stats = {k: {n: _jsonable(v) for n, v in _aggregate([s[k] for s in self._stats]).items()}
                 for k in [*self.all_features, *self.video_features]}
        videos = {k: {**ft, "info": self._video_info[k]} for k, ft in self.video_features.items()}
        (meta / "stats.json").write_text(json.dumps(stats, indent=4))
        info = {"codebase_version": CODEBASE_VERSION, "robot_type": self.robot_type,
                "total_episodes": len(self._episodes), "total_frames": self._total, "total_tasks": len(self._tasks),
                "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": 100,
                "video_files_size_in_mb": max(1, round(self._video_file_bytes / (1 << 20))), "fps": self.fps,
                "splits": {"train": f"0:{len(self._episodes)}"}, "data_path": DATA_PATH,
                "video_path": VIDEO_PATH if videos else None, "features": {**videos, **self.all_features},
                **self.extra_info}
        (meta / "info.json").write_text(json.dumps(info, indent=4))
        self.partial.rename(self.root)
        return self.root

    def abort(self) -> None:
        """Drop everything written (an interrupted recording)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        for writer in self._videos.values():
            writer.abort()
        self._videos.clear()
        shutil.rmtree(self.partial, ignore_errors=True)
