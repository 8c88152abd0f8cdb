"""The codecs' errors, beside the codecs: bytes that are not a valid frame or PDU.

``NckProtocolError`` and ``NckTruncatedError`` are defined with the whole hierarchy in
``nckemu.errors`` (the bottom of the package, the only module of ours that ``protocol/`` imports), so
that module imports nothing back. The other names are re-exported so that code written against
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
    NckProtocolError,
    NckServiceError,
    NckTimeoutError,
    NckTruncatedError,
    NckTypeInconsistent,
    NckTypeNotSupported,
    ReturnCode,
    item_error_for,
    service_error_for,
)
