"""Camera frames as the MP4 video of a LeRobot v3.0 dataset, encoded and decoded with PyAV (``av``).

LeRobot keeps an image feature (dtype ``video``) out of the parquet files: its frames are the video
``videos/<feature>/chunk-XXX/file-XXX.mp4``, episode after episode in one file until the file reaches
``video_files_size_in_mb``, and each episode's row says where its frames are (``videos/<feature>/
from_timestamp`` .. ``to_timestamp``, in seconds of that file). This module is that file's two ends:

* :class:`VideoFileWriter` encodes frames into one such file as LeRobot 0.4.4's ``encode_video_frames``
  does (PyAV, ``yuv420p``, a key frame every ``g=2`` frames, ``crf``; frame ``k`` of the file at
  ``pts = k / fps``), without LeRobot's PNG round trip, and :meth:`VideoFileWriter.info` is the
  feature's ``info`` block as LeRobot's ``get_video_info`` writes it.
* :func:`decode_video` reads one back, bounded: the file's size, the stream's width and height and the
  number of frames are checked before or while decoding, and a file that is not what it claims is
  refused with a one-line :class:`VideoFormatError`.

:func:`image_stats` is LeRobot's statistics of an image feature (per channel, in [0, 1], over at most
100 evenly spaced frames of an episode), which its normalisation reads from ``stats.json``.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["MAX_VIDEO_BYTES", "VIDEO_CODECS", "VideoFileWriter", "VideoFormatError", "VideoSettings", "decode_video",
           "image_stats"]

#: Bytes of one video file read at most.
MAX_VIDEO_BYTES = 4 << 30
#: Encoders a dataset may be written with (LeRobot's software choices): h264 (the default here: fast to
#: encode, decoded everywhere), hevc, libsvtav1 (LeRobot's default: smaller files, ~6x slower to encode).
VIDEO_CODECS = ("h264", "hevc", "libsvtav1")
#: The quantiles LeRobot's stats hold (q01 ... q99), of state features and images alike.
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)


class VideoFormatError(ValueError):
    """A video that cannot be written or read as the dataset says: the message is one line."""


def _av() -> Any:
    try:
        import av
    except ImportError as exc:  # pragma: no cover - the extra is missing
        raise VideoFormatError("recording images as video needs PyAV: pip install 'uniros[datasets]' (av)") from exc
    return av


@dataclass(frozen=True)
class VideoSettings:
    """How a dataset's videos are encoded: ``codec`` one of :data:`VIDEO_CODECS`, ``crf`` its quality
    (0 best .. 51; LeRobot's default is 30, x264's 23), ``gop`` frames between key frames (LeRobot: 2, so
    that a reader seeks to any frame cheaply), ``pix_fmt`` ``yuv420p`` (what every decoder reads),
    ``preset`` the h264/hevc encoder's speed (files as small as with x264's "medium" at these sizes)."""

    codec: str = "h264"
    crf: int = 23
    gop: int = 2
    pix_fmt: str = "yuv420p"
    preset: str = "veryfast"

    def __post_init__(self) -> None:
        if self.codec not in VIDEO_CODECS:
            raise VideoFormatError(f"video codec {self.codec!r}: one of {', '.join(VIDEO_CODECS)}")
        if not 0 <= self.crf <= 63 or self.gop < 1:
            raise VideoFormatError(f"crf must be 0..63 and gop at least 1, got crf={self.crf} gop={self.gop}")


class VideoFileWriter:
    """One MP4 file of a camera's frames, appended to episode after episode (see the module docstring).

    Args:
        path: the new file.
        width, height: the frames' size (even numbers: ``yuv420p`` halves the colour planes).
        fps: the dataset's frames per second; frame ``k`` of the file is at ``k / fps`` seconds.
    """

    def __init__(self, path: Path, width: int, height: int, fps: int, settings: VideoSettings) -> None:
        av = _av()
        if width % 2 or height % 2:
            raise VideoFormatError(f"images of {width} x {height}: video needs an even width and height "
                                   "(e.g. --image-size 64x48)")
        self.path, self.width, self.height, self.fps = Path(path), int(width), int(height), int(fps)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        options = {"g": str(settings.gop), "crf": str(settings.crf)}
        if settings.codec == "libsvtav1":
            options["svtav1-params"] = "lp=1"  # one thread: the machine's other work goes on
        else:  # x264/x265: "veryfast" costs 0.14 ms a 84 x 84 frame, "medium" (their default) 0.25, same size
            options.update(preset=settings.preset, threads="1")
        self._time_base = Fraction(1, self.fps)
        self._container = av.open(str(self.path), "w", format="mp4")
        try:
            stream = self._container.add_stream(settings.codec, self.fps, options=options)
            stream.width, stream.height, stream.pix_fmt = self.width, self.height, settings.pix_fmt
            stream.codec_context.time_base = self._time_base
        except Exception:
            self._container.close()
            raise
        self._stream = stream
        self.frames = 0
        self._info: dict[str, Any] | None = None

    def write(self, frames: np.ndarray) -> None:
        """Encode ``frames`` (``n x height x width x 3``, uint8 RGB) after those already written."""
        av = _av()
        if frames.ndim != 4 or frames.shape[1:] != (self.height, self.width, 3) or frames.dtype != np.uint8:
            raise VideoFormatError(f"frames of shape {frames.shape} ({frames.dtype}): the video holds uint8 "
                                   f"{self.height} x {self.width} x 3")
        for image in frames:
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="rgb24")
            frame.pts, frame.time_base = self.frames, self._time_base
            self._container.mux(self._stream.encode(frame))
            self.frames += 1

    def size_bytes(self) -> int:
        """Bytes written to the file so far (the encoder holds a few frames more)."""
        return self.path.stat().st_size if self.path.exists() else 0

    def close(self) -> None:
        """Flush the encoder and finish the file."""
        if self._container is None:
            return
        try:
            self._container.mux(self._stream.encode(None))
            self._info = {"video.height": self.height, "video.width": self.width,
                          "video.codec": self._stream.codec_context.codec.canonical_name,
                          "video.pix_fmt": self._stream.pix_fmt, "video.is_depth_map": False, "video.fps": self.fps,
                          "video.channels": 3, "has_audio": False}
        finally:
            self._container.close()
            self._container = None

    def info(self) -> dict[str, Any]:
        """The feature's ``info`` block of ``info.json`` (LeRobot's ``get_video_info`` keys), once closed."""
        if self._info is None:
            raise VideoFormatError(f"{self.path}: info() before close()")
        return dict(self._info)

    def abort(self) -> None:
        """Close without caring whether the file is whole (an interrupted recording)."""
        if self._container is not None:
            try:
                self._container.close()
            except Exception:  # noqa: BLE001 - the file is thrown away anyway
                pass
            self._container = None


def image_stats(frames: np.ndarray) -> dict[str, np.ndarray]:
    """LeRobot's statistics of an episode's frames (``n x H x W x 3`` uint8): per channel (shape 3 x 1 x 1),
    in [0, 1], over at most 100 evenly spaced frames (``compute_stats.sample_indices`` for short episodes;
    ``count`` is the frames sampled). Computed from each channel's 256-bin histogram: the same values as
    numpy's (its quantiles interpolated between order statistics), a few times cheaper than sorting."""
    n = len(frames)
    samples = min(n, max(100, min(int(n ** 0.75), 10_000)))
    picked = frames[np.round(np.linspace(0, n - 1, samples)).astype(int)].reshape(-1, 3)
    levels = np.arange(256, dtype=np.float64)
    out: dict[str, list[float]] = {}
    for c in range(3):
        hist = np.bincount(picked[:, c], minlength=256).astype(np.float64)
        total = hist.sum()
        mean = float(levels @ hist / total)
        nonzero = np.flatnonzero(hist)
        values = {"min": float(nonzero[0]), "max": float(nonzero[-1]), "mean": mean,
                  "std": float(np.sqrt(((levels - mean) ** 2) @ hist / total))}
        ends = np.cumsum(hist)  # the sorted pixels' k-th value is the first level whose count passes k
        for q in QUANTILES:
            at = (total - 1) * q
            low = int(np.floor(at))
            lo, hi = np.searchsorted(ends, [low + 1, min(low + 2, total)])
            values[f"q{round(q * 100):02d}"] = float(lo + (at - low) * (hi - lo))
        for key, value in values.items():
            out.setdefault(key, []).append(value / 255.0)
    stats = {k: np.array(v).reshape(3, 1, 1) for k, v in out.items()}
    stats["count"] = np.array([samples], np.int64)
    return stats


def decode_video(path: Path, *, width: int, height: int, fps: int, max_frames: int) -> np.ndarray:
    """The ``max_frames`` frames of the video ``path`` (the frames of the episodes in it) as ``max_frames x
    height x width x 3`` uint8 RGB, frame ``k`` being the one at ``k / fps`` seconds.

    Raises:
        VideoFormatError: the file is missing, larger than :data:`MAX_VIDEO_BYTES`, not a readable video,
            of another size than ``width x height``, with a frame off the ``1 / fps`` grid, twice, past
            ``max_frames`` or missing.
    """
    av = _av()
    path = Path(path)
    if not path.is_file():
        raise VideoFormatError(f"{path}: missing")
    if path.stat().st_size > MAX_VIDEO_BYTES:
        raise VideoFormatError(f"{path}: larger than {MAX_VIDEO_BYTES} bytes")
    out = np.empty((max_frames, height, width, 3), np.uint8)  # the caller bounds max_frames x the frame's size
    seen = np.zeros(max_frames, bool)
    try:
        with av.open(str(path), "r", format="mp4") as container:
            if not container.streams.video:
                raise VideoFormatError(f"{path}: no video stream")
            stream = container.streams.video[0]
            if (stream.codec_context.width, stream.codec_context.height) != (width, height):
                raise VideoFormatError(f"{path}: frames of {stream.codec_context.width} x "
                                       f"{stream.codec_context.height}, info.json says {width} x {height}")
            for frame in container.decode(stream):
                if frame.width != width or frame.height != height:
                    raise VideoFormatError(f"{path}: a frame of {frame.width} x {frame.height}, info.json says "
                                           f"{width} x {height}")
                if frame.time is None:
                    raise VideoFormatError(f"{path}: a frame without a timestamp")
                k = round(frame.time * fps)
                if abs(frame.time * fps - k) > 0.01 or not 0 <= k < max_frames:
                    raise VideoFormatError(f"{path}: a frame at {frame.time:.4f} s: not one of the "
                                           f"{max_frames} frames of its episodes at {fps} fps")
                if seen[k]:
                    raise VideoFormatError(f"{path}: two frames at {frame.time:.4f} s")
                seen[k] = True
                out[k] = frame.to_ndarray(format="rgb24")
    except VideoFormatError:
        raise
    except (av.error.FFmpegError, OSError, ValueError, EOFError) as exc:
        raise VideoFormatError(f"{path}: not a readable video ({str(exc).splitlines()[0][:200]})") from None
    if not seen.all():
        raise VideoFormatError(f"{path}: {int(seen.sum())} frames, its episodes have {max_frames}")
    return out
