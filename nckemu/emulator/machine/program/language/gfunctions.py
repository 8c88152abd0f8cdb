"""The G functions of SINUMERIK 840D sl/828D: one table of their groups, from which the interpreter's G
handling, the straight-block fast path (blocks.py) and the list in docs/programs-language.md derive.

Each entry says its G group (the Siemens numbering), whether the group is modal, whether it is the
group's basic position after reset (the delivery state of MD20150 GCODE_RESET_VALUES as the Siemens
list marks it; a machine may change it, and the emulator takes group 1 from ``env.reset_motion``), and what the emulator does with it:

- ``RUN``: the interpreter acts on it (motion, plane, units, frames, feed type, ...);
- ``NO_EFFECT``: the control has it and a program using it runs here, but nothing the emulator models
  changes (logged once per program): path quality, look-ahead, corner behaviour, OEM functions;
- ``NOT_SUPPORTED``: the control has it and it changes what the machine does (a circle through an
  intermediate point, a reference point approach, an axial offset), so running on would give wrong
  positions or times: the block
  stops with 12550 naming the G function "not supported by the emulator".

A G number that is not in the table is no SINUMERIK G function (G43 of an ISO control, G999): 12470.
Two different G functions of one of the syntax-defining groups 1 to 3 (motion, non-modal motion,
frames) in one block raise 12070 (UNCONFIRMED number, alarms.py: ``G0 G1 X10``); of another group the
one written last is active (``G90 G91`` is G91), as we remember the control's rule for groups that do
not define the syntax of the block, or, where the machine file says ``repeated_g_group = "alarm"``, they
raise 12060 (both UNCONFIRMED).

Named members of a group (CIP, BRISK, TRANS, ...) are in the table too, for the group check and the
documentation list; their words are read by blocks.py.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from ..motions import ProgramAlarm
from .alarms import ALARM_G_GROUP_TWICE, ALARM_SYNTAX_G_TWICE


class Emulation(enum.Enum):
    RUN = "run"
    NO_EFFECT = "accepted without effect"
    NOT_SUPPORTED = "not supported by the emulator"


RUN = Emulation.RUN
NO_EFFECT = Emulation.NO_EFFECT
NOT_SUPPORTED = Emulation.NOT_SUPPORTED

# Groups whose G functions define the syntax of the block (motion, non-modal motion, frames):
# only one G function of each may be programmed in a block.
SYNTAX_DEFINING_GROUPS = frozenset({1, 2, 3})


@dataclass(frozen=True, slots=True)
class GFunction:
    name: str                 # "G1", "G641", "CIP"
    group: int                # Siemens G group number
    modal: bool               # stays active until another of its group (False: this block only)
    default: bool             # the group's basic position after reset
    emulation: Emulation
    straight: bool = False    # may stand in a STRAIGHT block (blocks.py fast path): a modal setting
                              # that needs none of the block's other words

    @property
    def number(self) -> int | None:
        """The G number (641 for G641), None for a named function (CIP)."""
        digits = self.name[1:]
        return int(digits) if self.name[0] == "G" and digits.isdigit() else None


# (group, modal, title, default member, members: name -> emulation, members allowed in STRAIGHT blocks)
_GROUPS: tuple[tuple[int, bool, str, str | None, dict[str, Emulation], frozenset[str]], ...] = (
    (1, True, "motion", "G1", {
        "G0": RUN, "G1": RUN, "G2": RUN, "G3": RUN, "CIP": NOT_SUPPORTED, "ASPLINE": RUN, "BSPLINE": RUN,
        "CSPLINE": RUN, "POLY": RUN, "G33": RUN, "G331": RUN, "G332": RUN,
        "OEMIPO1": NOT_SUPPORTED, "OEMIPO2": NOT_SUPPORTED, "CT": NOT_SUPPORTED, "G34": NOT_SUPPORTED,
        "G35": NOT_SUPPORTED, "INVCW": NOT_SUPPORTED, "INVCCW": NOT_SUPPORTED, "G335": NOT_SUPPORTED,
        "G336": NOT_SUPPORTED}, frozenset({"G0", "G1"})),
    (2, False, "non-modal motion, dwell", None, {
        "G4": RUN, "G63": NOT_SUPPORTED, "G74": NOT_SUPPORTED, "G75": NOT_SUPPORTED, "REPOSL": NOT_SUPPORTED,
        "REPOSQ": NOT_SUPPORTED, "REPOSH": NOT_SUPPORTED, "REPOSA": NOT_SUPPORTED, "REPOSQA": NOT_SUPPORTED,
        "REPOSHA": NOT_SUPPORTED, "G147": NO_EFFECT, "G247": NO_EFFECT, "G347": NO_EFFECT, "G148": NO_EFFECT,
        "G248": NO_EFFECT, "G348": NO_EFFECT, "G5": NOT_SUPPORTED, "G7": NOT_SUPPORTED}, frozenset()),
    # G25/G26 S..: the block's S is a spindle speed limit, not a speed (the limit is not applied)
    (3, False, "programmable frame, working area limit, pole", None, {
        "TRANS": RUN, "ATRANS": RUN, "ROT": RUN, "AROT": RUN, "SCALE": RUN, "ASCALE": RUN, "MIRROR": RUN,
        "AMIRROR": RUN, "G25": RUN, "G26": RUN, "G110": RUN, "G111": RUN,
        "G112": RUN, "G58": NOT_SUPPORTED, "G59": NOT_SUPPORTED, "ROTS": NOT_SUPPORTED,
        "AROTS": NOT_SUPPORTED}, frozenset()),
    (4, True, "FIFO", "STARTFIFO", {"STARTFIFO": NO_EFFECT, "STOPFIFO": NO_EFFECT, "FIFOCTRL": NO_EFFECT},
     frozenset()),
    (6, True, "plane", "G17", {"G17": RUN, "G18": RUN, "G19": RUN}, frozenset({"G17", "G18", "G19"})),
    (7, True, "tool radius compensation", "G40", {"G40": RUN, "G41": RUN, "G42": RUN},
     frozenset({"G40"})),
    (8, True, "settable work offset", "G500", {
        "G500": RUN, "G54": RUN, "G55": RUN, "G56": RUN, "G57": RUN,
        **{f"G{number}": RUN for number in range(505, 600)}}, frozenset()),
    (9, False, "frame suppression", None, {"G53": RUN, "G153": RUN, "SUPA": RUN, "SUPD": NO_EFFECT},
     frozenset()),
    (10, True, "exact stop, continuous path", "G60", {
        "G60": RUN, "G64": RUN, "G641": RUN, "G642": RUN, "G643": RUN, "G644": RUN, "G645": RUN},
     frozenset({"G60", "G64", "G641", "G642", "G643", "G644", "G645"})),
    (11, False, "exact stop, non-modal", None, {"G9": RUN}, frozenset()),
    (12, True, "block change at exact stop", "G601", {"G601": NO_EFFECT, "G602": NO_EFFECT, "G603": NO_EFFECT},
     frozenset({"G601", "G602", "G603"})),
    (13, True, "inch/metric", "G71", {"G70": RUN, "G71": RUN, "G700": RUN, "G710": RUN},
     frozenset({"G70", "G71", "G700", "G710"})),
    (14, True, "absolute/incremental", "G90", {"G90": RUN, "G91": RUN}, frozenset({"G90", "G91"})),
    (15, True, "feed type", "G94", {
        "G93": RUN, "G94": RUN, "G95": RUN, "G96": RUN, "G97": RUN, "G931": NO_EFFECT,
        "G961": NO_EFFECT, "G971": NO_EFFECT, "G942": NO_EFFECT, "G952": NO_EFFECT, "G962": NO_EFFECT,
        "G972": NO_EFFECT, "G973": NO_EFFECT}, frozenset({"G94", "G95"})),
    (16, True, "feed override at curves", "CFC", {"CFC": NO_EFFECT, "CFTCP": NO_EFFECT, "CFIN": NO_EFFECT},
     frozenset()),
    (17, True, "approach/retract with tool offset", "NORM", {
        "NORM": NO_EFFECT, "KONT": NO_EFFECT, "KONTT": NO_EFFECT, "KONTC": NO_EFFECT}, frozenset()),
    (18, True, "corner behaviour with radius compensation", "G450", {"G450": NO_EFFECT, "G451": NO_EFFECT},
     frozenset()),
    (19, True, "spline start", "BAUTO", {"BNAT": NO_EFFECT, "BTAN": NO_EFFECT, "BAUTO": NO_EFFECT}, frozenset()),
    (20, True, "spline end", "EAUTO", {"ENAT": NO_EFFECT, "ETAN": NO_EFFECT, "EAUTO": NO_EFFECT}, frozenset()),
    (21, True, "acceleration profile", "BRISK", {"BRISK": NO_EFFECT, "SOFT": NO_EFFECT, "DRIVE": NO_EFFECT},
     frozenset()),
    (22, True, "tool offset type", "CUT2D", {
        "CUT2D": NO_EFFECT, "CUT2DF": NO_EFFECT, "CUT3DC": NO_EFFECT, "CUT3DF": NO_EFFECT}, frozenset()),
    (23, True, "collision monitoring", "CDOF", {"CDOF": NO_EFFECT, "CDON": NO_EFFECT, "CDOF2": NO_EFFECT},
     frozenset()),
    (24, True, "feedforward control", "FFWOF", {"FFWOF": NO_EFFECT, "FFWON": NO_EFFECT}, frozenset()),
    (25, True, "tool orientation reference", "ORIWKS", {"ORIWKS": NO_EFFECT, "ORIMKS": NO_EFFECT},
     frozenset()),
    (28, True, "working area limitation", "WALIMON", {"WALIMON": NO_EFFECT, "WALIMOF": NO_EFFECT},
     frozenset()),
    (29, True, "radius/diameter programming", "DIAMOF", {
        "DIAMOF": RUN, "DIAMON": RUN, "DIAM90": RUN}, frozenset()),
    (30, True, "NC block compression", "COMPOF", {
        "COMPOF": NO_EFFECT, "COMPON": NO_EFFECT, "COMPCURV": NO_EFFECT, "COMPCAD": NO_EFFECT,
        "COMPSURF": NO_EFFECT}, frozenset()),
    (31, True, "OEM G functions", "G810", {f"G{number}": NO_EFFECT for number in range(810, 820)}, frozenset()),
    (32, True, "OEM G functions", "G820", {f"G{number}": NO_EFFECT for number in range(820, 830)}, frozenset()),
    (33, True, "fine tool offset", "FTOCOF", {"FTOCOF": NO_EFFECT, "FTOCON": NO_EFFECT}, frozenset()),
    (37, True, "feed profile", "FNORM", {"FNORM": NO_EFFECT, "FLIN": NO_EFFECT, "FCUB": NO_EFFECT}, frozenset()),
    (43, True, "soft approach/retract direction", "G140", {
        "G140": NO_EFFECT, "G141": NO_EFFECT, "G142": NO_EFFECT, "G143": NO_EFFECT}, frozenset()),
    (44, True, "soft approach/retract segments", "G340", {"G340": NO_EFFECT, "G341": NO_EFFECT}, frozenset()),
    (45, True, "path reference for FGROUP axes", "SPATH", {"SPATH": NO_EFFECT, "UPATH": NO_EFFECT}, frozenset()),
    (47, True, "external NC languages", "G290", {"G290": NO_EFFECT, "G291": NOT_SUPPORTED}, frozenset()),
    (48, True, "approach/retract with radius compensation", "G460", {
        "G460": NO_EFFECT, "G461": NO_EFFECT, "G462": NO_EFFECT}, frozenset()),
    (49, True, "point-to-point motion", "CP", {"CP": NO_EFFECT, "PTP": NO_EFFECT, "PTPG0": NO_EFFECT},
     frozenset()),
    (50, True, "orientation programming", "ORIEULER", {
        "ORIEULER": NO_EFFECT, "ORIRPY": NO_EFFECT, "ORIVIRT1": NO_EFFECT, "ORIVIRT2": NO_EFFECT,
        "ORIAXPOS": NO_EFFECT, "ORIRPY2": NO_EFFECT}, frozenset()),
    (51, True, "orientation interpolation", "ORIVECT", {"ORIVECT": NO_EFFECT, "ORIAXES": NO_EFFECT}, frozenset()),
    (52, True, "frame rotation to the workpiece", "PAROTOF", {"PAROTOF": NO_EFFECT, "PAROT": NO_EFFECT},
     frozenset()),
    (56, True, "frame rotation to the tool", "TOROTOF", {"TOROTOF": NO_EFFECT, "TOROT": NO_EFFECT}, frozenset()),
    (57, True, "corner deceleration", "FENDNORM", {
        "FENDNORM": NO_EFFECT, "G62": NO_EFFECT, "G621": NO_EFFECT}, frozenset()),
    (58, True, "path dynamics", "DYNNORM", {
        "DYNNORM": NO_EFFECT, "DYNPOS": NO_EFFECT, "DYNROUGH": NO_EFFECT, "DYNSEMIFIN": NO_EFFECT,
        "DYNFINISH": NO_EFFECT, "DYNPREC": NO_EFFECT}, frozenset()),
    (61, True, "tool orientation smoothing", "ORISOF", {"ORISOF": NO_EFFECT, "ORISON": NO_EFFECT}, frozenset()),
)

GROUP_TITLES: dict[int, str] = {group: title for group, _, title, _, _, _ in _GROUPS}
# each group's members in the Siemens list's order: $P_GG[n] and G[n]= count in it from 1
GROUP_MEMBERS: dict[int, tuple[str, ...]] = {group: tuple(members) for group, _, _, _, members, _ in _GROUPS}
GROUP_DEFAULTS: dict[int, str] = {group: default for group, _, _, default, _, _ in _GROUPS if default}


def _build() -> dict[str, GFunction]:
    table: dict[str, GFunction] = {}
    for group, modal, _title, default, members, straight in _GROUPS:
        for name, emulation in members.items():
            table[name] = GFunction(name, group, modal, name == default, emulation, name in straight)
    return table


G_FUNCTIONS: dict[str, GFunction] = _build()
# by G number, for the address G<n> (the interpreter's look-up on every G word)
BY_NUMBER: dict[int, GFunction] = {
    entry.number: entry for entry in G_FUNCTIONS.values() if entry.number is not None}
# G numbers a STRAIGHT block may carry
STRAIGHT_G: frozenset[int] = frozenset(number for number, entry in BY_NUMBER.items() if entry.straight)
# G numbers the control has that change nothing the emulator models
NO_EFFECT_G: frozenset[int] = frozenset(
    number for number, entry in BY_NUMBER.items() if entry.emulation is NO_EFFECT)


def number_in_group(group: int, name: str | None) -> int:
    """What ``$P_GG[group]`` reads for the active ``name``: its place in its group's list, from 1 (0 when
    the group has nothing active or the emulator does not know the group)."""
    members = GROUP_MEMBERS.get(group, ())
    return members.index(name) + 1 if name in members else 0


def group_of(name: str) -> int | None:
    """The G group of a G function or named group member (``"G1"``, ``"CIP"``), None when it has none."""
    entry = G_FUNCTIONS.get(name)
    return entry.group if entry is not None else None


def conflict(names: list[str], every_group: bool = False) -> tuple[str, str, int] | None:
    """Two different G functions of one syntax-defining group (of any group: ``every_group``) among
    ``names`` (block order): (first, second, group), else None."""
    seen: dict[int, str] = {}
    for name in names:
        entry = G_FUNCTIONS.get(name)
        if entry is None or (not every_group and entry.group not in SYNTAX_DEFINING_GROUPS):
            continue
        earlier = seen.get(entry.group)
        if earlier is not None and earlier != name:
            return earlier, name, entry.group
        seen[entry.group] = name
    return None


def check_block(names: list[str], every_group: bool = False) -> None:
    """Raise 12070 when ``names`` (a block's G functions, in order) hold two of one syntax-defining group.

    Two of another group (G90 G91, SOFT BRISK) are no alarm: the one written last is active, as the
    control does with groups that do not define the block's syntax; with ``every_group`` (the machine
    file's ``repeated_g_group = "alarm"``) they raise 12060."""
    clash = conflict(names)
    if clash is not None:
        first, second, group = clash
        raise ProgramAlarm(ALARM_SYNTAX_G_TWICE, f"too many syntax-defining G functions: {first} and {second} "
                                                 f"(group {group}, {GROUP_TITLES[group]}) in one block")
    clash = conflict(names, every_group=True) if every_group else None
    if clash is not None:
        first, second, group = clash
        raise ProgramAlarm(ALARM_G_GROUP_TWICE, f"same G group programmed repeatedly: {first} and {second} "
                                                f"(group {group}, {GROUP_TITLES[group]}) in one block")


def markdown_table() -> str:
    """The list of docs/programs-language.md (a test keeps the page equal to it)."""
    lines = ["| group | what | modal | after reset | run | accepted without effect | not supported |",
             "|---|---|---|---|---|---|---|"]
    for group, modal, title, default, members, _ in _GROUPS:
        by_kind = {kind: _names([name for name, emulation in members.items() if emulation is kind])
                   for kind in Emulation}
        lines.append(f"| {group} | {title} | {'yes' if modal else 'no'} | {default or '–'} | "
                     f"{by_kind[RUN]} | {by_kind[NO_EFFECT]} | {by_kind[NOT_SUPPORTED]} |")
    return "\n".join(lines) + "\n"


def _names(names: list[str]) -> str:
    """``G505…G599`` for a run of consecutive G numbers, the names otherwise."""
    parts: list[str] = []
    index = 0
    while index < len(names):
        run_end = index
        while (run_end + 1 < len(names) and names[run_end].startswith("G") and names[run_end + 1].startswith("G")
               and names[run_end][1:].isdigit() and names[run_end + 1][1:].isdigit()
               and int(names[run_end + 1][1:]) == int(names[run_end][1:]) + 1):
            run_end += 1
        if run_end - index >= 3:
            parts.append(f"{names[index]}…{names[run_end]}")
        else:
            parts.extend(names[index:run_end + 1])
        index = run_end + 1
    return " ".join(f"`{part}`" for part in parts) or "–"
