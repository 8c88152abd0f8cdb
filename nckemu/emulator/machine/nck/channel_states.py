"""The numbers a channel's state is reported in (BTSS chanStatus, progStatus, acProg, opMode), apart
from the channel so that the PLC interface can read them without importing the channel.

chanStatus 0 reset, 1 active, 2 interrupted (two sources); progStatus 1 interrupted, 2 stopped,
3 running, 4 waiting, 5 aborted (2, 3, 5 one source; 1 and 4 unconfirmed); acProg 0 reset, 1 stopped,
2 running, 3 waiting, 4 interrupted (one source); opMode 0 JOG, 1 MDA, 2 AUTOMATIC.
"""

CHAN_RESET, CHAN_ACTIVE, CHAN_INTERRUPTED = 0, 1, 2
PROG_INTERRUPTED, PROG_STOPPED, PROG_RUNNING, PROG_WAITING, PROG_ABORTED = 1, 2, 3, 4, 5
AC_RESET, AC_STOPPED, AC_RUNNING, AC_WAITING, AC_INTERRUPTED = 0, 1, 2, 3, 4
MODE_JOG, MODE_MDA, MODE_AUTOMATIC = 0, 1, 2
MODE_NAMES = {MODE_JOG: "JOG", MODE_MDA: "MDA", MODE_AUTOMATIC: "AUTOMATIC"}
