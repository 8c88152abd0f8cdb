"""S7 error codes with their texts (header class/code, item return codes) and NCK area/module names."""

from __future__ import annotations

from enum import IntEnum

from nckemu.errors import HeaderError, ReturnCode

__all__ = ["HeaderError", "ReturnCode", "ErrorClass", "AREA_LETTERS", "NCK_MODULE_NAMES", "RETURN_CODE_TEXTS", "HEADER_ERROR_TEXTS",
           "describe_return_code", "describe_header_error", "describe_module",
           "SERVICE_HEADER_ERROR_TEXTS", "describe_service_header_error"]


RETURN_CODE_TEXTS: dict[int, str] = {
    0x00: "reserved", 0x01: "hardware error", 0x03: "access to the object not allowed",
    0x05: "invalid address", 0x06: "data type not supported", 0x07: "data type inconsistent",
    0x0A: "object does not exist", 0xFF: "success",
}


class ErrorClass(IntEnum):
    NO_ERROR = 0x00
    APPLICATION_RELATIONSHIP = 0x81
    OBJECT_DEFINITION = 0x82
    NO_RESOURCES = 0x83
    SERVICE_PROCESSING = 0x84
    SUPPLIES = 0x85
    ACCESS = 0x87


HEADER_ERROR_TEXTS: dict[int, str] = {
    0x0000: "no error",
    0x0110: "invalid block number", 0x0111: "invalid request length", 0x0112: "invalid parameter",
    0x0113: "invalid block type", 0x0114: "block not found", 0x0115: "block already exists",
    0x0116: "block is write-protected", 0x0119: "incorrect password entered", 0x011C: "protocol error",
    0x0141: "job cannot be processed for lack of resources",
    0x8001: "service not possible in the block's current status",
    0x8100: "service unknown to the remote module",
    0x8104: "service not implemented on the module or frame error",
    0x8204: "type specification for the object inconsistent",
    0x8301: "insufficient memory", 0x8302: "too few resources available", 0x8305: "function not available",
    0x8401: "invalid service sequence", 0x8402: "service cannot execute owing to the object's status",
    0x8404: "the function cannot be performed", 0x8500: "wrong frames",
    0x8701: "error addressing the object", 0x8702: "service not supported by the module",
    0x8703: "access to object refused", 0x8704: "object damaged",
    0xD201: "syntax error in block name", 0xD202: "syntax error in function parameters",
    0xD401: "invalid SZL ID", 0xD405: "service not supported or syntax error in function parameters",
    0xD601: "syntax error in function parameter", 0xD602: "incorrect password entered",
}

AREA_LETTERS = "NBCATVHM"

NCK_MODULE_NAMES: dict[int, str] = {
    0x10: "Y - Global system data", 0x11: "YNCFL - NCK instruction groups", 0x12: "FU - NCU global settable frames",
    0x13: "FA - Active NCU global frames", 0x14: "TO - Tool data", 0x15: "RP - Arithmetic parameters",
    0x16: "SE - Setting data", 0x17: "SGUD - SGUD-Block", 0x18: "LUD - Local userdata",
    0x19: "TC - Toolholder parameters", 0x1A: "M - Machine data", 0x1C: "WAL - Working area limitation",
    0x1E: "DIAG - Internal diagnostic data", 0x1F: "CC - Unknown", 0x20: "FE - Channel-specific external frame",
    0x21: "TD - Tool data: General data", 0x2D: "MGUD - MGUD-Block", 0x2E: "UGUD - UGUD-Block",
    0x4D: "SD - Servo data", 0x54: "SALUC - Alarm actions", 0x55: "AUXFU - Auxiliary functions",
    0x70: "SEGA - State data: Geometry axes in tool offset memory (extended)",
    0x71: "SEMA - State data: Machine axes (extended)", 0x72: "SSP - State data: Spindle",
    0x73: "SGA - State data: Geometry axes in tool offset memory", 0x74: "SMA - State data: Machine axes",
    0x75: "SALAL - Alarms: List organized according to time", 0x76: "SALAP - Alarms: by priority",
    0x77: "SALA - Alarms: List organized according to time", 0x7A: "SPARPP - Program pointer in automatic operation",
    0x7B: "SNCF - Active G functions", 0x7D: "SPARP - Part program information",
    0x7E: "SINF - Part-program-specific status data", 0x7F: "S - State data",
    0x60: "nckemu extension (no Siemens module)",
}


def describe_return_code(return_code: int) -> str:
    return f"{RETURN_CODE_TEXTS.get(return_code, 'unknown return code')} (0x{return_code:02X})"


def describe_header_error(error_class: int, error_code: int) -> str:
    combined = (error_class << 8) | error_code
    return f"{HEADER_ERROR_TEXTS.get(combined, 'error')} (0x{combined:04X})"


def describe_module(module: int) -> str:
    return NCK_MODULE_NAMES.get(module, f"0x{module:02X}")


# What a header error means to the service that got it. Wireshark's texts (above) are one per code
# across every service; a controller reuses some codes with a service's own meaning: 0xD201, "syntax
# error in block name", is how a PI service or a file transfer says the program or file named does not
# exist. The function codes: 0x28 PI service; 0x1A..0x1C download, 0x1D..0x1F upload (files).
_PI_TEXTS: dict[int, str] = {
    HeaderError.BLOCK_NAME_SYNTAX: "no such program or file",
    HeaderError.PI_PARAMETER_SYNTAX: "wrong number or form of arguments for this PI service",
    HeaderError.WRONG_PASSWORD: "incorrect password entered",
    HeaderError.ACCESS_REFUSED: "the connection's access level is too low for this service (log in first)",
    HeaderError.OBJECT_STATE: "the service cannot run now: the program or file is in use (running or selected)",
    HeaderError.NOT_IMPLEMENTED: "service not implemented on the module: the controller has no such PI service",
    HeaderError.WRONG_FRAMES: "the PI job does not parse (malformed parameters)",
    HeaderError.INVALID_SEQUENCE: "a job before setup communication",
    HeaderError.NO_RESOURCES: "more jobs outstanding than the connection allows",
}
_FILE_TEXTS: dict[int, str] = {
    HeaderError.BLOCK_NAME_SYNTAX: "no such file (or a file name the controller cannot read)",
    HeaderError.ACCESS_REFUSED: "access to the file refused (access level too low)",
    HeaderError.OBJECT_STATE: "the file is in use (running or selected) or the transfer is in the wrong step",
    HeaderError.NOT_IMPLEMENTED: "the controller does not offer this file transfer",
    HeaderError.WRONG_FRAMES: "the transfer job does not parse (malformed parameters)",
    HeaderError.INVALID_SEQUENCE: "a job before setup communication, or a transfer step out of order",
    HeaderError.NO_RESOURCES: "more jobs or transfers outstanding than the controller allows",
}
SERVICE_HEADER_ERROR_TEXTS: dict[int, dict[int, str]] = {
    0x28: _PI_TEXTS, **dict.fromkeys((0x1A, 0x1B, 0x1C, 0x1D, 0x1E, 0x1F), _FILE_TEXTS),
}


def describe_service_header_error(function: int, error_class: int, error_code: int) -> str:
    """A header error worded for the service (S7 function code) that got it, then Wireshark's code."""
    combined = (error_class << 8) | error_code
    text = SERVICE_HEADER_ERROR_TEXTS.get(function, {}).get(combined)
    if text is None:
        return describe_header_error(error_class, error_code)
    return f"{text} (header error 0x{combined:04X})"
