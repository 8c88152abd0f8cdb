"""Which monitored PLC items a write touches: the face's range index against plain overlap."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from nckemu.catalogue.node_ids import PlcNodeName
from nckemu.emulator.faces.opcua.monitoring import _Monitored, _PlcIndex
from nckemu.protocol.addresses import S7Area

KINDS = {"BYTE": 1, "WORD": 2, "DWORD": 4, "REAL": 4, "BOOL": 1, "STRING": 1}

items = st.builds(
    lambda area, db, byte, kind, count: PlcNodeName(area, db if area == "DB" else 0, byte,
                                                    0 if kind == "BOOL" else None, kind,
                                                    1 if kind in ("BOOL", "STRING") else count, count > 1),
    st.sampled_from(["DB", "M", "I", "Q"]), st.integers(1, 3), st.integers(0, 600),
    st.sampled_from(sorted(KINDS)), st.integers(1, 40))
writes = st.tuples(st.sampled_from([(S7Area.DB, 1), (S7Area.DB, 2), (S7Area.M, 0), (S7Area.Q, 0)]),
                   st.integers(0, 700), st.integers(1, 300))


def _monitored(name: PlcNodeName) -> _Monitored:
    return _Monitored(None, name, lambda: b"")  # type: ignore[arg-type]  # only the byte range is used


@given(st.lists(items, max_size=40), writes)
def test_a_write_touches_exactly_the_items_it_overlaps(names: list[PlcNodeName],
                                                       write: tuple[tuple[int, int], int, int]) -> None:
    (area, db), first, size = write
    entries = [_monitored(name) for name in names]
    expected = {id(entry) for entry in entries
                if entry.block == (area, db if area == S7Area.DB else 0)
                and entry.first_byte < first + size and entry.end_byte > first}
    touched = _PlcIndex(entries).touched(area, db, first, first + size)
    assert {id(entry) for entry in touched} == expected
    assert len(touched) == len(expected)


def test_a_string_is_touched_anywhere_in_its_characters() -> None:
    entry = _monitored(PlcNodeName("DB", 8, 2, None, "STRING", 1, False))
    index = _PlcIndex([entry])
    assert index.touched(S7Area.DB, 8, 200, 201) == [entry]
    assert index.touched(S7Area.DB, 8, 0, 2) == []
    assert index.touched(S7Area.DB, 9, 2, 3) == []
