"""The OPC UA face: an asyncua server in SINUMERIK naming over one ``Emulator`` (the S7 face's model).

``face = OpcUaFace(emulator, "127.0.0.1", 4840); await face.start(); ...; await face.stop()`` on the
running event loop; any number of faces may share a loop (a fleet).

This module only composes the face's parts, each typed against what it needs of the face
(``parts.py``):

- ``sinumerik_nodes``: the SINUMERIK namespace (node ids parsed by the catalogue, nodes made when first
  named, the browse tree, writes through the model with the user's rights);
- ``sessions``: logins, the controller's limits, the user's rights bound to each request;
- ``monitoring``: monitored items fed from the model's writes and a sampler;
- ``files`` and ``users``: the methods under ``Sinumerik/Methods``;
- ``alarms``: the NCK's alarms as events; ``models``: the umati and CNC companion models;
- ``security`` and ``transport``: endpoints, certificates, and the guards on each connection.

Where asyncua offers no public hook, the parts go through ``asyncua_internals`` (which says why).
"""

from __future__ import annotations

import logging
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from asyncua import Server

import nckemu
from nckemu.catalogue.node_ids import NodeName
from nckemu.emulator.faces.opcua import asyncua_internals, files, security, selection, transport, users
from nckemu.emulator.faces.opcua import shelf as address_cache
from nckemu.emulator.faces.opcua.alarms import AlarmEvents
from nckemu.emulator.faces.opcua.models import Models
from nckemu.emulator.faces.opcua.monitoring import Monitoring
from nckemu.emulator.faces.opcua.sessions import RealmRules, Sessions, UserManager
from nckemu.emulator.faces.opcua.settings import OpcUaSettings
from nckemu.emulator.faces.opcua.sinumerik_nodes import SinumerikNodes
from nckemu.emulator.faces.opcua.users import STATE_KEY as USERS_STATE
from nckemu.emulator.faces.opcua.users import UserRegistry
from nckemu.emulator.machine.core import Emulator

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.opcua.face")

PRODUCT_URI = "urn:nckemu"  # the product: BuildInfo and the endpoints' application description


class OpcUaFace:
    """One machine's OPC UA server; ``start()``/``stop()`` on the running loop."""

    def __init__(self, emulator: Emulator, host: str = "127.0.0.1", port: int = 4840,
                 settings: OpcUaSettings | None = None) -> None:
        self.emulator = emulator
        self.host = host
        self.port = port
        self.settings = settings or OpcUaSettings.from_machine(emulator.machine.opcua, emulator.machine.source)
        quiet = logging.getLogger("asyncua")
        if quiet.level == logging.NOTSET:  # its INFO lines (a thousand at init) would drown serve's own
            quiet.setLevel(logging.WARNING)
        self.users = UserRegistry(self.settings, changed=emulator.saves.request)  # methods await the save
        self.users.restore(emulator.restored_face_state.get(USERS_STATE))
        emulator.face_state[USERS_STATE] = self.users.snapshot
        self.server = Server(user_manager=UserManager(self))
        self.sinumerik = SinumerikNodes(emulator, self.rights_of)
        self.sessions = Sessions(self)
        self.monitoring = Monitoring(self)
        self.alarm_events = AlarmEvents(self)
        self.models = Models(self)  # the umati and CNC companion models (models.py)

    # ------------------------------------------------------------------ what the parts ask of the face
    @property
    def namespace(self) -> int:
        """The index of the SINUMERIK namespace (``SinumerikVarProvider``)."""
        return self.sinumerik.namespace

    @property
    def specs(self) -> tuple[Any, ...]:
        return self.sinumerik.specs

    def node_name(self, identifier: str) -> NodeName:
        """The parsed name of a node id string (cached; raises the catalogue's typed errors)."""
        return self.sinumerik.node_name(identifier)

    def rights_of(self, user: str | None) -> frozenset[str]:
        if not user:
            return self.settings.anonymous
        return self.users.rights_of(user) or frozenset()

    @property
    def updates_pushed(self) -> int:
        return self.monitoring.updates_pushed

    def sample(self) -> int:
        """Queue the monitored values that changed since they were last queued; how many."""
        return self.monitoring.sample()

    # ------------------------------------------------------------------ start / stop
    async def start(self) -> OpcUaFace:
        await self._init_server()
        server = self.server
        server.set_endpoint(f"opc.tcp://{self.host}:{self.port}/")
        await self._describe(server)
        await security.apply(server, self.emulator, self.settings, RealmRules())
        self.sinumerik.install(server, await server.register_namespace(self.settings.namespace_uri))
        self.monitoring.install(server)
        self.sessions.install(server)
        await self.sinumerik.build_browse_tree(server)
        await self.models.start(server)
        methods = await files.add_methods(self, server)
        await users.add_methods(self, server, methods, self.users)
        await selection.add_methods(self, server, methods)
        await self.alarm_events.start(server)
        transport.install(server)  # hostile input answered with OPC UA errors, half-open connections closed
        # A port in use reaches the caller as OSError (serve says so in one line); asyncua would also
        # log it with a traceback.
        starting = logging.getLogger("asyncua.server.server")
        level = starting.level
        starting.setLevel(logging.CRITICAL)
        try:
            await server.start()
        finally:
            starting.setLevel(level)
        if self.port == 0:
            self.port = self.bound_port()
        self.monitoring.start()
        log.info("OPC UA face on opc.tcp://%s:%d/ (namespace %s = ns=%d)", self.host, self.port,
                 self.settings.namespace_uri, self.namespace)
        return self

    async def _init_server(self) -> None:
        """asyncua's standard address space from the shared shelf (built by the first face to start), with
        the companion models when they are on (their own shelf, ``models.py``)."""
        shelf = await self.models.shelf() or address_cache.ready_shelf()
        self.server.iserver.bind_condition_methods = True  # ConditionRefresh (alarm events), off by default
        if shelf is not None:
            address_cache.share(self.server)
            try:
                await self.server.init(shelf)
                await self.models.after_init(self.server)
                return
            except Exception as exc:  # a damaged cache costs the time to build it again, nothing else
                log.warning("OPC UA: the address-space cache %s did not load (%s); building it again",
                            shelf.parent, exc)
                address_cache.discard(shelf)
                self.models.dropped()
                self.server = Server(user_manager=UserManager(self))
                self.server.iserver.bind_condition_methods = True
        building = address_cache.new_shelf()
        await self.server.init(building)
        if building is not None:
            address_cache.publish(building)

    async def _describe(self, server: Server) -> None:
        """The server names nckemu and its version (BuildInfo, the endpoints' ProductUri) and the machine
        (its name among others)."""
        server.product_uri = PRODUCT_URI
        server.manufacturer_name = "nckemu"
        server.set_server_name(f"nckemu {self.emulator.name}")
        built = datetime.fromtimestamp(Path(nckemu.__file__).stat().st_mtime, UTC)
        await server.set_build_info(PRODUCT_URI, "nckemu", "nckemu", nckemu.__version__, nckemu.__version__, built)

    def bound_port(self) -> int:
        return asyncua_internals.bound_port(self.server)

    async def stop(self) -> None:
        await self.monitoring.stop()
        await self.alarm_events.stop()
        await self.models.stop()
        await asyncua_internals.stop_time_updates(self.server.iserver)
        await self.server.stop()

    # ------------------------------------------------------------------ what `nckemu serve` reads of a face
    # (the Face protocol in emulator/faces)
    what = "OPC UA"

    @property
    def url(self) -> str:
        return f"opc.tcp://{self.host}:{self.port}/"

    @property
    def ready(self) -> dict[str, Any]:
        return {"opcua": self.url}

    @property
    def ready_line(self) -> str:
        return (f"OPC UA: {self.url} (namespace {self.settings.namespace_uri}), e.g. "
                f"uaread -u {self.url} -n 'ns={self.namespace};s=/Channel/State/progStatus'")
