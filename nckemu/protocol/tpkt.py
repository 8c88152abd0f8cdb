"""TPKT (RFC 1006): ``03 00 LL LL`` + payload, the length counting the 4 header bytes."""

from __future__ import annotations

import struct

from construct import Bytes, Const, Int8ub, Int16ub, Struct, this

from .errors import NckProtocolError, NckTruncatedError

TPKT_VERSION = 3
TPKT_HEADER_BYTES = 4
# The smallest frame S7 peers send: a TPKT header and a 3-byte COTP DT header.
MIN_FRAME_BYTES = 7

TPKT = Struct(
    "version" / Const(TPKT_VERSION, Int8ub),
    "reserved" / Int8ub,
    "length" / Int16ub,
    "payload" / Bytes(this.length - TPKT_HEADER_BYTES),
)

_HEADER = struct.Struct(">BBH")


def build_tpkt(payload: bytes) -> bytes:
    length = len(payload) + TPKT_HEADER_BYTES
    if length > 0xFFFF:
        raise NckProtocolError(f"TPKT payload of {len(payload)} bytes does not fit a TPKT frame")
    return _HEADER.pack(TPKT_VERSION, 0, length) + payload


def parse_tpkt(frame: bytes) -> bytes:
    """The payload of one complete TPKT frame."""
    if len(frame) < TPKT_HEADER_BYTES:
        raise NckTruncatedError(f"TPKT frame of {len(frame)} bytes is shorter than its header")
    version, _reserved, length = _HEADER.unpack_from(frame)
    if version != TPKT_VERSION:
        raise NckProtocolError(f"TPKT version {version}, expected 3")
    if length != len(frame):
        raise NckProtocolError(f"TPKT length {length} but the frame has {len(frame)} bytes")
    return frame[TPKT_HEADER_BYTES:]


def split_frames(buffer: bytes, max_frame_bytes: int = 0xFFFF) -> tuple[list[bytes], bytes]:
    """Cut a byte stream into complete TPKT frames; return them and the unconsumed rest."""
    frames: list[bytes] = []
    offset = 0
    end = len(buffer)
    while end - offset >= TPKT_HEADER_BYTES:
        version, _reserved, length = _HEADER.unpack_from(buffer, offset)
        if version != TPKT_VERSION:
            raise NckProtocolError(f"TPKT version {version} at stream offset {offset}, expected 3")
        if length < MIN_FRAME_BYTES or length > max_frame_bytes:
            raise NckProtocolError(f"TPKT length {length} outside {MIN_FRAME_BYTES}..{max_frame_bytes}")
        if end - offset < length:
            break
        frames.append(buffer[offset:offset + length])
        offset += length
    return frames, buffer[offset:]
