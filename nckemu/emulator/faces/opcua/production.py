"""umati Production: the ActiveProgram's and the job's state machines over the life of a program.

``ProgramTracker`` follows channel 1's program: the channel tells it each step (``on_change``: selected,
started, interrupted, resumed, ended, aborted, unselected); a change of the channel's state it did not
tell as a step (a recording runs the channel without a program) is worked out from how the channel looks
after it (``state_listeners``, ``program_states.events_between``). It moves the two state machines of
``program_states.py`` at once, under a lock, so a read right after the channel acted sees the new state;
the transition events go out afterwards, in order, from one task on the face's loop.

``StateMachineNodes`` reads a state machine type from the address space (the NodeSet as imported):
its states with their StateNumber and its transitions with their TransitionNumber and FromState/ToState.
A state machine instance shows CurrentState (with Id and Number) and LastTransition (with Id, Number
and TransitionTime); power-on is the initial state with no transition yet.

Each transition sends an event of the specification's transition event type for that machine
(``ProductionProgramTransitionEventType``: JobIdentifier and Name; ``ProductionJobTransitionEventType``:
Identifier, RunsCompleted, RunsPlanned; both with TransitionEventType's Transition, FromState and ToState
and their Ids). The specification makes both types abstract, so the events are of a concrete subtype of
each in the face's instance namespace (``Nckemu<type name>``), which a client filtering by the
specification's type receives. They are sent from the state machine object (its ``State``) and from the
Server object, with the state machine as SourceNode.
"""

from __future__ import annotations

import asyncio
import copy
import logging
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, Protocol

from asyncua import Server, ua

from nckemu.emulator.faces.opcua import nodesets
from nckemu.emulator.faces.opcua.feeds import Feed
from nckemu.emulator.faces.opcua.instances import Made, Types
from nckemu.emulator.faces.opcua.program_states import (
    ChannelLook,
    JobStates,
    ProgramStates,
    Step,
    events_between,
)
from nckemu.emulator.machine.nck.channel import Channel


class MachineToolHost(Protocol):
    """What the state machines need of the umati instance they belong to (typed here, not as the
    instance, so that umati and production do not import each other)."""

    @property
    def models(self) -> Any: ...

    @property
    def face(self) -> Any: ...

    @property
    def maker(self) -> Any: ...

log = logging.getLogger("nckemu.emulator.opcua.production")

_FROM_STATE = ua.NodeId(ua.ObjectIds.FromState)
_TO_STATE = ua.NodeId(ua.ObjectIds.ToState)
_TRANSITION_TYPE = ua.NodeId(ua.ObjectIds.TransitionType)
_HAS_COMPONENT = ua.NodeId(ua.ObjectIds.HasComponent)
_REALM = "State"  # the realm of progStatus, whose Read right these nodes need too
JOB_IDENTIFIER = "Job1"
# The optional children of a state machine instance the face makes (below its ``State``).
LAST_TRANSITION = ("CurrentState/Number", "LastTransition", "LastTransition/Number", "LastTransition/TransitionTime")


@dataclass(frozen=True)
class StateNode:
    node: ua.NodeId
    number: int


@dataclass(frozen=True)
class TransitionNode:
    node: ua.NodeId
    number: int
    from_state: str
    to_state: str


class StateMachineNodes:
    """The states and transitions a state machine type declares (its own and its supertypes')."""

    def __init__(self, types: Types, type_id: ua.NodeId) -> None:
        self.states: dict[str, StateNode] = {}
        self.transitions: dict[str, TransitionNode] = {}
        ends: dict[str, tuple[ua.NodeId | None, ua.NodeId | None]] = {}
        names: dict[ua.NodeId, str] = {}
        current: ua.NodeId | None = type_id
        while current is not None:
            for ref in types.node(current).references:
                if not ref.IsForward or ref.ReferenceTypeId != _HAS_COMPONENT or ref.NodeClass != ua.NodeClass.Object:
                    continue
                if types.rule(ref.NodeId) is not None:  # CurrentState, LastTransition: instance declarations
                    continue
                name = ref.BrowseName.Name
                if name in self.states or name in ends:
                    continue  # the most derived declaration wins
                node = types.node(ref.NodeId)
                number = _number(types, node)
                if types.type_definition(ref.NodeId) == _TRANSITION_TYPE:
                    ends[name] = (_target(node, _FROM_STATE), _target(node, _TO_STATE))
                    self.transitions[name] = TransitionNode(ref.NodeId, number, "", "")
                else:
                    self.states[name] = StateNode(ref.NodeId, number)
                    names[ref.NodeId] = name
            current = types.supertype(current)
        for name, (source, target) in ends.items():
            self.transitions[name] = TransitionNode(self.transitions[name].node, self.transitions[name].number,
                                                    names.get(source, "") if source else "",
                                                    names.get(target, "") if target else "")


def _number(types: Types, node: Any) -> int:
    for ref in node.references:
        if ref.IsForward and ref.BrowseName.Name in ("StateNumber", "TransitionNumber"):
            value = types.node(ref.NodeId).attributes[ua.AttributeIds.Value].value.Value.Value
            return int(value or 0)
    return 0


def _target(node: Any, reference: ua.NodeId) -> ua.NodeId | None:
    for ref in node.references:
        if ref.IsForward and ref.ReferenceTypeId == reference:
            return ref.NodeId  # type: ignore[no-any-return]
    return None


@dataclass(frozen=True)
class Moment:
    """A state machine as a read shows it: state, last transition (None at power-on) and its time."""

    state: str
    last: Step | None
    at: datetime | None


class ProgramTracker:
    """Channel ``number``'s program as the ActiveProgram and the job see it."""

    def __init__(self, emulator: Any, number: int = 1) -> None:
        self.emulator = emulator
        self.channel: Channel = emulator.nck.channels[number]
        self.program = ProgramStates()
        self.job = JobStates()
        self.program_at: datetime | None = None
        self.job_at: datetime | None = None
        self._lock = threading.Lock()
        self.listeners: list[Callable[[list[Step], list[Step]], None]] = []
        self._told = False  # a step told since the channel's state last changed
        self._look = self.look()

    def start(self) -> None:
        """Listen to the channel's steps, and to its state for the changes it tells as no step (a
        recording runs it without a program)."""
        self.channel.on_change.append(self.tell)
        self.channel.state_listeners.append(self._state_changed)

    def stop(self) -> None:
        for listeners, listener in ((self.channel.on_change, self.tell),
                                    (self.channel.state_listeners, self._state_changed)):
            if listener in listeners:
                listeners.remove(listener)  # type: ignore[arg-type]

    def counters(self) -> tuple[float, float]:
        """RunsCompleted and RunsPlanned: actParts and reqParts."""
        state = self.channel.state
        return float(state.actual_parts), float(state.required_parts)

    def look(self) -> ChannelLook:
        state = self.channel.state
        return ChannelLook(int(state.program_status), self.channel.selected, float(state.total_parts))

    def tell(self, event: str) -> None:
        """The channel did ``event`` (any thread)."""
        self._told = True
        self._step(event)

    def _state_changed(self, _channel: Any) -> None:
        """The channel's state changed: steps it did not tell are worked out from how it looks."""
        look = self.look()
        before, self._look = self._look, look
        told, self._told = self._told, False
        if not told:
            for event in events_between(before, look):
                self._step(event)

    def _step(self, event: str) -> None:
        with self._lock:
            program_steps = self.program.on(event)
            job_steps: list[Step] = []
            if event != "aborted" or program_steps:  # a reset with nothing running aborts no job
                completed, planned = self.counters()
                job_steps = self.job.on(event, completed, planned)
            now = datetime.now(UTC)
            if program_steps:
                self.program_at = now
            if job_steps:
                self.job_at = now
        if program_steps or job_steps:
            for listener in list(self.listeners):
                listener(program_steps, job_steps)

    def program_moment(self) -> Moment:
        with self._lock:
            return Moment(self.program.state, self.program.last, self.program_at)

    def job_moment(self) -> Moment:
        with self._lock:
            return Moment(self.job.state, self.job.last, self.job_at)


class Production:
    """The ActiveProgram's and Job1's state machines of one MachineTool instance, and their events."""

    def __init__(self, instance: MachineToolHost) -> None:
        self.instance = instance
        self.models = instance.models
        self.face = instance.face
        self.tracker = self.models.tracker(1)
        self.tracker.listeners.append(self._stepped)
        types = instance.maker.types
        mt = self.models.ns(nodesets.MACHINE_TOOL)
        self.program_nodes = StateMachineNodes(types, types.find(mt, "ProductionProgramStateMachineType"))
        self.job_nodes = StateMachineNodes(types, types.find(mt, "ProductionJobStateMachineType"))
        self.program_state: ua.NodeId | None = None
        self.job_state: ua.NodeId | None = None
        self._pending: deque[tuple[str, Step, dict[str, Any]]] = deque()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wake: asyncio.Event | None = None
        self._sender: asyncio.Task[None] | None = None
        self._generators: dict[str, list[Any]] = {}

    # ------------------------------------------------------------------ nodes
    def bind(self, active_program: Made, job: Made, active_path: str, job_path: str) -> None:
        """Feed the CurrentState and LastTransition of both state machines from the tracker."""
        self.program_state = active_program[active_path]
        self.job_state = job[job_path]
        self._bind(active_program, active_path, self.program_nodes, self.tracker.program_moment)
        self._bind(job, job_path, self.job_nodes, self.tracker.job_moment)

    def _bind(self, made: Made, path: str, nodes: StateMachineNodes, moment: Callable[[], Moment]) -> None:
        def state(raw: Moment) -> StateNode:
            return nodes.states[raw.state]

        def transition(raw: Moment) -> TransitionNode | None:
            return nodes.transitions.get(raw.last.name) if raw.last is not None else None

        def last_name(raw: Moment) -> ua.LocalizedText:
            return ua.LocalizedText(raw.last.name if raw.last is not None else "")

        def last_id(raw: Moment) -> ua.NodeId:
            found = transition(raw)
            return found.node if found is not None else ua.NodeId()

        def last_number(raw: Moment) -> int:
            found = transition(raw)
            return found.number if found is not None else 0

        feeds: dict[str, Callable[[Moment], ua.Variant]] = {
            "CurrentState": lambda raw: ua.Variant(ua.LocalizedText(raw.state)),
            "CurrentState/Id": lambda raw: ua.Variant(state(raw).node, ua.VariantType.NodeId),
            "CurrentState/Number": lambda raw: ua.Variant(state(raw).number, ua.VariantType.UInt32),
            "LastTransition": lambda raw: ua.Variant(last_name(raw)),
            "LastTransition/Id": lambda raw: ua.Variant(last_id(raw), ua.VariantType.NodeId),
            "LastTransition/Number": lambda raw: ua.Variant(last_number(raw), ua.VariantType.UInt32),
            "LastTransition/TransitionTime": lambda raw: ua.Variant(
                raw.at or datetime(1601, 1, 1, tzinfo=UTC), ua.VariantType.DateTime),
        }
        for child, variant in feeds.items():
            node = made.get(f"{path}/{child}")
            if node is not None:
                self.models.bind(node, Feed(moment, variant, _REALM))  # type: ignore[arg-type]

    # ------------------------------------------------------------------ events
    async def start(self, server: Server) -> None:
        self._loop = asyncio.get_running_loop()
        self._wake = asyncio.Event()
        types = self.instance.maker.types
        mt = self.models.ns(nodesets.MACHINE_TOOL)
        server_node = ua.NodeId(ua.ObjectIds.Server)
        for key, type_name, source in (("program", "ProductionProgramTransitionEventType", self.program_state),
                                       ("job", "ProductionJobTransitionEventType", self.job_state)):
            if source is None:
                continue
            concrete = await self._concrete(server, types.find(mt, type_name), f"Nckemu{type_name}")
            generators = []
            for emitter in (source, server_node):
                generator = await server.get_event_generator(concrete, emitter)
                generator.event.SourceNode = source
                generators.append(generator)
            self._generators[key] = generators
        self._sender = self._loop.create_task(self._send_forever())

    async def _concrete(self, server: Server, abstract: ua.NodeId, name: str) -> ua.NodeId:
        """A concrete subtype of an abstract event type, in the instance namespace (once per address space)."""
        nodeid = ua.NodeId(name, self.models.instance_namespace)
        if nodeid in server.iserver.aspace:
            return nodeid
        made = await server.get_node(abstract).add_object_type(nodeid, ua.QualifiedName(name, nodeid.NamespaceIndex))
        return made.nodeid  # type: ignore[no-any-return]

    async def stop(self) -> None:
        if self._stepped in self.tracker.listeners:
            self.tracker.listeners.remove(self._stepped)
        if self._sender is not None:
            self._sender.cancel()
            try:
                await self._sender
            except asyncio.CancelledError:
                pass
            self._sender = None

    def _stepped(self, program_steps: list[Step], job_steps: list[Step]) -> None:
        """Queue the events of the transitions just taken (any thread), with the values after them."""
        name = str(self.instance.value_of("/Channel/ProgramInfo/progName[u1]", ""))
        completed, planned = self.tracker.counters()
        for step in program_steps:
            self._pending.append(("program", step, {"JobIdentifier": JOB_IDENTIFIER, "Name": name}))
        for step in job_steps:
            self._pending.append(("job", step, {
                "Identifier": JOB_IDENTIFIER, "RunsCompleted": ua.Variant(int(completed), ua.VariantType.UInt32),
                "RunsPlanned": ua.Variant(int(planned), ua.VariantType.UInt32),
                "RunsPlanned/IsValid": planned > 0}))
        loop, wake = self._loop, self._wake
        if loop is not None and wake is not None and not loop.is_closed():
            loop.call_soon_threadsafe(wake.set)

    async def _send_forever(self) -> None:
        assert self._wake is not None
        while True:
            await self._wake.wait()
            self._wake.clear()
            self.face.sample()  # monitored state nodes get the new state now, not at the next sample
            while self._pending:
                key, step, values = self._pending.popleft()
                try:
                    await self._send(key, step, values)
                except Exception:  # an event that cannot go out must not stop the ones after it
                    log.exception("OPC UA transition event")

    async def _send(self, key: str, step: Step, values: dict[str, Any]) -> None:
        nodes = self.program_nodes if key == "program" else self.job_nodes
        transition = nodes.transitions.get(step.name)
        fields: dict[str, Any] = {
            "Message": ua.LocalizedText(f"{'ActiveProgram' if key == 'program' else JOB_IDENTIFIER}: {step.name}"),
            "Severity": ua.Variant(1, ua.VariantType.UInt16), "SourceName": "ActiveProgram" if key == "program" else JOB_IDENTIFIER,
            "Transition": ua.LocalizedText(step.name),
            "Transition/Id": transition.node if transition is not None else ua.NodeId(),
            "FromState": ua.LocalizedText(step.from_state),
            "FromState/Id": nodes.states[step.from_state].node,
            "ToState": ua.LocalizedText(step.to_state),
            "ToState/Id": nodes.states[step.to_state].node,
            **values,
        }
        now = datetime.now(UTC)
        for generator in self._generators.get(key, []):
            event = copy.copy(generator.event)  # one object per event: asyncua may keep it
            for name, value in fields.items():
                variant_type = value.VariantType if isinstance(value, ua.Variant) else None
                plain = value.Value if isinstance(value, ua.Variant) else value
                setattr(event, name, plain)
                known = event.data_types.get(name)
                if variant_type is not None:
                    event.data_types[name] = variant_type
                elif known in (None, ua.VariantType.Variant, ua.VariantType.Null):  # not found on the type
                    event.data_types[name] = _VARIANT_OF.get(type(plain), ua.VariantType.Variant)
            generator.event = event
            await generator.trigger(time_attr=now)


_VARIANT_OF = {str: ua.VariantType.String, bool: ua.VariantType.Boolean, int: ua.VariantType.UInt32,
               ua.LocalizedText: ua.VariantType.LocalizedText, ua.NodeId: ua.VariantType.NodeId}
