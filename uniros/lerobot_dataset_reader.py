"""LeRobot v3.0 datasets read back into numpy (:mod:`uniros.lerobot_dataset` writes them).

:func:`read_dataset` checks everything a file may lie about: ``info.json``'s version and features, every
file's size before it is read, shapes and counts against ``info.json`` and the episodes' rows, decoded
images against :data:`~uniros.lerobot_dataset.MAX_IMAGE_BYTES`; a dataset that fails is one
:class:`~uniros.lerobot_dataset.DatasetFormatError` line naming the file.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from multiros.excerpt import MAX_VALUE_QUOTE, excerpt, quote
from uniros.lerobot_dataset import (
    CODEBASE_VERSION,
    DATA_PATH,
    MAX_IMAGE_BYTES,
    MAX_INFO_BYTES,
    MAX_PARQUET_BYTES,
    DatasetFormatError,
    pyarrow_module,
)
from uniros.lerobot_video import VideoFormatError, decode_video

__all__ = ["RecordedDataset", "RecordedEpisode", "read_dataset", "read_info"]


@dataclass
class RecordedEpisode:
    """One episode read back: ``frames[feature]`` has a row per frame; ``final`` the observation features
    after the last step (uniros datasets), ``success`` the recorded outcome (``None``: not recorded)."""

    index: int
    task: str
    frames: dict[str, np.ndarray]
    success: bool | None = None
    final: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.frames["index"])


@dataclass
class RecordedDataset:
    """A dataset read by :func:`read_dataset`: ``info`` is ``meta/info.json``."""

    root: Path
    info: dict[str, Any]
    episodes: list[RecordedEpisode]

    @property
    def features(self) -> dict[str, dict[str, Any]]:
        return dict(self.info["features"])


def read_info(root: Path) -> dict[str, Any]:
    """A dataset's ``meta/info.json``, checked (DatasetFormatError otherwise)."""
    return _read_info(Path(root))


def _read_info(root: Path) -> dict[str, Any]:
    path = root / "meta" / "info.json"
    if not root.is_dir():
        raise DatasetFormatError(f"{root}: no such dataset folder")
    if not path.is_file():
        raise DatasetFormatError(f"{root}: not a LeRobot dataset (no meta/info.json)")
    if path.stat().st_size > MAX_INFO_BYTES:
        raise DatasetFormatError(f"{path}: larger than {MAX_INFO_BYTES} bytes")
    try:
        info = json.loads(path.read_bytes())
    except (ValueError, UnicodeDecodeError) as exc:
        raise DatasetFormatError(f"{path}: not JSON ({exc})") from None
    if not isinstance(info, dict):
        raise DatasetFormatError(f"{path}: not a JSON object")
    if info.get("codebase_version") != CODEBASE_VERSION:
        raise DatasetFormatError(f"{path}: codebase_version {quote(info.get('codebase_version'))}, uniros reads "
                                 f"{CODEBASE_VERSION} (convert older datasets with LeRobot)")
    feats = info.get("features")
    if not isinstance(feats, dict) or not all(
            isinstance(v, dict) and isinstance(v.get("shape"), list)
            and all(isinstance(n, int) and n > 0 for n in v["shape"]) for v in feats.values()):
        raise DatasetFormatError(f"{path}: features must map names to {{dtype, shape}}")
    for key in ("total_episodes", "total_frames", "fps"):
        if not isinstance(info.get(key), int) or info[key] < 0:
            raise DatasetFormatError(f"{path}: {key} must be a non-negative integer, got {quote(info.get(key))}")
    return info


def _read_parquet(path: Path) -> Any:
    pa = pyarrow_module()
    if not path.is_file():
        raise DatasetFormatError(f"{path}: missing")
    if path.stat().st_size > MAX_PARQUET_BYTES:
        raise DatasetFormatError(f"{path}: larger than {MAX_PARQUET_BYTES} bytes")
    try:
        return pa.parquet.read_table(str(path))
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise DatasetFormatError(f"{path}: not a readable parquet file ({str(exc).splitlines()[0][:200]})") from None


def _column(table: Any, name: str, feature: dict[str, Any], where: Path) -> np.ndarray:
    if name not in table.column_names:
        raise DatasetFormatError(f"{where}: no column {quote(name)} (info.json lists it)")
    col = table.column(name).combine_chunks()
    shape = [int(n) for n in feature["shape"]]
    try:
        while hasattr(col, "flatten") and col.type.num_fields:  # a (fixed-size) list column
            col = col.flatten()
        values = col.to_numpy(zero_copy_only=False)
        return np.asarray(values).reshape((table.num_rows, *([] if shape == [1] else shape)))
    except (ValueError, TypeError) as exc:
        raise DatasetFormatError(f"{where}: column {quote(name)} does not hold {table.num_rows} x {shape} values "
                                 f"({exc})") from None


def _video_features(root: Path, info: dict[str, Any]) -> dict[str, tuple[int, int]]:
    """``{feature: (height, width)}`` of the dataset's video features, checked."""
    out: dict[str, tuple[int, int]] = {}
    for key, ft in info["features"].items():
        if ft.get("dtype") != "video":
            continue
        shape = ft["shape"]
        if ft.get("names") in (["channels", "height", "width"], ["channel", "height", "width"]):
            shape = [*shape[1:], shape[0]]
        if len(shape) != 3 or shape[2] != 3 or not all(8 <= n <= 8192 for n in shape[:2]):
            raise DatasetFormatError(f"{root}: video feature {quote(key)} of shape {ft['shape']}: uniros reads RGB "
                                     "frames of 8 to 8192 pixels a side")
        out[key] = (int(shape[0]), int(shape[1]))
    if out and not isinstance(info.get("video_path"), str):
        raise DatasetFormatError(f"{root}: info.json has video features but no video_path")
    return out


def _read_videos(root: Path, info: dict[str, Any], episodes: list[RecordedEpisode],
                 rows: list[dict[str, Any]]) -> None:
    """Decode every video feature's frames into its episodes' ``frames`` (``n x H x W x 3`` uint8)."""
    sizes = _video_features(root, info)
    fps = int(info["fps"])
    total = sum(len(e) for e in episodes) * sum(h * w * 3 for h, w in sizes.values())
    if total > MAX_IMAGE_BYTES:
        raise DatasetFormatError(f"{root}: its images take {total} bytes decoded, more than the {MAX_IMAGE_BYTES} "
                                 "read at most")
    base = root.resolve()
    for key, (height, width) in sizes.items():
        spans: dict[tuple[int, int], list[tuple[RecordedEpisode, int]]] = {}
        for ep, row in zip(episodes, rows, strict=True):
            try:
                at = (int(row[f"videos/{key}/chunk_index"]), int(row[f"videos/{key}/file_index"]))
                start, stop = float(row[f"videos/{key}/from_timestamp"]), float(row[f"videos/{key}/to_timestamp"])
            except (KeyError, TypeError, ValueError):
                raise DatasetFormatError(f"{root}: episode {ep.index} has no videos/{key}/ columns") from None
            first = round(start * fps)
            if (not all(0 <= k < 10_000 for k in at) or not 0 <= first <= 10_000_000 or abs(start * fps - first) > 0.01
                    or abs((stop - start) * fps - len(ep)) > 0.01):
                raise DatasetFormatError(f"{root}: episode {ep.index}: videos/{key} from {start} to {stop} s is not "
                                         f"its {len(ep)} frames at {fps} fps")
            spans.setdefault(at, []).append((ep, first))
        for (chunk, file), eps in spans.items():
            try:
                path = root / str(info["video_path"]).format(video_key=key, chunk_index=chunk, file_index=file)
            except (KeyError, IndexError, ValueError):
                raise DatasetFormatError(f"{root}: video_path {quote(info['video_path'])} is not a path "
                                         "template") from None
            if not path.resolve().is_relative_to(base):
                raise DatasetFormatError(f"{root}: video {path} lies outside the dataset")
            count = max(first + len(ep) for ep, first in eps)
            if count * height * width * 3 > MAX_IMAGE_BYTES:
                raise DatasetFormatError(f"{path}: {count} frames, more than the images read at most")
            try:
                images = decode_video(path, width=width, height=height, fps=fps, max_frames=count)
            except VideoFormatError as exc:
                raise DatasetFormatError(str(exc)) from None
            for ep, first in eps:
                ep.frames[key] = images[first:first + len(ep)]


def read_dataset(root: Path | str, *, max_frames: int = 10_000_000, images: bool = False) -> RecordedDataset:
    """Read a LeRobot v3.0 dataset's frames into numpy; raises :class:`DatasetFormatError`.

    ``images=True`` also decodes its videos: each video feature's frames (``n x height x width x 3`` uint8
    RGB) in its episodes' ``frames`` (PyAV; the files' sizes, frame sizes and counts checked against
    ``info.json`` and the episodes' rows, at most :data:`MAX_IMAGE_BYTES` decoded).
    """
    root = Path(root)
    info = _read_info(root)
    if info["total_frames"] > max_frames:
        raise DatasetFormatError(f"{root}: {info['total_frames']} frames, more than the {max_frames} read at most")
    feats = {k: v for k, v in info["features"].items() if v.get("dtype") not in ("video", "image")}
    ep_files = sorted((root / "meta" / "episodes").glob("chunk-*/file-*.parquet"))
    if not ep_files:
        raise DatasetFormatError(f"{root}: no meta/episodes/chunk-*/file-*.parquet")
    ep_rows: list[dict[str, Any]] = []
    for f in ep_files:
        ep_rows.extend(_read_parquet(f).to_pylist())
    if len(ep_rows) != info["total_episodes"]:
        raise DatasetFormatError(f"{root}: {len(ep_rows)} episode rows, info.json says {info['total_episodes']}")
    data_path = info.get("data_path", DATA_PATH)
    columns: dict[tuple[int, int], dict[str, np.ndarray]] = {}
    episodes: list[RecordedEpisode] = []
    try:
        ep_rows.sort(key=lambda r: int(r.get("episode_index", -1)))
    except (TypeError, ValueError):
        raise DatasetFormatError(f"{root}: an episode row's episode_index is not an integer") from None
    for row in ep_rows:
        try:
            key = (int(row["data/chunk_index"]), int(row["data/file_index"]))
            start, stop = int(row["dataset_from_index"]), int(row["dataset_to_index"])
            index, tasks = int(row["episode_index"]), list(row["tasks"])
        except (KeyError, TypeError, ValueError) as exc:
            raise DatasetFormatError(f"{root}: an episode row lacks {excerpt(str(exc), MAX_VALUE_QUOTE)}") from None
        if key not in columns:
            if not all(0 <= k < 10_000 for k in key):
                raise DatasetFormatError(f"{root}: episode {index}: data file index {key} out of range")
            path = root / str(data_path).format(chunk_index=key[0], file_index=key[1])
            table = _read_parquet(path)
            columns[key] = {name: _column(table, name, ft, path) for name, ft in feats.items()}
        cols = columns[key]
        first = cols["index"]
        at = np.flatnonzero((first >= start) & (first < stop))
        if stop <= start or len(at) != stop - start or not np.all(cols["episode_index"][at] == index):
            raise DatasetFormatError(f"{root}: episode {index}'s frames {start}:{stop} are not in its data file")
        final = {k[len("final/"):]: np.asarray(v, np.float64) for k, v in row.items()
                 if k.startswith("final/") and v is not None}
        success = row.get("success")
        episodes.append(RecordedEpisode(index=index, task=str(tasks[0]) if tasks else "",
                                        frames={k: v[at] for k, v in cols.items()},
                                        success=None if success is None else bool(success), final=final))
    if images:
        _read_videos(root, info, episodes, ep_rows)
    return RecordedDataset(root=root, info=info, episodes=episodes)
