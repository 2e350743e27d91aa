"""A minimal websocket client speaking viser's wire protocol, standing in for a browser tab in
tests.

Server -> client frames: two little-endian uint64 (msgpack size, compressed size), the
zstd-compressed msgpack ``{"messages": [...], ...}`` (bytes inline; numpy arrays as placeholders
into trailing buffers, not needed here). Client -> server: one message as plain msgpack
(``Message.as_serializable_dict``), as viser's own client sends.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import msgspec
import numpy as np
import viser
import zstandard
from viser import _messages
from waiting import BACKSTOP_SECONDS
from websockets.sync.client import connect


def decode_frame(raw: bytes) -> list[dict[str, Any]]:
    inner = int.from_bytes(raw[:8], "little")
    compressed = int.from_bytes(raw[8:16], "little")
    payload = zstandard.ZstdDecompressor().decompress(
        raw[16 : 16 + compressed], max_output_size=inner
    )
    return list(msgspec.msgpack.decode(payload)["messages"])


def decode_image(data: bytes) -> np.ndarray:
    """(H, W, 3) uint8 RGB of a JPEG or PNG payload."""
    import cv2

    bgr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    return np.ascontiguousarray(bgr[..., ::-1])


class ViserTestClient:
    """Connect like a browser tab (same subprotocol, so the version check passes) and exchange
    messages."""

    def __init__(self, port: int, host: str = "127.0.0.1") -> None:
        self.socket = connect(
            f"ws://{host}:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None
        )
        self.received: list[dict[str, Any]] = []

    def close(self) -> None:
        self.socket.close()

    def send(self, message: Any) -> None:
        self.socket.send(msgspec.msgpack.encode(message.as_serializable_dict()))

    def send_camera(
        self, wxyz, position, fov: float = 0.8, width: int = 400, height: int = 400
    ) -> None:
        """What a browser sends whenever its view changes (OpenCV pose, vertical fov in radians)."""
        position = tuple(float(v) for v in position)
        self.send(
            _messages.ViewerCameraMessage(
                wxyz=tuple(float(v) for v in wxyz),
                position=position,
                fov=fov,
                near=0.01,
                far=1000.0,
                image_height=height,
                image_width=width,
                look_at=(0.0, 0.0, 0.0),
                up_direction=(0.0, 0.0, 1.0),
            )
        )

    def wait_for(
        self,
        predicate: Callable[[dict[str, Any]], bool],
        timeout: float = BACKSTOP_SECONDS,
        after: int = 0,
    ) -> dict[str, Any]:
        """The first message (from index ``after`` of everything received) matching
        ``predicate``."""
        deadline = time.monotonic() + timeout
        while True:
            for message in self.received[after:]:
                if predicate(message):
                    return message
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                kinds = sorted({m.get("type", "?") for m in self.received})
                raise TimeoutError(
                    f"no matching message within {timeout} s; received types: {kinds}"
                )
            try:
                raw = self.socket.recv(timeout=min(remaining, 1.0))
            except TimeoutError:
                continue
            if isinstance(raw, bytes):
                self.received.extend(decode_frame(raw))

    def background_images(self) -> list[np.ndarray]:
        return [
            decode_image(m["rgb_data"])
            for m in self.received
            if m.get("type") == "BackgroundImageMessage" and m.get("rgb_data")
        ]
