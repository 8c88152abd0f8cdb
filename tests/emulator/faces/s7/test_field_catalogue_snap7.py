"""python-snap7 against the real server: what field collectors read, as raw PDUs through
``Client.iso_exchange_buffer`` (our own bytes; the facts behind them are in
tests/emulator/faces/s7/test_field_catalogue.py and nckemu/catalogue/variables.toml)."""

from __future__ import annotations

import struct

import snap7

from nckemu.emulator.runner import EmulatorThread


def item(au: int, column: int, line: int, module: int, count: int = 1) -> bytes:
    return bytes([0x12, 0x08, 0x82, au]) + struct.pack(">HHBB", column, line, module, count)


def read(collector: snap7.Client, *items: bytes) -> list[tuple[int, bytes]]:
    parameter = bytes([0x04, len(items)]) + b"".join(items)
    answer = bytes(collector.iso_exchange_buffer(bytearray(
        struct.pack(">BBHHHH", 0x32, 1, 0, 0x0100, len(parameter), 0) + parameter)))
    assert answer[1] == 3 and answer[10:12] == b"\x00\x00" and answer[12:14] == bytes([4, len(items)])
    offset, out = 14, []
    for index in range(len(items)):
        rc, ts, length = answer[offset], answer[offset + 1], struct.unpack(">H", answer[offset + 2:offset + 4])[0]
        assert rc != 0xFF or ts == 0x09
        out.append((rc, answer[offset + 4:offset + 4 + length]))
        offset += 4 + length + (length % 2 if index < len(items) - 1 else 0)
    assert offset == len(answer)
    return out


def test_828d_tsaps_and_the_diagn_connect_probe(collector: snap7.Client) -> None:
    ((rc, data),) = read(collector, item(0x01, 0x14, 1, 0x3B))
    assert rc == 0xFF and len(data) == 2


def test_strings_real8_multi_line_and_multi_item(collector: snap7.Client) -> None:
    serial, versions, positions, chan, prog, parts = read(
        collector, item(0x01, 18030, 1, 0x1A), item(0x01, 18040, 1, 0x1A, 4), item(0x41, 2, 1, 0x74, 3),
        item(0x41, 0x0B, 1, 0x7F), item(0x41, 0x0D, 1, 0x7F), item(0x41, 0x79, 1, 0x7F))
    assert serial[0] == 0xFF and len(serial[1]) == 32
    assert versions[0] == 0xFF and len(versions[1]) == 80
    assert len(struct.unpack("<3d", positions[1])) == 3
    assert (chan[1], prog[1]) == (b"\x00\x00", b"\x05\x00")
    assert struct.unpack("<d", parts[1]) == (0.0,)


def test_alarm_list_and_unknown_addresses(emulator: EmulatorThread, collector: snap7.Client) -> None:
    emulator.call(lambda: emulator.nck.alarm_list.raise_alarm("test alarm", 700123))
    count, number, unknown = read(collector, item(0x01, 7, 1, 0x7F), item(0x01, 2, 1, 0x77),
                                  item(0x41, 0x1FF, 1, 0x7F))
    assert count[1] == b"\x01\x00" and number[1] == struct.pack("<i", 700123)
    assert unknown == (0x0A, b"")
