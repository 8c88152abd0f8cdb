"""What each part of the OPC UA face needs of the face, as small protocols.

``face.py`` composes the parts (``sinumerik_nodes``, ``sessions``, ``monitoring``, ``files``, ``users``,
``alarms``, ``models`` with ``umati`` and ``cnc``) and hands each itself; each part types that argument
with the protocol here that names only what it uses, so no part imports the face and the parts import
nothing that imports them back. A new part (a method set, a companion-model instance) adds its own
protocol here when none of these fits.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

from asyncua import ua

if TYPE_CHECKING:
    from nckemu.catalogue.node_ids import NodeName
    from nckemu.emulator.faces.opcua.feeds import Feed
    from nckemu.emulator.faces.opcua.settings import OpcUaSettings
    from nckemu.emulator.machine.core import Emulator


class MethodHost(Protocol):
    """Methods under ``Sinumerik/Methods`` (``files``, ``users``): the machine and the face's namespace."""

    @property
    def emulator(self) -> Emulator: ...

    @property
    def namespace(self) -> int: ...


class NamingHost(Protocol):
    """Companion models (``models``, ``umati``, ``cnc``): the machine, the settings, and SINUMERIK node ids
    parsed as the face parses them (a fed node reads the BTSS variable it mirrors)."""

    @property
    def emulator(self) -> Emulator: ...

    @property
    def settings(self) -> OpcUaSettings: ...

    def node_name(self, identifier: str) -> NodeName: ...


class ModelValues(Protocol):
    """What a companion-model instance (``umati``, ``cnc``) needs of ``models.Models``: its values bound
    to the machine, namespaces by URI, and the face as ``NamingHost``."""

    @property
    def face(self) -> NamingHost: ...

    @property
    def instance_namespace(self) -> int: ...

    def bind(self, nodeid: ua.NodeId, feed: Feed) -> None: ...

    def set(self, nodeid: ua.NodeId, variant: ua.Variant) -> None: ...

    def ns(self, uri: str) -> int: ...


class AlarmSources(Protocol):
    """Where alarm events come from when the CNC model is on (``alarms``)."""

    def cnc_alarm_type(self) -> ua.NodeId | None: ...

    def cnc_interface(self) -> ua.NodeId | None: ...


class AlarmHost(Protocol):
    """Alarm events (``alarms``): the machine's alarm list, the face's namespace, the CNC model's type and
    source object."""

    @property
    def emulator(self) -> Emulator: ...

    @property
    def namespace(self) -> int: ...

    @property
    def models(self) -> AlarmSources: ...


class Logins(Protocol):
    def login(self, name: str, password: str | None) -> bool: ...


class RealmsOfModels(Protocol):
    def realm_of(self, nodeid: ua.NodeId) -> str | None: ...


class SessionHost(Protocol):
    """Sessions, logins and monitored items (``sessions``): the limits, who may log in, each user's rights
    and the realm guarding each variable."""

    @property
    def settings(self) -> OpcUaSettings: ...

    @property
    def namespace(self) -> int: ...

    @property
    def users(self) -> Logins: ...

    @property
    def models(self) -> RealmsOfModels: ...

    def rights_of(self, user: str | None) -> frozenset[str]: ...

    def node_name(self, identifier: str) -> NodeName: ...


class FedMonitors(Protocol):
    def monitor(self, nodeid: ua.NodeId) -> Any: ...


class MonitoringHost(Protocol):
    """Monitored items fed by the face (``monitoring``): the machine whose writes it listens to, the
    sampling interval, SINUMERIK names, and the companion models' fed nodes."""

    @property
    def emulator(self) -> Emulator: ...

    @property
    def settings(self) -> OpcUaSettings: ...

    @property
    def namespace(self) -> int: ...

    @property
    def models(self) -> FedMonitors: ...

    def node_name(self, identifier: str) -> NodeName: ...
