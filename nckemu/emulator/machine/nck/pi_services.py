"""The NC PI services the emulated NCK executes (login, select, delete, power-on, leadscrew loading).

The catalogue says which services exist and how many arguments each takes; this module gives them
their behaviour. Refusals are typed header errors (``nckemu.errors``), so the answer a client sees
is the controller's code.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

from nckemu.catalogue.pi_services import NC_SERVICE_ARGUMENTS, PI_LOAD_LEADSCREW, PI_NEW_CONFIG, PI_POWER_ON
from nckemu.catalogue.program_names import directory_path, program_path
from nckemu.emulator.machine.nck.access import AccessContext
from nckemu.emulator.machine.nck.parts import NckParts
from nckemu.errors import (
    NckConfigError,
    NckNoSuchFile,
    NckPiAccessRefused,
    NckPiBadArguments,
    NckServiceError,
    NckWrongPassword,
)

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.nck.pi_services")

Handler = Callable[[NckParts, list[str], AccessContext], None]


def _login(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    level = model.machine.passwords.get(arguments[1])
    if level is None:
        raise NckWrongPassword("incorrect password")
    ctx.level = min(ctx.level, level)


def _logout(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    ctx.level = model.machine.connection_access_level


def _select(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    """_N_SELECT(ident, path): the channel selects the program (only in reset). The ident's last two
    digits name the channel ("201": channel 1; inferred, programs.md 7); others select in channel 1."""
    ident = arguments[0].strip()
    number = int(ident[-2:]) if len(ident) == 3 and ident.isdigit() and int(ident[-2:]) in model.channels else 1
    model.channels[number].select(arguments[1])


def _delete(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    # The path as the control writes it; a name as users write it (TEST.MPF) is taken too.
    model.programs.delete(program_path(arguments[1]))


def _transfer(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    """_N_F_XFER: mark a file or directory for the upload that follows (names its last part)."""
    path = directory_path(arguments[1]) or program_path(arguments[1])
    model.programs.mark_for_transfer(path)


def _setudt(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    log.info("user data taken over (_N_SETUDT)")


def _power_on(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    model.power_on()


def _new_config(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    # The second argument is Wireshark's "class"; no source gives its values, so any is taken.
    names = model.activate_new_config()
    log.info("%s: new configuration active (%s)", PI_NEW_CONFIG, ", ".join(names) or "no NEW_CONF data")


def _load_leadscrew(model: NckParts, arguments: list[str], ctx: AccessContext) -> None:
    enable = model.store.spec("ENC_COMP_ENABLE")
    if not ctx.may(enable.write_level):  # the same protection as the machine data that enables it
        raise NckPiAccessRefused(f"loading a table needs access level {enable.write_level}")
    path = arguments[1]
    try:
        with open(path, encoding="utf-8") as handle:
            text = handle.read()
    except (OSError, UnicodeDecodeError) as exc:
        log.warning("%s %s: cannot read (%s)", PI_LOAD_LEADSCREW, path, exc)
        raise NckNoSuchFile(f"cannot read {path}") from None
    try:
        tables = model.compensation.load_leadscrew_program(text, path)
    except NckServiceError as exc:
        log.warning("%s: %s", PI_LOAD_LEADSCREW, exc)
        raise
    except NckConfigError as exc:  # the wire has no room for the line; the log has it
        log.warning("%s: %s", PI_LOAD_LEADSCREW, exc)
        raise NckPiBadArguments(str(exc)) from None
    log.info("%s: %d table(s) from %s; active after power-on with MD32700 = 1", PI_LOAD_LEADSCREW,
             len(tables), path)


HANDLERS: dict[str, Handler] = {
    "_N_LOGIN_": _login,
    "_N_LOGOUT": _logout,
    "_N_SELECT": _select,
    "_N_F_DELE": _delete,
    "_N_F_XFER": _transfer,
    "_N_SETUDT": _setudt,
    PI_POWER_ON: _power_on,
    PI_NEW_CONFIG: _new_config,
    PI_LOAD_LEADSCREW: _load_leadscrew,
}
assert set(HANDLERS) == set(NC_SERVICE_ARGUMENTS), "every catalogued NC service needs a handler"


def run_service(model: NckParts, service: str, arguments: Sequence[str], ctx: AccessContext) -> None:
    handler = HANDLERS.get(service)
    if handler is None:
        raise NckServiceError(f"PI service {service} is not supported")
    expected = NC_SERVICE_ARGUMENTS[service]
    if len(arguments) != expected:
        raise NckPiBadArguments(f"{service} takes {expected} arguments, got {len(arguments)}")
    handler(model, list(arguments), ctx)
