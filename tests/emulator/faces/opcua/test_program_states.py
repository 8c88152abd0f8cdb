"""The umati program and job state machines (opcua/program_states.py) against OPC 40501-1's NodeSet.

Whatever a channel does, in any order, every transition taken is one the MachineTool NodeSet declares
for that state machine type (its FromState and ToState references, read with ElementTree from the file
as published), the transitions chain, and the machine ends in the state the last one reached. The fixed
sequences are a program's life as the issue lists it: power-on, select, start, M0, resume, end, reset.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nckemu.emulator.faces.opcua import nodesets
from nckemu.emulator.faces.opcua.program_states import (
    CHANNEL_EVENTS,
    INITIALIZING,
    ChannelLook,
    JobStates,
    ProgramStates,
    Step,
    events_between,
)

_NS = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
Transitions = dict[str, tuple[str, str]]


def _transitions(type_name: str) -> tuple[Transitions, set[str], str]:
    """A state machine type's transitions (name -> from, to), its states and its initial state, with
    those its supertypes declare, from the MachineTool NodeSet file."""
    directory = nodesets.find()
    if directory is None:
        pytest.skip(nodesets.how_to_get())
    root = ET.parse(directory / "Opc.Ua.MachineTool.NodeSet2.xml").getroot()
    nodes = {element.get("NodeId"): element for element in root if element.get("NodeId")}
    aliases = {alias.get("Alias"): alias.text for alias in root.iter(_NS + "Alias")}

    def refs(element: ET.Element) -> list[tuple[str, bool, str]]:
        found = element.find(_NS + "References")
        return [(aliases.get(ref.get("ReferenceType"), ref.get("ReferenceType")) or "",
                 ref.get("IsForward", "true") != "false", (ref.text or "").strip()) for ref in found or []]

    def name(node_id: str) -> str:
        return nodes[node_id].get("BrowseName", "").split(":", 1)[-1]

    type_id = next(key for key, element in nodes.items() if name(key) == type_name
                   and element.tag == _NS + "UAObjectType")
    transitions: Transitions = {}
    states: set[str] = set()
    initial = ""
    current: str | None = type_id
    while current in nodes:
        for reference, forward, target in refs(nodes[current]):
            if reference not in ("HasComponent", "i=47") or not forward or target not in nodes:
                continue
            child = nodes[target]
            child_refs = refs(child)
            type_definition = next((t for r, f, t in child_refs if r in ("HasTypeDefinition", "i=40") and f), "")
            if type_definition == "i=2310":     # TransitionType
                ends = {r: name(t) for r, f, t in child_refs if f and r in ("FromState", "ToState", "i=51", "i=52")}
                transitions.setdefault(name(target), (ends.get("FromState", ends.get("i=51", "")),
                                                      ends.get("ToState", ends.get("i=52", ""))))
            elif type_definition in ("i=2307", "i=2309"):   # StateType, InitialStateType
                states.add(name(target))
                if type_definition == "i=2309":
                    initial = name(target)
        current = next((t for r, f, t in refs(nodes[current]) if r in ("HasSubtype", "i=45") and not f), None)
    assert transitions and states and initial, type_name  # the file was read, not an empty match
    return transitions, states, initial


@pytest.fixture(scope="module")
def program_type() -> tuple[Transitions, set[str], str]:
    return _transitions("ProductionProgramStateMachineType")


@pytest.fixture(scope="module")
def job_type() -> tuple[Transitions, set[str], str]:
    return _transitions("ProductionJobStateMachineType")


def _legal(steps: list[Step], before: str, after: str, transitions: Transitions) -> None:
    state = before
    for step in steps:
        assert step.name in transitions, step
        assert transitions[step.name] == (step.from_state, step.to_state), step
        assert step.from_state == state
        state = step.to_state
    assert state == after


events = st.lists(st.tuples(st.sampled_from(CHANNEL_EVENTS), st.integers(0, 5), st.integers(0, 5)), max_size=60)


@given(sequence=events)
def test_any_channel_events_give_legal_transitions(sequence: list[tuple[str, int, int]],
                                                  program_type: tuple[Transitions, set[str], str],
                                                  job_type: tuple[Transitions, set[str], str]) -> None:
    program, job = ProgramStates(), JobStates()
    assert program.state == program_type[2] == INITIALIZING   # power-on: the NodeSet's initial state
    assert job.state == job_type[2] == INITIALIZING
    for event, completed, planned in sequence:
        before = program.state
        steps = program.on(event)
        _legal(steps, before, program.state, program_type[0])
        assert program.state in program_type[1]
        if steps:
            assert program.last == steps[-1]
        before = job.state
        job_steps = job.on(event, completed, planned)
        _legal(job_steps, before, job.state, job_type[0])
        assert job.state in job_type[1]


def test_a_program_s_life() -> None:
    program = ProgramStates()
    life = [("selected", []), ("started", ["InitializingToRunning"]), ("interrupted", ["RunningToInterrupted"]),
            ("resumed", ["InterruptedToRunning"]), ("ended", ["RunningToEnded"]),
            ("aborted", []),                                             # a reset in reset aborts nothing
            ("started", ["EndedToInitializing", "InitializingToRunning"]),  # NC start again: the next run
            ("aborted", ["RunningToAborted"]), ("selected", ["AbortedToInitializing"]),
            ("unselected", []), ("interrupted", [])]
    for event, expected in life:
        assert [step.name for step in program.on(event)] == expected, event
    assert program.state == INITIALIZING


def test_a_job_runs_its_planned_runs_then_ends() -> None:
    job = JobStates()
    assert [s.name for s in job.on("started", 0, 2)] == ["InitializingToRunning"]
    assert [s.name for s in job.on("ended", 1, 2)] == ["RunningToRunning"]     # one of two made
    assert job.on("started", 1, 2) == []                                         # the next run: still Running
    assert [s.name for s in job.on("ended", 2, 2)] == ["RunningToEnded"]
    assert [s.name for s in job.on("started", 2, 2)] == ["EndedToInitializing", "InitializingToRunning"]
    assert [s.name for s in job.on("ended", 3, 0)] == ["RunningToEnded"]        # none planned: each run a job
    job.on("started", 0, 5)
    job.on("ended", 1, 5)
    assert [s.name for s in job.on("selected", 1, 5)] == ["RunningToAborted", "AbortedToInitializing"]


def _look(status: int, selected: str = "/_N_MPF_DIR/_N_A_MPF", parts: float = 0.0) -> ChannelLook:
    return ChannelLook(status, selected, parts)


def test_a_channel_that_does_not_tell_is_read_from_its_state() -> None:
    """progStatus 5 aborted, 3 running, 4 waiting (still running), 2 stopped; a part counted marks a
    normal end."""
    looks = [_look(5, ""), _look(5), _look(3), _look(4), _look(3), _look(2), _look(3), _look(5, parts=1),
             _look(3, parts=1), _look(5, parts=1), _look(5, parts=2)]
    told = [events_between(a, b) for a, b in zip(looks, looks[1:], strict=False)]
    assert told == [["selected"], ["started"], [], [], ["interrupted"], ["resumed"], ["ended"], ["started"],
                    ["aborted"], ["started", "ended"]]


@given(looks=st.lists(st.tuples(st.sampled_from([1, 2, 3, 4, 5]), st.sampled_from(["", "/_N_MPF_DIR/_N_A_MPF"]),
                          st.integers(0, 3)), min_size=2, max_size=40))
def test_any_looks_give_legal_transitions(looks: list[tuple[int, str, int]],
                                          program_type: tuple[Transitions, set[str], str]) -> None:
    program = ProgramStates()
    total = 0
    seen = []
    for status, selected, more in looks:
        total += more
        seen.append(ChannelLook(status, selected, float(total)))
    for before, after in zip(seen, seen[1:], strict=False):
        for event in events_between(before, after):
            assert event in CHANNEL_EVENTS
            state = program.state
            _legal(program.on(event), state, program.state, program_type[0])
