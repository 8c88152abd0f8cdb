"""Userdata (ROSCTR 7), CPU functions, read SZL: what S7 clients ask to identify a CPU.

Request parameter ``00 01 12 04 11 44 01 00`` (head, length 4, method request, type request and
group 4 "CPU functions", subfunction 1 "read SZL", sequence); data ``FF 09 00 04`` + SZL ID + index.
Answer parameter ``00 01 12 08 12 84 01 <seq> 00 00 <error code>``; data ``FF 09 len`` + the SZL
(ID, index, record length, record count, records), or ``0A 00 00 00`` with an error code.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from .errors import NckProtocolError, NckServiceError, NckTruncatedError

METHOD_REQUEST = 0x11
METHOD_RESPONSE = 0x12
GROUP_CPU_FUNCTIONS = 0x04
SUBFUNCTION_READ_SZL = 0x01
TYPE_PUSH = 0x0
TYPE_REQUEST = 0x4
TYPE_RESPONSE = 0x8
# Userdata error code for an SZL the CPU does not have ("invalid SZL ID", as S7 CPUs answer).
ERROR_SZL_NOT_AVAILABLE = 0xD401


@dataclass(frozen=True, slots=True)
class SzlReadRequest:
    szl_id: int
    szl_index: int
    sequence_number: int = 0


@dataclass(frozen=True, slots=True)
class SzlReadResponse:
    szl_id: int
    szl_index: int
    payload: bytes  # record length, record count and the records
    error_code: int = 0
    sequence_number: int = 0


def parse_szl_request(parameter: bytes, data: bytes) -> SzlReadRequest:
    if len(parameter) < 8 or parameter[:3] != b"\x00\x01\x12":
        raise NckProtocolError("userdata parameter head is not 00 01 12")
    method, type_group, subfunction, sequence = parameter[4], parameter[5], parameter[6], parameter[7]
    # pyS7 (0.x) sends its SZL reads with type 0 ("push") and the request method; it works against
    # real CPUs, which go by the method, so we do too.
    if method != METHOD_REQUEST or type_group >> 4 not in (TYPE_REQUEST, TYPE_PUSH):
        raise NckProtocolError("userdata is not a request")
    if type_group & 0x0F != GROUP_CPU_FUNCTIONS or subfunction != SUBFUNCTION_READ_SZL:
        raise NckServiceError(f"userdata group {type_group & 0x0F} subfunction {subfunction} not served",
                              error_class=0x81, error_code=0x04)
    if len(data) < 8:
        raise NckTruncatedError("SZL request data shorter than 8 bytes")
    szl_id, szl_index = struct.unpack_from(">HH", data, 4)
    return SzlReadRequest(szl_id, szl_index, sequence)


def build_szl_request(request: SzlReadRequest) -> tuple[bytes, bytes]:
    parameter = bytes([0x00, 0x01, 0x12, 0x04, METHOD_REQUEST, (TYPE_REQUEST << 4) | GROUP_CPU_FUNCTIONS,
                       SUBFUNCTION_READ_SZL, request.sequence_number & 0xFF])
    return parameter, struct.pack(">BBHHH", 0xFF, 0x09, 4, request.szl_id, request.szl_index)


def _response_parameter(sequence: int, error_code: int) -> bytes:
    return bytes([0x00, 0x01, 0x12, 0x08, METHOD_RESPONSE, (TYPE_RESPONSE << 4) | GROUP_CPU_FUNCTIONS,
                  SUBFUNCTION_READ_SZL, sequence & 0xFF, 0x00, 0x00]) + struct.pack(">H", error_code)


def build_szl_response(request: SzlReadRequest, szl: bytes) -> tuple[bytes, bytes]:
    """``szl`` is the whole list: ID, index, record length, record count and the records."""
    if len(szl) > 0xFFFF:
        raise NckProtocolError("SZL answer too long")
    return _response_parameter(request.sequence_number, 0), struct.pack(">BBH", 0xFF, 0x09, len(szl)) + szl


def build_szl_error_response(request: SzlReadRequest, error_code: int = ERROR_SZL_NOT_AVAILABLE
                             ) -> tuple[bytes, bytes]:
    return _response_parameter(request.sequence_number, error_code), b"\x0A\x00\x00\x00"


def parse_szl_response(parameter: bytes, data: bytes) -> SzlReadResponse:
    if len(parameter) < 12 or parameter[:3] != b"\x00\x01\x12":
        raise NckProtocolError("userdata answer parameter head is not 00 01 12")
    (error_code,) = struct.unpack_from(">H", parameter, 10)
    if len(data) < 4:
        raise NckTruncatedError("SZL answer data shorter than 4 bytes")
    _rc, _ts, length = struct.unpack_from(">BBH", data)
    body = data[4:4 + length]
    if len(body) != length:
        raise NckTruncatedError("SZL answer shorter than announced")
    if error_code or length < 4:
        return SzlReadResponse(0, 0, b"", error_code, parameter[7])
    szl_id, szl_index = struct.unpack_from(">HH", body)
    return SzlReadResponse(szl_id, szl_index, body[4:], 0, parameter[7])
