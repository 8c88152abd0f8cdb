"""The one error hierarchy of nckemu.

Every error carries what a real controller would answer, so the server can turn any exception in a
job into a protocol answer and a client can raise exactly what the controller said:

* ``error_class`` / ``error_code``: the S7 header error (ack / ack_data), e.g. 0x85/0x00 "wrong frames";
* ``return_code``: the per-item return code of a read/write item, e.g. 0x0A "object does not exist";
* ``state``: the FB2/FB3/FB4 ``State`` word a PLC block would show (assumed values, see clients).

This module lives in ``protocol/`` because the codecs raise it and ``protocol/`` imports nothing
from the rest of the project; ``nckemu.errors`` re-exports it.
"""

from __future__ import annotations


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


class NckProtocolError(NckError):
    """Bytes that are not a valid frame or PDU (answered with 0x85/0x00, wrong frames)."""

    error_class = 0x85
    error_code = 0x00


class NckTruncatedError(NckProtocolError):
    """The bytes end before the structure they announce."""


class NckServiceError(NckError):
    """A job the controller refuses as a whole: the answer carries a header error class/code."""

    error_class = 0x81
    error_code = 0x04


class NckItemError(NckError):
    """One item of a read/write job fails; the other items of the job are unaffected."""

    return_code = 0x05


class NckHardwareError(NckItemError):
    """Item return code 0x01: hardware error."""

    return_code = 0x01


class NckAccessDenied(NckItemError):
    """Item return code 0x03: accessing the object not allowed (e.g. protection level too low)."""

    return_code = 0x03


class NckAddressOutOfRange(NckItemError):
    """Item return code 0x05: invalid address (line, count or offset beyond the object)."""

    return_code = 0x05


class NckTypeNotSupported(NckItemError):
    """Item return code 0x06: data type not supported."""

    return_code = 0x06


class NckTypeInconsistent(NckItemError):
    """Item return code 0x07: data type inconsistent (e.g. wrong length written)."""

    return_code = 0x07


class NckObjectDoesNotExist(NckItemError):
    """Item return code 0x0A: object does not exist (unknown module, column, DB, syntax ID)."""

    return_code = 0x0A


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
    cls.return_code: cls  # type: ignore[misc]
    for cls in (NckHardwareError, NckAccessDenied, NckAddressOutOfRange, NckTypeNotSupported,
                NckTypeInconsistent, NckObjectDoesNotExist)
}


def item_error_for(return_code: int, message: str = "") -> NckItemError:
    """The typed item error for a return code read off the wire."""
    cls = ITEM_ERRORS_BY_CODE.get(return_code, NckItemError)
    return cls(message or f"item return code 0x{return_code:02X}", return_code=return_code)
