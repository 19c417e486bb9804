"""What a browser received from the teleoperation page: viser's WebSocket frames decoded into messages.

A frame is ``[8 bytes msgpack size][8 bytes compressed size][zstd msgpack][aligned binary buffers]``
(viser's wire format); the msgpack holds ``{"messages": [...], ...}``. The checks of the page's
sessions read every frame a browser got (Playwright's ``framereceived``) and look for what must not
be there: the token, anything about the robot before the session logged in.
"""
from __future__ import annotations

from typing import Any

__all__ = ["ROBOT_WORDS", "about_robot", "decode_frame", "mentions"]

#: Names that only a message about the robot (its scene, its state, its controls) carries.
ROBOT_WORDS = ("/robot", "link_", "joint_", "lrmate", "/hand", "/waypoints", "/obstacles", "/table", "Hand position",
               "Record waypoint", "Jog", "Joints")


def decode_frame(frame: bytes | str) -> tuple[list[dict[str, Any]], bytes]:
    """The messages of one viser frame and its raw bytes after decompression (msgpack + binary buffers).

    Args:
        frame: the frame's payload as the browser received it.

    Returns:
        (messages, raw) -- raw is what a search for a byte string (a token) must look through.
    """
    import msgspec
    import zstandard

    if isinstance(frame, str):
        return [], frame.encode("utf-8", "surrogatepass")
    n_inner = int.from_bytes(frame[:8], "little")
    n_comp = int.from_bytes(frame[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(frame[16:16 + n_comp], max_output_size=max(n_inner, 1))
    payload = msgspec.msgpack.decode(inner)
    messages = payload.get("messages", []) if isinstance(payload, dict) else []
    return list(messages), inner + frame[16 + n_comp:]


def mentions(frames: list[bytes | str], needle: str) -> int:
    """How many frames hold ``needle`` (UTF-8) anywhere in their decompressed bytes."""
    b = needle.encode("utf-8", "surrogatepass")
    return sum(b in decode_frame(f)[1] for f in frames)


def about_robot(frames: list[bytes | str]) -> int:
    """How many messages in ``frames`` carry one of :data:`ROBOT_WORDS`."""
    n = 0
    for f in frames:
        for m in decode_frame(f)[0]:
            text = repr(m)
            n += any(w in text for w in ROBOT_WORDS)
    return n
