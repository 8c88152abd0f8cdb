"""COTP class 0 (ISO 8073) as S7 uses it: CR, CC, DT (with EOT), DR, DC, ER.

Every TPDU starts with the length indicator LI (bytes that follow it in the header) and the code
in the high nibble of the next byte. CR/CC carry variable parameters: TPDU size (0xC0, 2^n bytes)
and the calling/called TSAPs (0xC1/0xC2), which name rack and slot for S7.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from construct import Const, GreedyBytes, GreedyRange, Int8ub, Int16ub, Prefixed, Struct

from .errors import NckProtocolError, NckTruncatedError
from .tpkt import TPKT_HEADER_BYTES, TPKT_VERSION, build_tpkt

CODE_CR = 0xE0
CODE_CC = 0xD0
CODE_DT = 0xF0
CODE_DR = 0x80
CODE_DC = 0xC0
CODE_ER = 0x70

PARAM_TPDU_SIZE = 0xC0
PARAM_CALLING_TSAP = 0xC1
PARAM_CALLED_TSAP = 0xC2

# The declared formats (construct); the hand-written parse/build below are the fast path and
# tests/protocol check that both agree.
PARAMETER = Struct("code" / Int8ub, "value" / Prefixed(Int8ub, GreedyBytes))
CONNECT_TPDU = Prefixed(Int8ub, Struct(
    "code" / Int8ub,
    "dst_ref" / Int16ub,
    "src_ref" / Int16ub,
    "class_option" / Int8ub,
    "parameters" / GreedyRange(PARAMETER),
))
DATA_TPDU = Struct(
    "length_indicator" / Const(2, Int8ub),
    "code" / Const(0xF0, Int8ub),
    "eot_and_number" / Int8ub,
    "payload" / GreedyBytes,
)

DT_EOT = 0x80
DT_HEADER_EOT = bytes([2, CODE_DT, DT_EOT])


@dataclass(frozen=True, slots=True)
class _Connect:
    src_ref: int
    dst_ref: int = 0
    class_option: int = 0
    calling_tsap: bytes | None = None
    called_tsap: bytes | None = None
    tpdu_size: int | None = None
    other_parameters: tuple[tuple[int, bytes], ...] = ()


@dataclass(frozen=True, slots=True)
class ConnectRequest(_Connect):
    """CR, client to server."""


@dataclass(frozen=True, slots=True)
class ConnectConfirm(_Connect):
    """CC, server to client (a distinct type: a session must not take one for the other)."""


@dataclass(frozen=True, slots=True)
class DataTpdu:
    payload: bytes
    eot: bool = True
    tpdu_number: int = 0


@dataclass(frozen=True, slots=True)
class DisconnectRequest:
    dst_ref: int
    src_ref: int
    reason: int = 0


@dataclass(frozen=True, slots=True)
class DisconnectConfirm:
    dst_ref: int
    src_ref: int


@dataclass(frozen=True, slots=True)
class TpduError:
    dst_ref: int
    reject_cause: int = 0


Cotp = ConnectRequest | ConnectConfirm | DataTpdu | DisconnectRequest | DisconnectConfirm | TpduError


def _tpdu_size_code(size: int) -> int:
    code = size.bit_length() - 1
    if size <= 0 or 1 << code != size or not 7 <= code <= 13:
        raise NckProtocolError(f"TPDU size {size} is not a power of two from 128 to 8192")
    return code


def _parse_parameters(data: bytes) -> list[tuple[int, bytes]]:
    parameters: list[tuple[int, bytes]] = []
    offset = 0
    while offset < len(data):
        if offset + 2 > len(data):
            raise NckTruncatedError("COTP parameter header cut short")
        code, length = data[offset], data[offset + 1]
        value = data[offset + 2:offset + 2 + length]
        if len(value) != length:
            raise NckTruncatedError(f"COTP parameter 0x{code:02X} announces {length} bytes")
        parameters.append((code, value))
        offset += 2 + length
    return parameters


def _parse_connect(cls: type[ConnectRequest] | type[ConnectConfirm], header: bytes) -> Cotp:
    if len(header) < 6:
        raise NckTruncatedError("COTP connect TPDU shorter than its fixed part")
    dst_ref = int.from_bytes(header[1:3], "big")
    src_ref = int.from_bytes(header[3:5], "big")
    class_option = header[5]
    calling = called = None
    tpdu_size = None
    others: list[tuple[int, bytes]] = []
    for code, value in _parse_parameters(header[6:]):
        if code == PARAM_CALLING_TSAP and calling is None:
            calling = value
        elif code == PARAM_CALLED_TSAP and called is None:
            called = value
        elif code == PARAM_TPDU_SIZE and tpdu_size is None and len(value) == 1 and 7 <= value[0] <= 13:
            tpdu_size = 1 << value[0]
        else:
            others.append((code, value))
    return cls(src_ref=src_ref, dst_ref=dst_ref, class_option=class_option, calling_tsap=calling,
               called_tsap=called, tpdu_size=tpdu_size, other_parameters=tuple(others))


def parse_cotp(data: bytes) -> Cotp:
    """One COTP TPDU (the TPKT payload)."""
    if len(data) < 2:
        raise NckTruncatedError("COTP TPDU shorter than 2 bytes")
    length_indicator = data[0]
    if length_indicator + 1 > len(data) or length_indicator < 1:
        raise NckProtocolError(f"COTP length indicator {length_indicator} exceeds the TPDU")
    header = data[1:1 + length_indicator]
    code = header[0] & 0xF0
    if code == CODE_DT:
        if length_indicator != 2:
            raise NckProtocolError(f"COTP DT with length indicator {length_indicator}, expected 2")
        return DataTpdu(data[3:], eot=bool(header[1] & DT_EOT), tpdu_number=header[1] & 0x7F)
    if len(data) != length_indicator + 1 and code in (CODE_CR, CODE_CC):
        raise NckProtocolError(f"COTP 0x{code:02X} TPDU carries {len(data) - length_indicator - 1} "
                               "bytes of user data (class 0 has none)")
    # A DR may carry user data (python-snap7 sends one byte); it is not needed and is dropped.
    if code == CODE_CR:
        return _parse_connect(ConnectRequest, header)
    if code == CODE_CC:
        return _parse_connect(ConnectConfirm, header)
    if code == CODE_DR:
        if len(header) < 6:
            raise NckTruncatedError("COTP DR shorter than its fixed part")
        return DisconnectRequest(int.from_bytes(header[1:3], "big"), int.from_bytes(header[3:5], "big"),
                                 header[5])
    if code == CODE_DC:
        if len(header) < 5:
            raise NckTruncatedError("COTP DC shorter than its fixed part")
        return DisconnectConfirm(int.from_bytes(header[1:3], "big"), int.from_bytes(header[3:5], "big"))
    if code == CODE_ER:
        if len(header) < 4:
            raise NckTruncatedError("COTP ER shorter than its fixed part")
        return TpduError(int.from_bytes(header[1:3], "big"), header[3])
    raise NckProtocolError(f"COTP TPDU code 0x{code:02X} is not used by S7")


def _connect_header(code: int, tpdu: ConnectRequest | ConnectConfirm) -> bytes:
    parts = [bytes([code]), tpdu.dst_ref.to_bytes(2, "big"), tpdu.src_ref.to_bytes(2, "big"),
             bytes([tpdu.class_option])]
    if tpdu.tpdu_size is not None:
        parts.append(bytes([PARAM_TPDU_SIZE, 1, _tpdu_size_code(tpdu.tpdu_size)]))
    for parameter_code, value in (
        (PARAM_CALLING_TSAP, tpdu.calling_tsap), (PARAM_CALLED_TSAP, tpdu.called_tsap),
    ):
        if value is not None:
            parts.append(bytes([parameter_code, len(value)]) + value)
    for parameter_code, value in tpdu.other_parameters:
        parts.append(bytes([parameter_code, len(value)]) + value)
    return b"".join(parts)


def build_cotp(tpdu: Cotp) -> bytes:
    if isinstance(tpdu, DataTpdu):
        if tpdu.eot and tpdu.tpdu_number == 0:
            return DT_HEADER_EOT + tpdu.payload
        return bytes([2, CODE_DT, (DT_EOT if tpdu.eot else 0) | (tpdu.tpdu_number & 0x7F)]) + tpdu.payload
    if isinstance(tpdu, ConnectRequest):
        header = _connect_header(CODE_CR, tpdu)
    elif isinstance(tpdu, ConnectConfirm):
        header = _connect_header(CODE_CC, tpdu)
    elif isinstance(tpdu, DisconnectRequest):
        header = bytes([CODE_DR]) + tpdu.dst_ref.to_bytes(2, "big") + tpdu.src_ref.to_bytes(2, "big") \
            + bytes([tpdu.reason])
    elif isinstance(tpdu, DisconnectConfirm):
        header = bytes([CODE_DC]) + tpdu.dst_ref.to_bytes(2, "big") + tpdu.src_ref.to_bytes(2, "big")
    elif isinstance(tpdu, TpduError):
        header = bytes([CODE_ER]) + tpdu.dst_ref.to_bytes(2, "big") + bytes([tpdu.reject_cause])
    else:
        raise TypeError(f"not a COTP TPDU: {tpdu!r}")
    if len(header) > 254:
        raise NckProtocolError("COTP header longer than 254 bytes")
    return bytes([len(header)]) + header


# TPKT header and DT header in one pack: every answer goes through here.
_DATA_FRAME_HEAD = struct.Struct(">BBHBBB")
# Where the S7 PDU starts in a frame of one DT: after the TPKT and DT headers.
DATA_FRAME_PDU_OFFSET = TPKT_HEADER_BYTES + len(DT_HEADER_EOT)


def build_data_frame(payload: bytes) -> bytes:
    """TPKT + COTP DT (EOT) around one S7 PDU: what every answer is."""
    length = len(payload) + DATA_FRAME_PDU_OFFSET
    if length > 0xFFFF:
        return build_tpkt(DT_HEADER_EOT + payload)  # raises the TPKT layer's error
    return _DATA_FRAME_HEAD.pack(TPKT_VERSION, 0, length, 2, CODE_DT, DT_EOT) + payload


DT_HEADER_MORE = bytes([2, CODE_DT, 0x00])


def build_data_frames(payload: bytes, tpdu_size: int) -> list[bytes]:
    """One S7 PDU in as many DTs as the negotiated TPDU size needs (COTP segmentation, ISO 8073:
    the TPDU size counts the 3-byte DT header and the user data, not TPKT); every DT but the last
    has EOT clear. Class 0 numbers no TPDU, so the number stays 0 (as C snap7 sends them)."""
    room = tpdu_size - len(DT_HEADER_EOT)
    if room <= 0:
        raise NckProtocolError(f"TPDU size {tpdu_size} leaves no room for data")
    if len(payload) <= room:
        return [build_tpkt(DT_HEADER_EOT + payload)]
    last = (len(payload) - 1) // room * room
    return [build_tpkt((DT_HEADER_EOT if offset == last else DT_HEADER_MORE) + payload[offset:offset + room])
            for offset in range(0, len(payload), room)]


def build_frame(tpdu: Cotp) -> bytes:
    """A whole frame: TPKT around COTP."""
    return build_tpkt(build_cotp(tpdu))
