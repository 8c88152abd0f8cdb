"""Wire-specific errors: bytes that are not a valid frame or PDU.

They subclass the one hierarchy in ``nckemu.errors`` (the bottom of the package, the only module of
ours that ``protocol/`` imports). The other names are re-exported so that code written against
``nckemu.protocol.errors`` before 0.2 keeps working.
"""

from __future__ import annotations

from nckemu.errors import *  # noqa: F403
from nckemu.errors import (  # noqa: F401
    ITEM_ERRORS_BY_CODE,
    HeaderError,
    NckAccessDenied,
    NckAddressOutOfRange,
    NckConfigError,
    NckConnectionError,
    NckError,
    NckHardwareError,
    NckItemError,
    NckObjectDoesNotExist,
    NckServiceError,
    NckTimeoutError,
    NckTypeInconsistent,
    NckTypeNotSupported,
    ReturnCode,
    item_error_for,
    service_error_for,
)


class NckProtocolError(NckError):
    """Bytes that are not a valid frame or PDU (answered with 0x85/0x00, wrong frames)."""

    error_class = HeaderError.WRONG_FRAMES.error_class
    error_code = HeaderError.WRONG_FRAMES.error_code


class NckTruncatedError(NckProtocolError):
    """The bytes end before the structure they announce."""
