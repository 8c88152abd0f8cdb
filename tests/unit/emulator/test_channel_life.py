"""The channel's program life table (nck/channel_life.py): every place is reachable from reset, every
place can be reset and ended, and only the channel moves along it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.machine.nck.channel_life import TRANSITIONS, Event, Life, LifeError, next_life
from nckemu.emulator.machine.nck.channel_states import CHAN_RESET, PROG_ABORTED

PACKAGE = Path(__file__).resolve().parents[3] / "nckemu"


def test_every_place_is_reached_from_reset_and_left_by_reset_and_end() -> None:
    reached, frontier = {Life.RESET}, [Life.RESET]
    while frontier:
        where = frontier.pop()
        for (source, _event), (target, _told) in TRANSITIONS.items():
            if source is where and target not in reached:
                reached.add(target)
                frontier.append(target)
    assert reached == set(Life)
    for where in Life:
        assert next_life(where, Event.END)[0] is Life.ENDED
        assert next_life(where, Event.RESET)[0].at_rest


def test_reset_and_ended_report_alike_as_btss_does() -> None:
    assert Life.RESET.reported == Life.ENDED.reported == (CHAN_RESET, PROG_ABORTED)
    assert len({life.reported for life in Life}) == len(Life) - 1


@given(st.sampled_from(list(Life)), st.sampled_from(list(Event)))
def test_a_change_is_in_the_table_or_an_error(where: Life, event: Event) -> None:
    if (where, event) in TRANSITIONS:
        target, told = next_life(where, event)
        assert target in Life and (told is None or told in ("started", "resumed", "interrupted", "ended", "aborted"))
    else:
        with pytest.raises(LifeError):
            next_life(where, event)


def test_only_the_channel_writes_its_status() -> None:
    writes = re.compile(r"\.(?:status|program_status)\s*(?:,[^=\n]*)?=(?!=)")
    writers = {path.relative_to(PACKAGE).as_posix() for path in PACKAGE.rglob("*.py")
               if any(writes.search(line) and "state." in line for line in path.read_text(encoding="utf-8").splitlines())}
    assert writers <= {"emulator/machine/nck/channel.py"}, writers
