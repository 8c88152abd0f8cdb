"""The one error hierarchy of nckemu, at the bottom of the package (it imports nothing of ours).

Every error carries what a real controller would answer, so the server can turn any exception in a
job into a protocol answer and a client can raise exactly what the controller said:

* ``error_class`` / ``error_code``: the S7 header error of an ack/ack_data (``HeaderError``);
* ``return_code``: the per-item return code of a read/write item (``ReturnCode``);
* ``state``: the FB2/FB3/FB4 ``State`` word a PLC block would show (assumed values, see clients).

Errors about malformed bytes (``NckProtocolError``, ``NckTruncatedError``) are the codecs' own; they
are defined here with the rest and ``nckemu.protocol.errors`` names them beside the codecs.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Any


class ReturnCode(IntEnum):
    """Item return codes of read/write-var answers."""

    RESERVED = 0x00
    HARDWARE_ERROR = 0x01
    ACCESS_DENIED = 0x03
    INVALID_ADDRESS = 0x05
    DATA_TYPE_NOT_SUPPORTED = 0x06
    DATA_TYPE_INCONSISTENT = 0x07
    OBJECT_DOES_NOT_EXIST = 0x0A
    SUCCESS = 0xFF


class HeaderError(IntEnum):
    """S7 header errors (class << 8 | code) that nckemu answers or expects; texts in protocol.codes."""

    NONE = 0x0000
    NOT_IMPLEMENTED = 0x8104       # service not implemented on the module, or frame error
    NO_RESOURCES = 0x8302          # too few resources (more jobs than the granted AMQ)
    INVALID_SEQUENCE = 0x8401      # a job before setup communication
    OBJECT_STATE = 0x8402          # service cannot execute owing to the object's status
    WRONG_FRAMES = 0x8500          # a job whose parameters do not parse, or a PDU over the size
    ACCESS_REFUSED = 0x8703        # access to the object refused (protection level)
    BLOCK_NAME_SYNTAX = 0xD201     # syntax error in block name (no such program or file)
    PI_PARAMETER_SYNTAX = 0xD405   # syntax error in function parameters
    WRONG_PASSWORD = 0xD602        # incorrect password entered

    @property
    def error_class(self) -> int:
        return self.value >> 8

    @property
    def error_code(self) -> int:
        return self.value & 0xFF


class NckError(Exception):
    """Root of all nckemu errors."""

    error_class: int = 0x00
    error_code: int = 0x00
    return_code: int | None = None

    def __init__(
        self,
        message: str = "",
        *,
        error_class: int | None = None,
        error_code: int | None = None,
        return_code: int | None = None,
    ) -> None:
        super().__init__(message or self.__class__.__doc__ or self.__class__.__name__)
        if error_class is not None:
            self.error_class = error_class
        if error_code is not None:
            self.error_code = error_code
        if return_code is not None:
            self.return_code = return_code

    @property
    def header_error(self) -> int:
        """Class and code as the 16-bit value Wireshark shows (``s7comm.param.errcod``)."""
        return (self.error_class << 8) | self.error_code


class NckServiceError(NckError):
    """A job the controller refuses as a whole: the answer carries a header error class/code."""

    error_class = HeaderError.NOT_IMPLEMENTED.error_class
    error_code = HeaderError.NOT_IMPLEMENTED.error_code

    def __init_subclass__(cls, header: HeaderError | None = None, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if header is not None:
            cls.error_class, cls.error_code = header.error_class, header.error_code


class NckInvalidSequence(NckServiceError, header=HeaderError.INVALID_SEQUENCE):
    """0x8401: the job is not allowed in the connection's state (e.g. before setup communication)."""


class NckNoResources(NckServiceError, header=HeaderError.NO_RESOURCES):
    """0x8302: more jobs outstanding than the granted AMQ."""


class NckWrongFrames(NckServiceError, header=HeaderError.WRONG_FRAMES):
    """0x8500: the job's parameters do not parse, or the PDU exceeds the negotiated size."""


class NckPiStateError(NckServiceError, header=HeaderError.OBJECT_STATE):
    """0x8402: the PI service cannot run in the object's current state."""


class NckPiAccessRefused(NckServiceError, header=HeaderError.ACCESS_REFUSED):
    """0x8703: the connection's access level does not allow the PI service."""


class NckNoSuchFile(NckServiceError, header=HeaderError.BLOCK_NAME_SYNTAX):
    """0xD201: the program or file named by a PI service does not exist."""


class NckPiBadArguments(NckServiceError, header=HeaderError.PI_PARAMETER_SYNTAX):
    """0xD405: a PI service got the wrong number or form of arguments."""


class NckWrongPassword(NckServiceError, header=HeaderError.WRONG_PASSWORD):
    """0xD602: the password given to a login PI service is not known."""


class NckItemError(NckError):
    """One item of a read/write job fails; the other items of the job are unaffected."""

    return_code = ReturnCode.INVALID_ADDRESS


class NckHardwareError(NckItemError):
    """Item return code 0x01: hardware error."""

    return_code = ReturnCode.HARDWARE_ERROR


class NckAccessDenied(NckItemError):
    """Item return code 0x03: accessing the object not allowed (e.g. protection level too low)."""

    return_code = ReturnCode.ACCESS_DENIED


class NckAddressOutOfRange(NckItemError):
    """Item return code 0x05: invalid address (line, count or offset beyond the object)."""

    return_code = ReturnCode.INVALID_ADDRESS


class NckTypeNotSupported(NckItemError):
    """Item return code 0x06: data type not supported."""

    return_code = ReturnCode.DATA_TYPE_NOT_SUPPORTED


class NckTypeInconsistent(NckItemError):
    """Item return code 0x07: data type inconsistent (e.g. wrong length written)."""

    return_code = ReturnCode.DATA_TYPE_INCONSISTENT


class NckObjectDoesNotExist(NckItemError):
    """Item return code 0x0A: object does not exist (unknown module, column, DB, syntax ID)."""

    return_code = ReturnCode.OBJECT_DOES_NOT_EXIST


class NckConnectionError(NckError):
    """The connection to the controller failed or was lost."""


class NckTimeoutError(NckConnectionError):
    """The controller did not answer in time."""


class NckConfigError(NckError):
    """A configuration or input file is wrong; the message names the file, line and field."""

    def __init__(self, message: str, *, path: str | None = None, line: int | None = None,
                 field: str | None = None) -> None:
        where = ", ".join(
            part for part in (
                path,
                f"line {line}" if line is not None else None,
                f"field {field!r}" if field is not None else None,
            ) if part
        )
        super().__init__(f"{where}: {message}" if where else message)
        self.path = path
        self.line = line
        self.field = field


ITEM_ERRORS_BY_CODE: dict[int, type[NckItemError]] = {
    int(cls.return_code): cls  # type: ignore[arg-type]
    for cls in (NckHardwareError, NckAccessDenied, NckAddressOutOfRange, NckTypeNotSupported,
                NckTypeInconsistent, NckObjectDoesNotExist)
}

SERVICE_ERRORS_BY_HEADER: dict[int, type[NckServiceError]] = {
    (cls.error_class << 8) | cls.error_code: cls
    for cls in (NckInvalidSequence, NckNoResources, NckWrongFrames, NckPiStateError, NckPiAccessRefused,
                NckNoSuchFile, NckPiBadArguments, NckWrongPassword)
}


def item_error_for(return_code: int, message: str = "") -> NckItemError:
    """The typed item error for a return code read off the wire."""
    cls = ITEM_ERRORS_BY_CODE.get(return_code, NckItemError)
    return cls(message or f"item return code 0x{return_code:02X}", return_code=return_code)


def service_error_for(error_class: int, error_code: int, message: str = "") -> NckServiceError:
    """The typed service error for a header error read off the wire (NckServiceError if unnamed)."""
    cls = SERVICE_ERRORS_BY_HEADER.get((error_class << 8) | error_code, NckServiceError)
    return cls(message, error_class=error_class, error_code=error_code)


class NckProtocolError(NckError):
    """Bytes that are not a valid frame or PDU (answered with 0x85/0x00, wrong frames)."""

    error_class = HeaderError.WRONG_FRAMES.error_class
    error_code = HeaderError.WRONG_FRAMES.error_code


class NckTruncatedError(NckProtocolError):
    """The bytes end before the structure they announce."""


class NckNodeIdError(NckError):
    """An OPC UA node id in SINUMERIK syntax that names nothing (``ua_status``: the answer's status)."""

    ua_status = "BadNodeIdUnknown"


class NckNodeIdUnknown(NckNodeIdError):
    """Not a SINUMERIK node id: malformed, or outside the controller's namespaces."""


class NckNodeNotConfigured(NckNodeIdError):
    """A well-formed SINUMERIK variable this machine lacks (the controller answers BadAttributeIdInvalid)."""

    ua_status = "BadAttributeIdInvalid"
