"""Part programs on the emulated channel: interpreter -> canonical motions -> planner -> channel.

The seam is the one RS274NGC and LinuxCNC use. ``language/`` walks a program's blocks and emits the
events of :mod:`.motions`; it reads and writes the NCK's values only through
:class:`.environment.ProgramEnvironment`, never bytes or sockets. The planner turns each motion into
simulated time and never sees program text. The channel steps both on the emulator's clock and owns
the state the controller reports; the run that feeds the interpreter the NCK's values and moves the
channel's axes is the NCK's (``nck/program_run.py``): this package imports nothing of the NCK.
"""
