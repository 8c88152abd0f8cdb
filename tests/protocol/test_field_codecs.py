"""The codecs of what real S7 devices send: userdata parameters of every group, block transfer parameters,
PI block lists; parse(build(v)) == v, build(parse(x)) == x, garbage raises only our typed errors; error
items with a length carry no data."""

from __future__ import annotations

import struct

from hypothesis import given
from hypothesis import strategies as st

from nckemu.errors import NckProtocolError
from nckemu.protocol import blocks, s7, userdata

u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)

userdata_parameters = st.one_of(
    st.builds(userdata.UserdataParameter, method=u8, type=st.integers(0, 15), group=st.integers(0, 15),
              subfunction=u8, sequence=u8),
    st.builds(userdata.UserdataParameter, method=u8, type=st.integers(0, 15), group=st.integers(0, 15),
              subfunction=u8, sequence=u8, long=st.just(True), data_unit_ref=u8, last_data_unit=u8,
              error_code=u16),
    # a STEP 7 CPU's mode-transition push: head 01 00 10
    st.builds(userdata.UserdataParameter, method=u8, type=st.integers(0, 15), group=st.integers(0, 15),
              subfunction=u8, sequence=u8, head=st.just(userdata.MODE_TRANSITION_HEAD)))

ascii_text = st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=40)
block_controls = st.one_of(
    st.builds(blocks.BlockControl, function=st.sampled_from(sorted(blocks.FUNCTIONS))),
    st.builds(blocks.BlockControl, function=st.sampled_from(sorted(blocks.FUNCTIONS)), status=u8),
    st.builds(blocks.BlockControl, function=st.sampled_from(sorted(blocks.FUNCTIONS)), status=u8, error_code=u16,
              session=st.integers(0, 0xFFFFFFFF)),
    st.builds(blocks.BlockControl, function=st.sampled_from(sorted(blocks.FUNCTIONS)), status=u8, error_code=u16,
              session=st.integers(0, 0xFFFFFFFF), file_name=ascii_text),
    st.builds(blocks.BlockControl, function=st.sampled_from(sorted(blocks.FUNCTIONS)), status=u8, error_code=u16,
              session=st.integers(0, 0xFFFFFFFF), file_name=ascii_text, part2=ascii_text))

block_names = st.builds(blocks.BlockName, block_type=st.sampled_from(sorted(blocks.BLOCK_TYPE_NAMES)),
                        number=st.integers(0, 99999), file_system=st.sampled_from("PAB"))


@given(userdata_parameters)
def test_userdata_parameter_round_trip(parameter: userdata.UserdataParameter) -> None:
    raw = userdata.build_userdata_parameter(parameter)
    assert userdata.parse_userdata_parameter(raw) == parameter
    assert userdata.build_userdata_parameter(userdata.parse_userdata_parameter(raw)) == raw


@given(st.one_of(st.binary(max_size=16), st.binary(min_size=5, max_size=5).map(lambda b: b"\x01\x00\x10" + b)))
def test_userdata_garbage_raises_typed_errors(raw: bytes) -> None:
    try:
        parameter = userdata.parse_userdata_parameter(raw)
    except NckProtocolError:
        return
    assert userdata.build_userdata_parameter(parameter) == raw


@given(st.integers(0, 15), u8)
def test_every_group_and_subfunction_has_a_name(group: int, subfunction: int) -> None:
    name = userdata.describe(group, subfunction)
    assert name.startswith(userdata.group_name(group))


@given(block_controls)
def test_block_control_round_trip(control: blocks.BlockControl) -> None:
    raw = blocks.build_block_control(control)
    assert blocks.parse_block_control(raw) == control
    assert blocks.build_block_control(blocks.parse_block_control(raw)) == raw


@given(st.binary(max_size=40))
def test_block_control_garbage_raises_typed_errors(raw: bytes) -> None:
    try:
        control = blocks.parse_block_control(raw)
    except NckProtocolError:
        return
    assert blocks.build_block_control(control) == raw
    blocks.describe_block_control(control)


@given(block_names, st.sampled_from(["", "_", "$"]))
def test_block_name_round_trip(name: blocks.BlockName, ident: str) -> None:
    name = blocks.BlockName(name.block_type, name.number, name.file_system, ident)
    text = blocks.build_block_name(name)
    assert len(text) == 8 + len(ident)
    assert blocks.parse_block_name(text) == name


@given(st.lists(block_names, max_size=10))
def test_block_list_round_trip(names: list[blocks.BlockName]) -> None:
    raw = blocks.build_block_list(tuple(names))
    assert blocks.parse_block_list(raw) == tuple(names)
    assert blocks.build_block_list(blocks.parse_block_list(raw)) == raw


@given(st.binary(max_size=40))
def test_block_list_garbage_raises_typed_errors(raw: bytes) -> None:
    try:
        names = blocks.parse_block_list(raw)
    except NckProtocolError:
        return
    assert len(raw) == 2 + 8 * len(names)


@given(st.lists(st.tuples(st.sampled_from([0x01, 0x03, 0x05, 0x06, 0x07, 0x0A]), u8, u16), min_size=1, max_size=8),
       st.binary(min_size=1, max_size=8))
def test_error_items_carry_no_data_whatever_their_length(errors: list[tuple[int, int, int]], value: bytes) -> None:
    """A real S7-300 answers ``0A 00 00 04`` with no data after it; a good item after error items is read
    right where their headers end."""
    data = b"".join(struct.pack(">BBH", code, size, length) for code, size, length in errors)
    good = s7.DataItem(0xFF, 0x09, value)
    answer = s7.parse_read_var_response(bytes([0x04, len(errors) + 1]), data + s7.build_data_items((good,)))
    assert answer.items == tuple(s7.DataItem(code, size, b"") for code, size, _length in errors) + (good,)
