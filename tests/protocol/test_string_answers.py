"""STRING items: the controller's answer shows any text (Latin-1, '?' outside it, cut at the field's
end); a client's write refuses what the field cannot hold as given."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.errors import NckTypeInconsistent
from nckemu.protocol.addresses import NckType
from nckemu.protocol.values import decode_nck_values, encode_nck_values


def test_an_answer_replaces_what_latin1_lacks_and_cuts_at_the_field() -> None:
    raw = encode_nck_values(NckType.STRING, ["Warmlauf 20 → 25 °C"], area=2, string_length=32, answer=True)
    assert raw == b"Warmlauf 20 ? 25 \xb0C".ljust(32, b"\x00")
    assert encode_nck_values(NckType.STRING, ["x" * 40], area=2, string_length=8, answer=True) == b"x" * 8


def test_a_write_refuses_what_the_field_cannot_hold() -> None:
    with pytest.raises(NckTypeInconsistent, match="Latin-1"):
        encode_nck_values(NckType.STRING, ["20 → 25"], area=2, string_length=32)
    with pytest.raises(NckTypeInconsistent):
        encode_nck_values(NckType.STRING, ["x" * 40], area=2, string_length=8)


@given(st.text(max_size=80))
def test_any_text_makes_an_answer_of_the_fields_size(text: str) -> None:
    raw = encode_nck_values(NckType.STRING, [text], area=2, string_length=66, answer=True)
    assert len(raw) == 66
    shown = decode_nck_values(NckType.STRING, raw, area=2, string_length=66)[0]
    expected = text.encode("latin-1", errors="replace")[:66].split(b"\x00", 1)[0].decode("latin-1")
    assert shown == expected
