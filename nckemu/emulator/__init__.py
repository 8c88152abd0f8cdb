"""The emulated controller: one machine, several ways in.

- ``machine/``: the machine itself: the NCK model (``nck/``), the PLC memory (``plc/``), the machine
  file, the clock, retained state and :class:`~nckemu.emulator.machine.core.Emulator`, which composes
  them. It imports no face.
- ``faces/``: the ways in, one sub-package each: ``s7/`` (ISO-on-TCP, sans-IO session, dispatch),
  ``opcua/`` (asyncua, SINUMERIK node ids), ``web/`` (the live page). A face imports the machine and
  never another face.
- At this level, the parts that compose a machine with its faces: ``commands`` (``nckemu serve``),
  ``runner`` (a machine and its S7 face in a thread, for tests and ``trace replay --spawn``) and
  ``fleet`` (many machines, each with its faces, on one event loop).
"""
