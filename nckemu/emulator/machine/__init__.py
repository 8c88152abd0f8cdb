"""The machine: what a SINUMERIK NCU holds, whichever face a client comes through.

``core.Emulator`` composes the NCK model (``nck/``: variables, axes, compensation, programs, PI
services, alarms, tools, frames), the PLC memory (``plc/``: DBs, sensor inputs, SZL, the 840C command
channel), the machine file (``machine_file``; the built-in default is ``machines/default.toml``), the
clock (``clock``), retained state (``state``), the cycle a living machine runs on (``cycle``) and
what the machine is doing now (``status``); ``offline`` runs a program on it without a server and
``frame_math`` is the frame arithmetic the interpreter (``program/``) and the NCK's frames share.
Nothing here imports a face, and no two parts import each other round (``.importlinter``'s acyclic
contract, type imports counted): a part names what it needs of others in a protocol of its own.
"""
