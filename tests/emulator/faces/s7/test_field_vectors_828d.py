"""The 828D vectors (../shared/field/vectors_828d.txt): request/response pairs a real SINUMERIK 828D
answered, replayed against the emulator. Each answer item must match the 828D's in return code,
transport size and length (the values are the machine's state, not the emulator's)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
import snap7

VECTORS = "field/vectors_828d.txt"
PDU_OFFSET = 7  # TPKT (4) and COTP DT (3) before the S7 PDU


def read_pairs(path: Path) -> list[tuple[bytes, bytes]]:
    lines = [line.split() for line in path.read_text().splitlines() if line[:4] in ("REQ ", "RSP ")]
    assert [kind for kind, _hex in lines] == ["REQ", "RSP"] * (len(lines) // 2), "REQ and RSP alternate"
    return [(bytes.fromhex(lines[i][1]), bytes.fromhex(lines[i + 1][1])) for i in range(0, len(lines), 2)]


def answer_shapes(pdu: bytes) -> list[tuple[int, int, int]]:
    """(return code, transport size, data length in bytes) of each item of a read-var answer PDU."""
    parameter_length, data_length = struct.unpack_from(">HH", pdu, 6)
    offset = 12 + parameter_length  # header 10, error class and code 2
    count = pdu[13]
    shapes = []
    for index in range(count):
        return_code, transport_size, length = pdu[offset], pdu[offset + 1], struct.unpack_from(">H", pdu, offset + 2)[0]
        if return_code != 0xFF:
            length = 0
        elif transport_size not in (0x07, 0x09):
            length //= 8  # a length in bits
        shapes.append((return_code, transport_size, length))
        offset += 4 + length + (length & 1 if index + 1 < count else 0)
    assert offset == 12 + parameter_length + data_length, pdu.hex()
    return shapes


@pytest.fixture
def vectors(shared_dir: Path) -> list[tuple[bytes, bytes]]:
    path = shared_dir / VECTORS
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    return read_pairs(path)


def test_every_828d_item_is_answered_alike(vectors: list[tuple[bytes, bytes]], collector: snap7.Client) -> None:
    items = alike = 0
    differing = []
    for request, response in vectors:
        answer = bytes(collector.iso_exchange_buffer(bytearray(request[PDU_OFFSET:])))
        want, got = answer_shapes(response[PDU_OFFSET:]), answer_shapes(answer)
        assert len(got) == len(want), request.hex()
        for recorded, emulated in zip(want, got, strict=True):
            items += 1
            if recorded == emulated:
                alike += 1
            else:
                differing.append((request.hex(), recorded, emulated))
    assert (len(vectors), items) == (28, 39)
    assert alike == items, differing
