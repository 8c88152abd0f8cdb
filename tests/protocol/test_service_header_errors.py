"""Every header error a PI service or a file transfer answers is worded for that service (issue 44):
0xD201 from _N_SELECT is "no such program", not Wireshark's "syntax error in block name"."""

from __future__ import annotations

import pytest

from nckemu import errors
from nckemu.protocol.codes import SERVICE_HEADER_ERROR_TEXTS, describe_service_header_error

PI, FILE_FUNCTIONS = 0x28, (0x1A, 0x1B, 0x1C, 0x1D, 0x1E, 0x1F)
SERVICE_ERRORS = [cls for cls in vars(errors).values()
                  if isinstance(cls, type) and issubclass(cls, errors.NckServiceError) and cls is not errors.NckServiceError]


@pytest.mark.parametrize("error", SERVICE_ERRORS, ids=lambda cls: cls.__name__)
def test_every_header_error_the_emulator_raises_has_a_pi_wording(error: type[errors.NckServiceError]) -> None:
    instance = error()
    text = describe_service_header_error(PI, instance.error_class, instance.error_code)
    assert instance.header_error in SERVICE_HEADER_ERROR_TEXTS[PI]
    assert "syntax error in block name" not in text and f"0x{instance.header_error:04X}" in text


@pytest.mark.parametrize("function", FILE_FUNCTIONS)
def test_file_transfers_say_no_such_file(function: int) -> None:
    missing = errors.NckNoSuchFile()
    text = describe_service_header_error(function, missing.error_class, missing.error_code)
    assert text.startswith("no such file") and "0xD201" in text
    in_use = errors.NckPiStateError()
    assert "in use" in describe_service_header_error(function, in_use.error_class, in_use.error_code)


def test_pi_no_such_program_and_other_functions_keep_wiresharks_text() -> None:
    assert describe_service_header_error(PI, 0xD2, 0x01) == "no such program or file (header error 0xD201)"
    assert describe_service_header_error(0x04, 0xD2, 0x01).startswith("syntax error in block name")
