"""The machine: what a SINUMERIK NCU holds, whichever face a client comes through.

``core.Emulator`` composes the NCK model (``nck/``: variables, axes, compensation, programs, PI
services, alarms, tools, frames), the PLC memory (``plc/``: DBs, sensor inputs, SZL, the 840C command
channel), the machine file (``machine_file``; the built-in default is ``machines/default.toml``), the
clock (``clock``), retained state (``state``), the cycle a living machine runs on (``cycle``) and
what the machine is doing now (``status``). Nothing here imports a face.
"""
