"""Decoding the MP4s the tests write: FFmpeg's H.264 decoder through PyAV, as a player would see them."""
from __future__ import annotations

import av
import numpy as np


def mp4_frames(path) -> tuple[dict, list[np.ndarray]]:
    """``(info, frames)``: ``info["size"]`` (width, height) and ``info["fps"]``, and every frame of
    ``path`` as an (h, w, 3) uint8 RGB array.

    Converted with the matrix and range the recorder writes and tags (BT.709,
    limited), whatever a decoder would guess for an untagged file.
    """
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        info = {"size": (stream.codec_context.width, stream.codec_context.height),
                "fps": float(stream.average_rate)}
        frames = [f.reformat(format="rgb24", src_colorspace="ITU709", dst_colorspace="ITU709",
                             src_color_range="MPEG", dst_color_range="JPEG").to_ndarray()
                  for f in container.decode(stream)]
    return info, frames
