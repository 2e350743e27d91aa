"""Encode 8-bit RGB frames to an MP4 that browsers play: H.264 (yuv420p), with a stated fallback.

Encoders, tried in this order unless one is named:

1. ``av`` — PyAV (``pip install 'olatbench[video]'``): libx264, ``yuv420p``, CRF 18, ``+faststart``.
2. ``imageio-ffmpeg`` — the ffmpeg binary that package ships (also in ``olatbench[video]``), same
   settings, frames piped in as raw RGB.
3. ``opencv`` — OpenCV's ``mp4v`` (MPEG-4 Part 2), always installed. Browsers do not play it (the
   HTML report cannot show it; VLC and ffplay can), so choosing it is logged as a warning naming the
   extra to install.

``yuv420p`` stores colour at half resolution, so H.264 frames need an even width and height: an odd
frame is padded by repeating its last column / row (the video is then up to one pixel larger than
the PNG frames). Frames are ``(H, W, 3)`` uint8 sRGB, all of one size.
"""

from __future__ import annotations

import importlib.util
import logging
import subprocess
from pathlib import Path
from typing import Protocol

import numpy as np

log = logging.getLogger(__name__)

ENCODERS = ("av", "imageio-ffmpeg", "opencv")
CRF = 18  # visually lossless for renders; x264's default is 23
FALLBACK_WARNING = (
    "no H.264 encoder found (install 'olatbench[video]': PyAV or imageio-ffmpeg); writing MPEG-4 "
    "Part 2 (mp4v) with OpenCV, which browsers do not play"
)


class FrameWriter(Protocol):
    """What `open_video` returns: ``write`` one (H, W, 3) uint8 RGB frame at a time, then
    ``close``."""

    encoder: str

    def write(self, frame: np.ndarray) -> None: ...

    def close(self) -> None: ...


def available_encoders() -> list[str]:
    """The encoders of `ENCODERS` this environment can use, in order of preference."""
    found = [
        name
        for name, module in (("av", "av"), ("imageio-ffmpeg", "imageio_ffmpeg"))
        if importlib.util.find_spec(module) is not None
    ]
    return [*found, "opencv"]


def _even(frame: np.ndarray) -> np.ndarray:
    """``frame`` padded to an even height and width by repeating its last row / column."""
    height, width = frame.shape[:2]
    return np.pad(frame, ((0, height % 2), (0, width % 2), (0, 0)), mode="edge")


class _AvWriter:
    encoder = "av"

    def __init__(self, path: Path, fps: float, width: int, height: int) -> None:
        from fractions import Fraction

        import av

        self.container = av.open(
            str(path), mode="w", format="mp4", options={"movflags": "+faststart"}
        )
        self.stream = self.container.add_stream(
            "libx264", rate=Fraction(fps).limit_denominator(1001)
        )
        self.stream.width, self.stream.height = width + width % 2, height + height % 2
        self.stream.pix_fmt = "yuv420p"
        self.stream.options = {"crf": str(CRF)}
        self.frame_type = av.VideoFrame

    def write(self, frame: np.ndarray) -> None:
        for packet in self.stream.encode(
            self.frame_type.from_ndarray(_even(frame), format="rgb24")
        ):
            self.container.mux(packet)

    def close(self) -> None:
        for packet in self.stream.encode():
            self.container.mux(packet)
        self.container.close()


class _FfmpegWriter:
    encoder = "imageio-ffmpeg"

    def __init__(self, path: Path, fps: float, width: int, height: int) -> None:
        import imageio_ffmpeg

        even = f"{width + width % 2}x{height + height % 2}"
        command = [
            imageio_ffmpeg.get_ffmpeg_exe(),
            "-y",
            "-loglevel",
            "error",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-s",
            even,
            "-r",
            f"{fps}",
            "-i",
            "-",
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "-crf",
            str(CRF),
            "-movflags",
            "+faststart",
            "-f",
            "mp4",
            str(path),
        ]
        self.process = subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE)

    def write(self, frame: np.ndarray) -> None:
        self.process.stdin.write(np.ascontiguousarray(_even(frame)).tobytes())

    def close(self) -> None:
        _, error = self.process.communicate()
        if self.process.returncode:
            raise OSError(
                f"ffmpeg failed ({self.process.returncode}): "
                f"{error.decode(errors='replace').strip()}"
            )


class _OpenCvWriter:
    encoder = "opencv"

    def __init__(self, path: Path, fps: float, width: int, height: int) -> None:
        import cv2

        self.writer = cv2.VideoWriter(
            str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (width, height)
        )
        if not self.writer.isOpened():
            raise OSError(f"{path}: OpenCV cannot open an mp4v video writer")

    def write(self, frame: np.ndarray) -> None:
        self.writer.write(np.ascontiguousarray(frame[..., ::-1]))  # OpenCV takes BGR

    def close(self) -> None:
        self.writer.release()


_WRITERS = {"av": _AvWriter, "imageio-ffmpeg": _FfmpegWriter, "opencv": _OpenCvWriter}


def open_video(
    path: str | Path, fps: float, width: int, height: int, encoder: str | None = None
) -> FrameWriter:
    """A writer of ``width`` × ``height`` frames into the MP4 at ``path``; the file is complete
    after ``close()`` (written in place: wrap it in `olatbench.atomic.atomic_path` for an atomic
    file). ``encoder``: one of `ENCODERS`, default the first available; falling back to ``opencv``
    logs `FALLBACK_WARNING`."""
    if encoder is None:
        encoder = available_encoders()[0]
        if encoder == "opencv":
            log.warning(FALLBACK_WARNING)
    if encoder not in _WRITERS:
        raise ValueError(
            f"unknown video encoder {encoder!r}; expected one of {', '.join(ENCODERS)}"
        )
    return _WRITERS[encoder](Path(path), fps, width, height)
