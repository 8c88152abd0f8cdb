"""Sessions of the OPC UA face: who logs in, the controller's limits, and the user's rights on each
request.

- Logins: the face's users (``UserRegistry``); an unknown user or a wrong password is refused at
  activation, and anonymous where it is switched off. asyncua's service-level rules let everything
  through: the realm rights decide per variable and method.
- Limits as the controller's: sessions, subscriptions, session timeout, the allowed publishing
  intervals and samples per second (items past the cap are refused one by one).
- Rights: each read (asyncua's PreRead server callback), method call and monitored-item creation is
  served with its session user's rights bound (``request.bind``); an item on a variable the user may
  not read is refused, and alarm events need AlarmRead.

The session methods are wrapped through ``asyncua_internals`` (asyncua has no callback before them).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua
from asyncua.common.callback import CallbackType, ServerItemCallback
from asyncua.common.utils import ServiceError
from asyncua.crypto.permission_rules import PermissionRuleset, UserRole
from asyncua.crypto.permission_rules import User as UaUser

from nckemu.emulator.faces.opcua import asyncua_internals, request
from nckemu.emulator.faces.opcua.alarms import ALARM_RIGHTS
from nckemu.emulator.faces.opcua.settings import ALLOWED_INTERVALS_MS, may
from nckemu.emulator.faces.opcua.structures import refused_item
from nckemu.errors import NckNodeIdError

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import SessionHost


class RealmRules(PermissionRuleset):
    """asyncua's service-level rules let everything through: the realm rights decide per variable and
    method (asyncua's default refuses e.g. ModifySubscription to a non-admin user)."""

    def check_validity(self, user: Any, action_type: Any, body: Any) -> bool:
        return True


class UserManager:
    """The face's users (``UserRegistry``: the machine file's, as the methods changed them); an unknown
    user or a wrong password is refused at activation, and anonymous where it is switched off."""

    def __init__(self, face: SessionHost) -> None:
        self.face = face

    def get_user(self, iserver: Any, username: str | None = None, password: str | None = None,
                 certificate: Any = None) -> UaUser | None:
        if username is None and password is None:  # an anonymous token (a user name token needs a name)
            if not self.face.settings.allow_anonymous:
                return None
            return UaUser(role=UserRole.User, name=None)  # asyncua refuses reads to its Anonymous role
        if not username or not self.face.users.login(username, password):
            return None
        return UaUser(role=UserRole.User, name=username)


class Sessions:
    """The sessions of one face's server (``made``: every session created, the closed ones pruned)."""

    def __init__(self, face: SessionHost) -> None:
        self.face = face
        self.made: list[Any] = []

    def install(self, server: Server) -> None:
        """Wrap ``server``'s sessions (initialised, not yet started)."""
        iserver = server.iserver
        # asyncua 2.x raises a shorter session timeout than the client asked for to 5 s; the controller
        # keeps a shorter one (only longer ones are revised down, in create_session_capped below).
        iserver.min_session_timeout_ms = 0.0
        server.subscribe_server_callback(CallbackType.PreRead, self._before_read)
        asyncua_internals.on_new_session(iserver, self._made)
        self._cap_samples(iserver.subscription_service)

    def bind(self, user: Any) -> None:
        """The request now served is ``user``'s (an asyncua User, None: anonymous)."""
        name = getattr(user, "name", None)
        request.bind(name, self.face.rights_of(name))

    async def _before_read(self, event: ServerItemCallback, _dispatcher: Any) -> None:
        if event.is_external:  # the server's own reads keep what is bound
            self.bind(event.user)

    def _made(self, session: Any) -> None:
        self.made = [s for s in self.made if s.state.name != "Closed"]
        self.made.append(session)
        self._wrap(session)

    def _wrap(self, session: Any) -> None:
        face, sessions = self.face, self

        def activate_session(activate: Any) -> Any:
            def activate_session(params: Any, peer_certificate: Any) -> Any:
                active = sum(1 for s in sessions.made if s is not session and s.state.name == "Activated")
                if session.state.name == "Created" and active >= face.settings.max_sessions:
                    raise ServiceError(ua.StatusCodes.BadTooManySessions)
                return activate(params, peer_certificate)
            return activate_session

        def call_as_user(call: Any) -> Any:
            async def call_as_user(params: Any) -> Any:
                sessions.bind(session.user)
                return await call(params)
            return call_as_user

        def create_subscription(subscribe: Any) -> Any:
            async def create_subscription(params: Any, callback: Any, request_callback: Any = None) -> Any:
                if len(session.subscription_service.subscriptions) >= face.settings.max_subscriptions:
                    raise ServiceError(ua.StatusCodes.BadTooManySubscriptions)
                params.RequestedPublishingInterval = allowed_interval(params.RequestedPublishingInterval)
                return await subscribe(params, callback, request_callback)
            return create_subscription

        def monitor_as_user(monitor: Any) -> Any:
            async def monitor_as_user(params: ua.CreateMonitoredItemsParameters) -> Any:
                # The item's first value is read as this user, and an item on a variable the user may not
                # read is refused: pushes later would otherwise carry values its reads are denied.
                sessions.bind(session.user)
                return await sessions._monitor_with_rights(params, monitor)
            return monitor_as_user

        def create_session_capped(create_session: Any) -> Any:
            async def create_session_capped(params: ua.CreateSessionParameters, sockname: Any = None) -> Any:
                # asyncua keeps what the client asks for (its own client asks for an hour) and closes a
                # session idle that long; the controller's is 60 s.
                cap_ms = face.settings.session_timeout_s * 1000.0
                requested = params.RequestedSessionTimeout
                params.RequestedSessionTimeout = cap_ms if not requested or requested <= 0 else min(requested, cap_ms)
                return await create_session(params, sockname=sockname)
            return create_session_capped

        for method, wrap in (("create_session", create_session_capped), ("activate_session", activate_session),
                             ("call", call_as_user), ("create_subscription", create_subscription),
                             ("create_monitored_items", monitor_as_user)):
            asyncua_internals.override_session(session, method, wrap)

    def samples_per_s(self, subscriptions: Any) -> float:
        """What the data-change items of all subscriptions cost, in samples per second."""
        return sum(asyncua_internals.datachange_items(sub) * 1000.0 / max(
            sub.data.RevisedPublishingInterval, ALLOWED_INTERVALS_MS[0]) for sub in subscriptions.values())

    def _cap_samples(self, service: Any) -> None:
        """Items past ``max_samples_per_s`` are refused one by one; the others are created."""
        face, sessions = self.face, self

        def capped(create: Any) -> Any:
            async def create_monitored_items(params: ua.CreateMonitoredItemsParameters) -> Any:
                subscription = service.subscriptions.get(params.SubscriptionId)
                if subscription is None:
                    return await create(params)
                each = 1000.0 / max(subscription.data.RevisedPublishingInterval, ALLOWED_INTERVALS_MS[0])
                budget = face.settings.max_samples_per_s - sessions.samples_per_s(service.subscriptions)
                refused: set[int] = set()
                for position, item in enumerate(params.ItemsToCreate):
                    if item.ItemToMonitor.AttributeId == ua.AttributeIds.Value:
                        if budget + 1e-9 < each:
                            refused.add(position)
                            continue
                        budget -= each
                return await create_refusing(params, refused, ua.StatusCodes.BadTooManyMonitoredItems, create)
            return create_monitored_items

        asyncua_internals.override_monitored_item_creation(service, capped)

    async def _monitor_with_rights(self, params: ua.CreateMonitoredItemsParameters,
                                   create: Callable[[ua.CreateMonitoredItemsParameters], Any]) -> Any:
        face = self.face
        rights = request.rights()
        denied: set[int] = set()
        for position, item in enumerate(params.ItemsToCreate):
            nodeid = item.ItemToMonitor.NodeId
            if item.ItemToMonitor.AttributeId == ua.AttributeIds.EventNotifier:
                if not rights & ALARM_RIGHTS:  # alarm events need AlarmRead (the controller's realm)
                    denied.add(position)
                continue
            if item.ItemToMonitor.AttributeId == ua.AttributeIds.Value and nodeid.NamespaceIndex != face.namespace:
                realm = face.models.realm_of(nodeid)  # a companion model's variable: its BTSS variable's realm
                if realm is not None and not may(rights, realm, write=False):
                    denied.add(position)
                continue
            if item.ItemToMonitor.AttributeId != ua.AttributeIds.Value or not isinstance(nodeid.Identifier, str):
                continue
            try:
                name = face.node_name(nodeid.Identifier)
            except NckNodeIdError:
                continue  # asyncua answers for ids that are no variable
            if not may(rights, name.realm, write=False):
                denied.add(position)
        return await create_refusing(params, denied, ua.StatusCodes.BadUserAccessDenied, create)


async def create_refusing(params: ua.CreateMonitoredItemsParameters, refused: set[int], status: int,
                          create: Callable[[ua.CreateMonitoredItemsParameters], Any]) -> Any:
    """Create the items of ``params`` but those at the ``refused`` positions, which get ``status``; the
    results in the request's order."""
    if not refused:
        return await create(params)
    taken = [item for position, item in enumerate(params.ItemsToCreate) if position not in refused]
    created = iter(await create(dataclasses.replace(params, ItemsToCreate=taken)) if taken else [])
    refusal = ua.StatusCode(status)
    return [refused_item(refusal) if position in refused else next(created)
            for position in range(len(params.ItemsToCreate))]


def allowed_interval(requested_ms: float) -> float:
    """The smallest allowed interval at or above the request (the controller revises to its set)."""
    for allowed in ALLOWED_INTERVALS_MS:
        if requested_ms <= allowed:
            return float(allowed)
    return float(ALLOWED_INTERVALS_MS[-1])
