"""The session's transition table on its own, without bytes (as h11's tests drive ``ConnectionState``)."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.faces.s7.session import _TRANSITIONS, Event, SessionState, next_state
from nckemu.errors import HeaderError

S = SessionState


@pytest.mark.parametrize(("state", "event", "expected"), [
    (S.WAIT_CONNECT, Event.CONNECT_REQUEST, S.CONNECTED),
    (S.WAIT_CONNECT, Event.DATA, S.CLOSED),
    (S.WAIT_CONNECT, Event.DISCONNECT_REQUEST, S.CLOSED),
    (S.CONNECTED, Event.SETUP, S.READY),
    (S.CONNECTED, Event.JOB, HeaderError.INVALID_SEQUENCE),
    (S.CONNECTED, Event.CONNECT_REQUEST, S.CLOSED),
    (S.READY, Event.JOB, S.READY),
    (S.READY, Event.SETUP, S.READY),
    (S.READY, Event.CONNECT_REQUEST, S.CLOSED),
    (S.READY, Event.DISCONNECT_REQUEST, S.CLOSED),
])
def test_policy(state: SessionState, event: Event, expected: object) -> None:
    assert next_state(state, event) == expected


def test_closed_takes_nothing() -> None:
    assert all(next_state(S.CLOSED, event) is S.CLOSED for event in Event)
    assert not any(state is S.CLOSED for state, _event in _TRANSITIONS)


def test_every_pair_has_an_answer() -> None:
    for state, event in itertools.product(S, Event):
        assert isinstance(next_state(state, event), SessionState | HeaderError)


@given(st.lists(st.sampled_from(list(Event)), max_size=30))
def test_ready_only_through_setup_and_never_back(events: list[Event]) -> None:
    """READY is reached only by a setup communication after a connect, and no event leads from
    READY or CONNECTED back to WAIT_CONNECT; once CLOSED, always CLOSED."""
    state = S.WAIT_CONNECT
    seen_setup_after_connect = False
    for event in events:
        outcome = next_state(state, event)
        if isinstance(outcome, HeaderError):
            assert state is S.CONNECTED and event is Event.JOB
            continue
        if outcome is S.READY and state is not S.READY:
            assert event is Event.SETUP and state is S.CONNECTED
            seen_setup_after_connect = True
        assert not (state is not S.WAIT_CONNECT and outcome is S.WAIT_CONNECT)
        if state is S.CLOSED:
            assert outcome is S.CLOSED
        state = outcome
    if state is S.READY:
        assert seen_setup_after_connect
