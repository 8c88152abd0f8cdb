"""awlsim hardware module ``nckemu``: a PLC program in awlsim talks to an NCK over S7comm.

awlsim imports hardware modules by the name ``awlsimhw_<name>``, hence this top-level package of
the nckemu distribution. Load the FB2/FB3/FB4 stubs (``nckemu plc stubs DIR`` writes them) with
the program and start awlsim with, e.g.::

    awlsim-test -H nckemu:host=127.0.0.1:port=1102 program_with_stubs.awl

The program's FB2 "GET", FB3 "PUT" and FB4 "PI_SERV" calls become NCK jobs to that controller
(nckemu's emulator or a real one), run without blocking the cycle; PIW reads answer from the
controller's PLC inputs, mirrored in the background. Time is awlsim's (real time).
"""

from __future__ import annotations

import time
from typing import Any

from awlsim.core.hardware_params import HwParamDesc_int, HwParamDesc_str

from nckemu.clients import NckClient
from nckemu.errors import NckError
from nckemu.plcsim.bridge import NckBridge, NckBridgeHardware
from nckemu.plcsim.remote import InputMirror


class HardwareInterface(NckBridgeHardware):
    name = "nckemu"
    description = "FB2/FB3/FB4 stubs to NCK jobs on an S7comm connection; PIW from the controller's inputs"
    paramDescs = [
        HwParamDesc_str("host", defaultValue="127.0.0.1", description="controller address"),
        HwParamDesc_int("port", defaultValue=102, minValue=1, maxValue=65535, description="ISO-on-TCP port"),
        HwParamDesc_int("rack", defaultValue=0, minValue=0, maxValue=7, description="rack of the NCK"),
        HwParamDesc_int("slot", defaultValue=4, minValue=0, maxValue=31, description="slot of the NCK"),
    ]

    def __init__(self, sim: Any, parameters: dict[str, Any] | None = None) -> None:
        self.client: NckClient | None = None
        self.mirror: InputMirror | None = None
        started_s = time.monotonic()
        bridge = NckBridge(sim, None, self._read_peripheral, lambda: time.monotonic() - started_s)
        super().__init__(sim, bridge, parameters)

    def _read_peripheral(self, offset: int, size: int) -> bytes:
        return self.mirror.read(offset, size) if self.mirror is not None else bytes(size)

    def doStartup(self) -> None:  # noqa: N802 - awlsim's hook names
        host = self.getParamValueByName("host")
        port = self.getParamValueByName("port")
        try:
            self.client = NckClient(host, port, rack=self.getParamValueByName("rack"),
                                    slot=self.getParamValueByName("slot")).connect()
        except NckError as exc:
            self.raiseException(f"cannot reach the controller at {host}:{port}: {exc}")
        self.bridge.client = self.client
        self.mirror = InputMirror(self.client)

    def doShutdown(self) -> None:  # noqa: N802
        if self.client is not None:
            self.client.close()
            self.client = None

    def readInputs(self) -> None:  # noqa: N802
        if self.mirror is not None:
            self.mirror.refresh()
