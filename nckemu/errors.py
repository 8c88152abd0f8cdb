"""Re-export of the error hierarchy (it lives in ``nckemu.protocol.errors``)."""

from nckemu.protocol.errors import *  # noqa: F403
from nckemu.protocol.errors import (  # noqa: F401
    ITEM_ERRORS_BY_CODE,
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
    item_error_for,
)
