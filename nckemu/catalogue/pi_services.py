"""The NC PI services the controller offers (names and argument counts), shared by clients and emulator.

Wireshark's service names and texts are wire vocabulary and live in ``protocol/pi.py``; this table
says which of them an NCK (and nckemu) executes, with how many string arguments.
"""

from __future__ import annotations

# The power-on / NCK reset service name is not in our sources: an assumption.
PI_POWER_ON = "_N_NCKRES"
# nckemu extension (no Siemens service): load a leadscrew table program from a file on the emulator's
# host, as `serve --lec` does at start. Arguments: the address identification and the file's path.
PI_LOAD_LEADSCREW = "_N_NCKEMU_LEC"
# "Reconfigures machine data" (Wireshark's PI table: arguments addressident, class): what an HMI's
# "activate MD" sends; machine data with effectiveness "new_conf" (MD32000, MD32760) take effect.
PI_NEW_CONFIG = "_N_CONFIG"

# service -> number of arguments (the first is always the address identification, e.g. "201")
NC_SERVICE_ARGUMENTS: dict[str, int] = {
    "_N_LOGIN_": 2,
    "_N_LOGOUT": 1,
    "_N_SELECT": 2,
    "_N_F_DELE": 2,
    "_N_F_XFER": 2,
    "_N_SETUDT": 1,
    PI_POWER_ON: 1,
    PI_NEW_CONFIG: 2,
    PI_LOAD_LEADSCREW: 2,
}
