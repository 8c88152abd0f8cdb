"""Userdata (ROSCTR 7) parameter head of every function group, and the names tshark gives groups and
subfunctions.

Parameter: ``00 01 12``, the length of what follows (4 or 8), the method (0x11 request, 0x12
response), the type in the high nibble (0 push, 4 request, 8 response) and the function group in the
low one, the subfunction and a sequence number; the 8-byte form adds the data unit reference, a
"last data unit" byte (0 yes, 1 no) and a 16-bit error code. A request (type 4) and its response
(type 8) carry the same PDU reference; a CPU sends pushes (type 0: cyclic data, alarm and diagnostic
messages) on its own, with PDU reference 0. The data part is return code, transport size, 16-bit
length and the payload.

Names: Wireshark's s7comm dissector as packaged in tshark 4.0.17 (Debian 12), read off its Info
column for every group 0..7, 0xF and subfunction 0..0x16 of frames built here
(``tests/traces/test_field_corpus.py`` checks them against it).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from .errors import NckProtocolError, NckTruncatedError

PARAMETER_HEAD = b"\x00\x01\x12"
# The head of a STEP 7 CPU's mode-transition push (``01 00 10``, then 0x10 where the length would be,
# method 0, type push, group 0, the new mode, sequence): tshark decodes it as the usual parameter
# ("Parameter head: 0x010010"; iti step7_s300_stop.pcapng).
MODE_TRANSITION_HEAD = b"\x01\x00\x10"
_MODE_TRANSITION_LENGTH = 0x10
METHOD_REQUEST = 0x11
METHOD_RESPONSE = 0x12
TYPE_PUSH = 0x0
TYPE_REQUEST = 0x4
TYPE_RESPONSE = 0x8

TYPE_NAMES = {TYPE_PUSH: "Push", TYPE_REQUEST: "Request", TYPE_RESPONSE: "Response"}

GROUP_MODE_TRANSITION = 0x0
GROUP_PROGRAMMER = 0x1
GROUP_CYCLIC = 0x2
GROUP_BLOCK = 0x3
GROUP_CPU = 0x4
GROUP_SECURITY = 0x5
GROUP_PBC = 0x6
GROUP_TIME = 0x7
GROUP_NC_PROGRAMMING = 0xF

GROUP_NAMES = {
    GROUP_MODE_TRANSITION: "Mode-transition", GROUP_PROGRAMMER: "Programmer commands",
    GROUP_CYCLIC: "Cyclic services", GROUP_BLOCK: "Block functions", GROUP_CPU: "CPU functions",
    GROUP_SECURITY: "Security", GROUP_PBC: "PBC BSEND/BRECV", GROUP_TIME: "Time functions",
    GROUP_NC_PROGRAMMING: "NC programming",
}

# Subfunction names by group. tshark names no subfunction of group 6 (PBC); for group 0 the
# "subfunction" byte is the CPU's new mode.
SUBFUNCTION_NAMES: dict[int, dict[int, str]] = {
    GROUP_MODE_TRANSITION: {0x00: "STOP", 0x01: "Warm Restart", 0x02: "RUN", 0x03: "Hot Restart", 0x04: "HOLD",
                            0x06: "Cold Restart", 0x09: "RUN_R (H-System redundant)", 0x0B: "LINK-UP",
                            0x0C: "UPDATE"},
    GROUP_PROGRAMMER: {0x01: "Block status", 0x02: "Variable status", 0x03: "Output ISTACK",
                       0x04: "Output BSTACK", 0x05: "Output LSTACK", 0x06: "Time measurement from to",
                       0x07: "Force selection", 0x08: "Modify variable", 0x09: "Force", 0x0A: "Breakpoint",
                       0x0B: "Exit HOLD", 0x0C: "Memory reset", 0x0D: "Disable job", 0x0E: "Enable job",
                       0x0F: "Delete job", 0x10: "Read job list", 0x11: "Read job", 0x12: "Replace job",
                       0x13: "Block status v2", 0x16: "Flash LED"},
    GROUP_CYCLIC: {0x01: "Cyclic transfer", 0x04: "Unsubscribe", 0x05: "Change driven transfer",
                   0x07: "Change driven transfer modify", 0x08: "RDREC"},
    GROUP_BLOCK: {0x01: "List blocks", 0x02: "List blocks of type", 0x03: "Get block info"},
    GROUP_CPU: {0x01: "Read SZL", 0x02: "Message service", 0x03: "Diagnostic message", 0x05: "ALARM_8 indication",
                0x06: "NOTIFY indication", 0x07: "ALARM_8 lock", 0x08: "ALARM_8 unlock", 0x09: "SCAN indication",
                0x0B: "ALARM ack", 0x0C: "ALARM ack indication", 0x0D: "ALARM lock indication",
                0x0E: "ALARM unlock indication", 0x11: "ALARM_SQ indication", 0x12: "ALARM_S indication",
                0x13: "ALARM query", 0x16: "NOTIFY_8 indication"},
    GROUP_SECURITY: {0x01: "PLC password"},
    GROUP_TIME: {0x01: "Read clock", 0x02: "Set clock", 0x03: "Read clock (following)", 0x04: "Set clock"},
    GROUP_NC_PROGRAMMING: {0x01: "Request download", 0x02: "Download block", 0x03: "Continue download",
                           0x04: "Download ended", 0x06: "Start upload", 0x07: "Upload", 0x08: "Continue upload"},
}


@dataclass(frozen=True, slots=True)
class UserdataParameter:
    """The parameter of a userdata PDU; the last four fields exist only in the 8-byte form (``long``)."""

    method: int
    type: int
    group: int
    subfunction: int
    sequence: int = 0
    long: bool = False
    data_unit_ref: int = 0
    last_data_unit: int = 0
    error_code: int = 0
    head: bytes = PARAMETER_HEAD


def parse_userdata_parameter(parameter: bytes) -> UserdataParameter:
    if len(parameter) == 8 and parameter[:3] == MODE_TRANSITION_HEAD and parameter[3] == _MODE_TRANSITION_LENGTH:
        method, type_group, subfunction, sequence = parameter[4:8]
        return UserdataParameter(method, type_group >> 4, type_group & 0x0F, subfunction, sequence,
                                 head=MODE_TRANSITION_HEAD)
    if len(parameter) < 8 or parameter[:3] != PARAMETER_HEAD:
        raise NckTruncatedError("userdata parameter shorter than 8 bytes") if len(parameter) < 8 \
            else NckProtocolError("userdata parameter head is not 00 01 12")
    length = parameter[3]
    if length not in (4, 8) or len(parameter) != 4 + length:
        raise NckProtocolError(f"userdata parameter announces {length} bytes, has {len(parameter) - 4}")
    method, type_group, subfunction, sequence = parameter[4:8]
    if length == 4:
        return UserdataParameter(method, type_group >> 4, type_group & 0x0F, subfunction, sequence)
    data_unit_ref, last_data_unit, error_code = struct.unpack_from(">BBH", parameter, 8)
    return UserdataParameter(method, type_group >> 4, type_group & 0x0F, subfunction, sequence, True,
                             data_unit_ref, last_data_unit, error_code)


def build_userdata_parameter(parameter: UserdataParameter) -> bytes:
    if parameter.head == MODE_TRANSITION_HEAD:
        return MODE_TRANSITION_HEAD + bytes([_MODE_TRANSITION_LENGTH, parameter.method,
                                             (parameter.type << 4) | parameter.group, parameter.subfunction,
                                             parameter.sequence])
    head = PARAMETER_HEAD + bytes([8 if parameter.long else 4, parameter.method,
                                   (parameter.type << 4) | parameter.group, parameter.subfunction,
                                   parameter.sequence])
    if not parameter.long:
        return head
    return head + struct.pack(">BBH", parameter.data_unit_ref, parameter.last_data_unit, parameter.error_code)


def group_name(group: int) -> str:
    return GROUP_NAMES.get(group, f"Unknown function: 0x{group:02x}")


def subfunction_name(group: int, subfunction: int) -> str | None:
    """tshark's name of a subfunction; None for group 6, where tshark names none."""
    if group == GROUP_PBC:
        return None
    return SUBFUNCTION_NAMES.get(group, {}).get(subfunction, f"Unknown subfunc: 0x{subfunction:02x}")


def describe(group: int, subfunction: int) -> str:
    """Group and subfunction as tshark's Info column shows them: ``CPU functions -> Read SZL``."""
    name = subfunction_name(group, subfunction)
    return group_name(group) if name is None else f"{group_name(group)} -> {name}"
