"""Users and rights of the OPC UA face, and the methods that manage them under ``Sinumerik/Methods``.

As the controller: AddUser(user, password), DeleteUser(user), GetUserList(), ChangeMyPassword(old,
new), GiveUserAccess(user, "Realm;Realm"), DeleteUserAccess(user, "Realm;Realm"),
GetUserAccessRights(user); only the admin manages users (others: BadInvalidArgument), anonymous
sessions call no methods (BadRequestNotAllowed), at most 20 users. AddCertificateUser answers
BadNotSupported: certificate users are not emulated. The admin is the machine file's ``[opcua] admin``
(``nckemu`` on the default machine; docs/assumptions.md). Users, passwords and rights changed here
are retained data: with ``serve --state`` they survive a restart.
"""

from __future__ import annotations

import hmac
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from asyncua import Server, ua

from nckemu.emulator.faces.opcua import request
from nckemu.emulator.faces.opcua.settings import RIGHTS, OpcUaSettings

if TYPE_CHECKING:
    from nckemu.emulator.faces.opcua.parts import MethodHost

MAX_USERS = 20
MAX_TEXT = 128
_NAME = re.compile(r"^[A-Za-z0-9_.@-]{1,64}$")
STATE_KEY = "opcua_users"


class UserError(Exception):
    """A refused user-management call, with the status the controller answers."""

    def __init__(self, status: str, why: str) -> None:
        super().__init__(why)
        self.status = status


def parse_rights(text: str) -> frozenset[str]:
    """``"StateRead;PlcWrite"`` as a set of rights; an unknown one is BadInvalidArgument."""
    if not isinstance(text, str) or len(text) > 1024:
        raise UserError("BadInvalidArgument", "expected rights as text, e.g. StateRead;PlcWrite")
    rights = frozenset(part.strip() for part in text.split(";") if part.strip())
    unknown = sorted(rights - RIGHTS)
    if unknown or not rights:
        raise UserError("BadInvalidArgument", f"unknown right {unknown[0]!r}" if unknown else "no rights named")
    return rights


def format_rights(rights: frozenset[str]) -> str:
    return ";".join(sorted(rights))


@dataclass
class Account:
    password: str
    rights: frozenset[str] = field(default_factory=frozenset)


class UserRegistry:
    """The face's users: those of the machine file, then as the methods changed them."""

    def __init__(self, settings: OpcUaSettings, changed: Callable[[], None] = lambda: None) -> None:
        self.admin = settings.admin
        self.accounts: dict[str, Account] = {name: Account(user.password, user.rights)
                                             for name, user in settings.users.items()}
        self._changed = changed

    # --------------------------------------------------------------- what sessions ask
    def login(self, name: str, password: str | None) -> bool:
        # The same work whether the user or the password is wrong (no timing tells which part was).
        account = self.accounts.get(name)
        expected = (account.password if account is not None else "\0 no such user").encode()
        same = hmac.compare_digest(expected, (password if isinstance(password, str) else "").encode())
        return account is not None and isinstance(password, str) and same

    def rights_of(self, name: str) -> frozenset[str] | None:
        account = self.accounts.get(name)
        return account.rights if account is not None else None

    # --------------------------------------------------------------- the methods (caller: a user name)
    def _admin_only(self, caller: str) -> None:
        if caller != self.admin:
            raise UserError("BadInvalidArgument", "only the admin manages users")

    def _existing(self, name: Any) -> Account:
        account = self.accounts.get(name) if isinstance(name, str) else None
        if account is None:
            raise UserError("BadInvalidArgument", f"no user {name!r}")
        return account

    def add_user(self, caller: str, name: Any, password: Any) -> None:
        self._admin_only(caller)
        if not isinstance(name, str) or not _NAME.match(name):
            raise UserError("BadInvalidArgument", "a user name is 1..64 letters, digits, _ . @ -")
        if not isinstance(password, str) or not 1 <= len(password) <= MAX_TEXT:
            raise UserError("BadInvalidArgument", f"a password is 1..{MAX_TEXT} characters")
        if name in self.accounts:
            raise UserError("BadInvalidArgument", f"user {name!r} exists")
        if len(self.accounts) >= MAX_USERS:
            raise UserError("BadInvalidArgument", f"at most {MAX_USERS} users")
        self.accounts[name] = Account(password)
        self._changed()

    def delete_user(self, caller: str, name: Any) -> None:
        self._admin_only(caller)
        self._existing(name)
        if name == self.admin:
            raise UserError("BadInvalidArgument", "the admin cannot be deleted")
        del self.accounts[name]
        self._changed()

    def user_list(self, caller: str) -> list[str]:
        self._admin_only(caller)
        return sorted(self.accounts)

    def change_my_password(self, caller: str, old: Any, new: Any) -> None:
        account = self._existing(caller)
        if not isinstance(old, str) or old != account.password:
            raise UserError("BadInvalidArgument", "the old password does not match")
        if not isinstance(new, str) or not 1 <= len(new) <= MAX_TEXT:
            raise UserError("BadInvalidArgument", f"a password is 1..{MAX_TEXT} characters")
        account.password = new
        self._changed()

    def give_access(self, caller: str, name: Any, rights: Any) -> None:
        self._admin_only(caller)
        account = self._existing(name)
        account.rights = account.rights | parse_rights(rights)
        self._changed()

    def delete_access(self, caller: str, name: Any, rights: Any) -> None:
        self._admin_only(caller)
        account = self._existing(name)
        account.rights = account.rights - parse_rights(rights)
        self._changed()

    def access_rights(self, caller: str, name: Any) -> str:
        self._admin_only(caller)
        return format_rights(self._existing(name).rights)

    # --------------------------------------------------------------- retained data
    def snapshot(self) -> dict[str, Any]:
        return {name: {"password": account.password, "rights": sorted(account.rights)}
                for name, account in sorted(self.accounts.items())}

    def restore(self, snapshot: Any) -> None:
        """Users as a state file kept them; a damaged section leaves the machine file's users."""
        if not isinstance(snapshot, dict):
            return
        accounts: dict[str, Account] = {}
        for name, entry in snapshot.items():
            if not isinstance(name, str) or not isinstance(entry, dict) or not isinstance(entry.get("password"), str):
                return
            rights = entry.get("rights", [])
            if not isinstance(rights, list) or not set(rights) <= RIGHTS:
                return
            accounts[name] = Account(entry["password"], frozenset(rights))
        self.accounts = accounts


async def add_methods(face: MethodHost, server: Server, methods: Any, registry: UserRegistry) -> None:
    """The user-management methods on the ``Methods`` object (``methods``, made by ``files.add_methods``)."""
    ns = face.namespace
    text, texts = ua.VariantType.String, ua.VariantType.String

    def call(action: Callable[..., Any], result: ua.VariantType | None = None) -> Callable[..., Any]:
        async def method(_parent: Any, *arguments: Any) -> Any:
            caller = request.user()
            if not caller:
                return ua.StatusCode(ua.StatusCodes.BadRequestNotAllowed)
            values = [a.Value if isinstance(a, ua.Variant) else a for a in arguments]
            saves = face.emulator.saves
            requested = saves.requested
            try:
                answer = action(caller, *values)
            except UserError as refusal:
                return ua.StatusCode(getattr(ua.StatusCodes, refusal.status))
            except TypeError:  # an argument of another type (the count is checked before)
                return ua.StatusCode(ua.StatusCodes.BadInvalidArgument)
            if saves.requested != requested:  # the users changed: answered once they are on disk
                await saves.durable()
            if result is None:
                return []
            return [ua.Variant(answer, result)]
        return method

    async def not_supported(_parent: Any, *_arguments: Any) -> Any:
        return ua.StatusCode(ua.StatusCodes.BadNotSupported)

    def argument(name: str, kind: ua.VariantType = text, rank: int = -1) -> ua.Argument:
        return ua.Argument(Name=name, DataType=ua.NodeId(kind.value), ValueRank=rank, ArrayDimensions=[],
                           Description=ua.LocalizedText(name))

    table: list[tuple[str, Callable[..., Any], list[ua.Argument], list[ua.Argument]]] = [
        ("AddUser", call(registry.add_user), [argument("user"), argument("password")], []),
        ("DeleteUser", call(registry.delete_user), [argument("user")], []),
        ("GetUserList", call(registry.user_list, texts), [], [argument("users", texts, 1)]),
        ("ChangeMyPassword", call(registry.change_my_password), [argument("old"), argument("new")], []),
        ("GiveUserAccess", call(registry.give_access), [argument("user"), argument("rights")], []),
        ("DeleteUserAccess", call(registry.delete_access), [argument("user"), argument("rights")], []),
        ("GetUserAccessRights", call(registry.access_rights, text), [argument("user")], [argument("rights")]),
        ("AddCertificateUser", not_supported, [argument("user"), argument("certificate", ua.VariantType.ByteString)],
         []),
    ]
    def admin_only(user: str, _rights: frozenset[str]) -> bool:
        return bool(user) and user == registry.admin

    # Who may call each (UserExecutable as the session reads it): as the registry decides.
    executable: dict[str, Callable[[str, frozenset[str]], bool]] = {
        name: admin_only for name in ("AddUser", "DeleteUser", "GetUserList", "GiveUserAccess", "DeleteUserAccess",
                                      "GetUserAccessRights")}
    executable["ChangeMyPassword"] = lambda user, _rights: bool(user)
    executable["AddCertificateUser"] = lambda _user, _rights: False  # not supported for anyone
    for name, method, inputs, outputs in table:
        node = await methods.add_method(ua.NodeId(f"/Methods/{name}", ns), ua.QualifiedName(name, ns),
                                        request.with_arguments(method, len(inputs)), inputs, outputs)
        server.set_attribute_value_callback(node.nodeid, request.user_executable(executable[name]),
                                            ua.AttributeIds.UserExecutable)
