"""The SINUMERIK part-program language: lexer, parser, expressions, control flow, subprograms.

::

    interp = Interpreter(env, "/_N_MPF_DIR/_N_DAILY_MPF", text)
    for event in interp.events():   # motions.Event, a Block before each executed block
        ...

The subset, what is accepted without effect, and the alarms: docs/programs-language.md.
"""

from .interpreter import Interpreter

__all__ = ["Interpreter"]
