"""A block's tokens compiled into what the interpreter executes.

``compile_block`` turns one line (comment already stripped) into a :class:`Compiled`: a kind (plain
words, IF, WHILE, FOR, ...) and its items. Address words with constant values stay constants; every
expression becomes a closure (expressions.py). Names are resolved by category here (R parameter,
system variable, variable, axis, address letter); whether a variable exists is checked when it is
read, so a compiled block can be kept and run again in a loop.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from ..motions import ALARM_NAME_NOT_DEFINED, ALARM_SYNTAX, ProgramAlarm
from .expressions import FUNCTIONS, NAME, NUM, OP, STR, Parser, is_dynamic
from .gfunctions import G_FUNCTIONS, GROUP_TITLES, NO_EFFECT, NOT_SUPPORTED, STRAIGHT_G, check_block
from .words import (
    AddressWord,
    Assign,
    AxisSetting,
    AxisWord,
    Call,
    CentreWord,
    Fill,
    FrameWord,
    GWord,
    IndirectAxisWord,
    Jump,
    ModalCall,
    Msg,
    NoOp,
    PositionWord,
    Return,
    Setal,
    Spos,
    Suppress,
    WaitPosition,
    Word,
)

# block kinds
WORDS, IF, ELSE, ENDIF, WHILE, ENDWHILE, FOR, ENDFOR, REPEAT, UNTIL, LOOP, ENDLOOP = range(12)
IF_JUMP, CASE, DEF, PROC, EXTERN, NOTHING, STRAIGHT, SECTION = range(12, 20)

_KEYWORD_KINDS = {"ELSE": ELSE, "ENDIF": ENDIF, "ENDWHILE": ENDWHILE, "ENDFOR": ENDFOR,
                  "REPEAT": REPEAT, "LOOP": LOOP, "ENDLOOP": ENDLOOP}


SINGLE_ADDRESSES = frozenset("FSMTDHLPIJKE")
WORD_ADDRESSES = frozenset({"CR", "TURN", "AR", "AP", "RP", "PW", "SD", "PL", "LIMS", "OVR", "SPOS", "SPOSA"})
# Addresses taking an extension as digits before '=' (M1=3: spindle 1, M3)
EXTENDED = frozenset("MSHTD")
FRAME_WORDS = frozenset({"TRANS", "ATRANS", "ROT", "AROT", "SCALE", "ASCALE", "MIRROR", "AMIRROR"})
JUMPS = frozenset({"GOTOF", "GOTOB", "GOTO", "GOTOC", "GOTOS"})
# Per-axis settings written as NAME[axis]=value; kept so a program can read them back (ACC[X]).
AXIS_SETTINGS = frozenset({"ACC", "FA", "FL", "FGREF", "OVRA", "VELOLIM", "JERKLIM"})
# Positioning axes: POS (the block waits for the axis), POSA (it runs on past the block), POSP (in
# sections; run here as POS to its end point)
POSITIONING = frozenset({"POS", "POSA", "POSP"})

# Words that change nothing the emulator models: accepted, logged once (docs/programs-language.md).
NO_OP_WORDS = frozenset({
    "STOPRE", "BRISK", "BRISKA", "SOFT", "SOFTA", "DRIVE", "DRIVEA", "FFWON", "FFWOF", "CFC", "CFTCP",
    "CFIN", "COMPOF", "COMPON", "COMPCAD", "COMPCURV", "COMPSURF", "TRAFOOF", "TRAORI", "ORIWKS",
    "ORIMKS", "ORIAXES", "ORIVECT", "ORIAXPOS", "ORIEULER", "ORIRPY", "CUT2D", "CUT2DF", "CUT3DC",
    "CUT3DF", "DIAMOF", "DIAMON", "DIAM90", "UPATH", "SPATH", "FNORM", "FLIN", "FCUB", "DYNNORM",
    "DYNPOS", "DYNROUGH", "DYNSEMIFIN", "DYNFINISH", "WALIMON", "WALIMOF", "NORM", "KONT", "KONTC",
    "KONTT", "BNAT", "BTAN", "BAUTO", "ENAT", "ETAN", "EAUTO", "PTP", "CP", "PTPG0", "SPOF", "SPIF1",
    "SPIF2", "DISPLOF", "DISPLON", "SAVE", "SBLOF", "SBLON", "DRFOF", "ACN", "ACP", "DC", "CDON",
    "CDOF", "CDOF2", "DISC", "OFFN", "FENDNORM", "TOFFON", "TOFFOF", "G40", "RESET", "WAITMC",
    "FGROUP", "FTOCON", "FTOCOF", "ORISON", "ORISOF", "PAROT", "PAROTOF", "TOROT", "TOROTOF",
    "TCARR", "TCOABS", "TCOFR", "SUPD", "CPROTDEF", "LIFTFAST", "SETMS", "PROTA", "PROTS",
    "WAITS",  # the spindles it waits for (SPOS, SPOSA) stop at once here
}) | frozenset(name for name, entry in G_FUNCTIONS.items() if entry.number is None and entry.emulation is NO_EFFECT)
# Named G functions of the control that the emulator cannot run right (CIP, CT, REPOSA, ...): 12550.
NOT_SUPPORTED_WORDS = frozenset(
    name for name, entry in G_FUNCTIONS.items() if entry.number is None and entry.emulation is NOT_SUPPORTED)
SPLINES = frozenset({"ASPLINE", "BSPLINE", "CSPLINE", "POLY"})

# X=IC(..) incremental, AC absolute; for rotary axes DC/ACP/ACN (shortest way, positive, negative
# direction) and CIC are absolute/incremental positions here (the direction is not modelled)
_DIMENSION_MODES = {"IC": "IC", "AC": "AC", "DC": "AC", "ACP": "AC", "ACN": "AC", "CIC": "IC"}
_ADDRESS_WORD = re.compile(r"([A-Z]+?)(\d+)")


@dataclass(frozen=True, slots=True)
class Section:
    """A program section repetition: run the lines from label ``start`` to ``end`` (the line before
    the REPEAT when None; the ENDLABEL: line for "ENDLABEL"; ``start`` alone when ``single``)
    ``count`` times (an expression), then go on after the REPEAT."""

    start: str
    end: str | None
    count: Any
    single: bool = False


class Compiled:
    __slots__ = ("number", "kind", "items", "text")

    def __init__(self, number: str, kind: int, items: Any, text: str) -> None:
        self.number = number
        self.kind = kind
        self.items = items
        self.text = text


# A block of address words with constant values only (most CAM blocks): N10 G1 X12.5 Y-3 F1200
_SIMPLE_BLOCK = re.compile(r"(?:[ \t]*[A-Z]+[ \t]*=?[ \t]*[+-]?(?:\d+\.?\d*|\.\d+))+[ \t]*", re.IGNORECASE)
_SIMPLE_WORD = re.compile(r"([A-Z]+)[ \t]*=?[ \t]*([+-]?(?:\d+\.?\d*|\.\d+))", re.IGNORECASE)
# The same words as a CAM post writes them (ASCII letters, an optional '=', a number, blanks after it),
# found in one pass: (letters, digits, "") per word, and ("", "", char) for a character no such word
# takes. Without one of those the words are _SIMPLE_WORD's and _SIMPLE_BLOCK matches (a word's
# boundaries are forced: it starts at a letter, its number ends at the next letter or blank); with one,
# the pair of scans over any text decides as before (X = 10, the Kelvin sign IGNORECASE takes for K,
# Arabic digits \d takes). Possessive quantifiers: nothing after a word's part can need it shorter.
# A third of the cost of the pair.
_CAM_WORDS = re.compile(r"([A-Za-z]++)=?+([+-]?+(?:[0-9]++\.?+[0-9]*+|\.[0-9]++))[ \t]*+|(.)", re.DOTALL)
_SIMPLE_ADDRESSES = frozenset({"M", "S", "F", "T", "D", "H", "CR", "TURN"})
_G_WORD, _F_WORD, _N_WORD = 1, 2, 3
# The digits of a G a STRAIGHT block may hold, as written (G1, G01, G90), to the G number
_STRAIGHT_G_DIGITS = {digits: code for code in STRAIGHT_G
                      for digits in (str(code), f"{code:02d}", f"{code:03d}")}


class BlockCompiler:
    """Compiles blocks for one interpreter (it knows the axes and how names resolve)."""

    def __init__(self, axes: tuple[str, ...], resolver: Any, repeated_g_alarm: bool = False) -> None:
        self.axes = frozenset(axis.upper() for axis in axes)
        self.resolver = resolver
        # two G functions of one group that does not define the syntax: 12060 (True) or the last wins
        self.repeated_g_alarm = repeated_g_alarm
        # letters of a STRAIGHT block in either case -> an axis' upper-case name (a str), or G, F, N as
        # _G_WORD, _F_WORD, _N_WORD (ints: told apart from a name by the class alone)
        self._straight_words: dict[str, str | int] = {}
        for axis in self.axes:
            self._straight_words[axis] = self._straight_words[axis.lower()] = axis
        for kind, letter in ((_G_WORD, "G"), (_F_WORD, "F"), (_N_WORD, "N")):
            if letter not in self.axes:
                self._straight_words[letter] = self._straight_words[letter.lower()] = kind

    def compile_simple(self, text: str) -> Compiled | None:
        """The fast way for a block of constant address words, or None (then :meth:`compile`)."""
        words = _CAM_WORDS.findall(text)
        straight = self._straight(words, text)
        if straight is not None:
            return straight
        for word in words:
            if word[2]:  # a character no CAM word takes: the scans over any text decide
                return self._compile_simple_any(text)
        return self._simple_words(words, text)

    def _compile_simple_any(self, text: str) -> Compiled | None:
        if _SIMPLE_BLOCK.fullmatch(text) is None:
            return None
        words = [(letters, digits, "") for letters, digits in _SIMPLE_WORD.findall(text)]
        return self._straight(words, text) or self._simple_words(words, text)

    def _simple_words(self, words: list[tuple[str, str, str]], text: str) -> Compiled | None:
        items: list[tuple] = []
        number = ""
        axes = self.axes
        for index, (letters, digits, _) in enumerate(words):
            letters = letters.upper()
            value: float | int = float(digits) if "." in digits else int(digits)
            if letters in axes:
                items.append(AxisWord(letters, value))
            elif letters == "G":
                if value.__class__ is float or value < 0:
                    return None
                items.append(GWord(value))
            elif letters == "N":
                if index or value.__class__ is float or value < 0:
                    return None
                number = "N" + digits
            elif letters in _SIMPLE_ADDRESSES:
                if letters == "M" and (value.__class__ is float or value < 0):
                    return None
                items.append(AddressWord(letters, value))
            elif letters in ("I", "J", "K"):
                items.append(CentreWord(letters, value))
            else:
                return None
        _check_groups(items, self.repeated_g_alarm)
        return Compiled(number, WORDS, items, text)

    def _straight(self, words: list[tuple[str, str, str]], text: str) -> Compiled | None:
        """A STRAIGHT block (only modal G of STRAIGHT_G, each axis once, F), or None."""
        known = self._straight_words
        g_codes: list[int] = []
        targets: dict[str, float] = {}
        feed = None
        number = ""
        for letters, digits, _ in words:
            entry = known.get(letters)
            if entry is None:
                return None  # not a STRAIGHT letter, or ("", "", char): not a word at all
            if entry.__class__ is str:  # an axis
                if entry in targets:
                    return None
                targets[entry] = float(digits)
            elif entry == _G_WORD:
                code = _STRAIGHT_G_DIGITS.get(digits)
                if code is None:
                    if not digits.isdigit() or int(digits) not in STRAIGHT_G:
                        return None
                    code = int(digits)
                g_codes.append(code)
            elif entry == _F_WORD and feed is None:
                feed = float(digits)
            elif entry == _N_WORD and not number and not targets and not g_codes and feed is None and digits.isdigit():
                number = "N" + digits  # the block number: the first word
            else:
                return None
        if len(g_codes) > 1:
            check_block([f"G{code}" for code in g_codes], self.repeated_g_alarm)
        return Compiled(number, STRAIGHT, (tuple(g_codes), targets, feed), text)  # targets: read only

    def compile(self, text: str, tokens: list) -> Compiled:
        parser = Parser(tokens, self.resolver)
        number = ""
        if parser.at_op("/"):  # block skip (executed: no skip level is active in the emulator)
            parser.pos += 1
            token = parser.peek()
            if token is not None and token[0] == NUM:
                parser.pos += 1
        token = parser.peek()
        if token is not None and token[0] == NAME and token[2] is None and re.fullmatch(r"N\d+", token[1]):
            number = token[1]
            parser.pos += 1
        elif parser.at_op(":") and parser.pos + 1 < len(tokens) and tokens[parser.pos + 1][0] == NUM:
            number = ":" + str(tokens[parser.pos + 1][1])
            parser.pos += 2
        token = parser.peek()
        if (token is not None and token[0] == NAME and token[2] is None and parser.pos + 1 < len(tokens)
                and tokens[parser.pos + 1][0] == OP and tokens[parser.pos + 1][1] == ":"):
            parser.pos += 2  # a label
        token = parser.peek()
        if token is None:
            return Compiled(number, NOTHING, (), text)
        if token[0] == NAME and token[2] is None:
            keyword = token[1]
            kind = _KEYWORD_KINDS.get(keyword)
            if keyword in ("REPEAT", "REPEATB") and (keyword == "REPEATB" or parser.pos + 1 < len(tokens)):
                parser.pos += 1
                return Compiled(number, SECTION, self._section(parser, keyword), text)
            if kind is not None:
                parser.pos += 1
                if not parser.at_end():
                    raise ProgramAlarm(ALARM_SYNTAX, f"{keyword} stands alone in its block")
                return Compiled(number, kind, (), text)
            if keyword in ("IF", "WHILE", "UNTIL"):
                parser.pos += 1
                condition = parser.expression()
                if keyword == "IF" and not parser.at_end():
                    # IF c1 GOTOF A IF c2 GOTOF B: conditional jumps tried in order, the first true jumps
                    jumps = [(condition, self._jump(parser))]
                    while parser.at_name("IF"):
                        parser.pos += 1
                        jumps.append((parser.expression(), self._jump(parser)))
                    self._end(parser)
                    return Compiled(number, IF_JUMP, tuple(jumps), text)
                self._end(parser)
                return Compiled(number, {"IF": IF, "WHILE": WHILE, "UNTIL": UNTIL}[keyword], condition, text)
            if keyword == "FOR":
                parser.pos += 1
                target = self._lvalue(parser)
                parser.expect_op("=")
                start = parser.expression()
                if not parser.at_name("TO"):
                    raise ProgramAlarm(ALARM_SYNTAX, "FOR needs TO")
                parser.pos += 1
                end = parser.expression()
                self._end(parser)
                return Compiled(number, FOR, (target, start, end), text)
            if keyword == "CASE":
                return Compiled(number, CASE, self._case(parser), text)
            if keyword == "DEF":
                parser.pos += 1
                return Compiled(number, DEF, self._def(parser), text)
            if keyword == "PROC":
                parser.pos += 1
                return Compiled(number, PROC, self.proc_header(parser), text)
            if keyword == "EXTERN":
                return Compiled(number, EXTERN, (), text)
        items = self._words(parser)
        _check_groups(items, self.repeated_g_alarm)
        return Compiled(number, WORDS, items, text)

    # --- pieces ----------------------------------------------------------------------------------
    def _section(self, parser: Parser, keyword: str) -> Section:
        """Program section repetition: ``REPEAT START [END | ENDLABEL] [P=n]`` or ``REPEATB LABEL [P=n]``."""
        start = self._target(parser)
        end: str | None = None
        if keyword == "REPEAT" and not parser.at_end() and not parser.at_name("P") \
                and not self._at_repeat_count(parser):
            end = self._target(parser)
        count: Any = 1
        if not parser.at_end():
            count = self._repeat(parser)
            if count is None:
                token = parser.peek()
                raise ProgramAlarm(ALARM_SYNTAX, f"{keyword}: P=count expected, found {token[1]!r}")  # type: ignore[index]
        self._end(parser)
        return Section(start, end, count, single=keyword == "REPEATB")

    @staticmethod
    def _at_repeat_count(parser: Parser) -> bool:
        token = parser.peek()
        return token is not None and token[0] == NAME and re.fullmatch(r"P\d+", token[1]) is not None

    def _end(self, parser: Parser) -> None:
        if not parser.at_end():
            token = parser.peek()
            raise ProgramAlarm(ALARM_SYNTAX, f"unexpected {token[1]!r}")  # type: ignore[index]

    def _jump(self, parser: Parser) -> tuple[str, Any]:
        token = parser.peek()
        if token is None or token[0] != NAME or token[1] not in JUMPS:
            raise ProgramAlarm(ALARM_SYNTAX, "GOTOF, GOTOB, GOTO or GOTOC expected")
        parser.pos += 1
        if token[1] == "GOTOS":  # back to the program's start: no target
            return token[1], ""
        return token[1], self._target(parser)

    def _target(self, parser: Parser) -> Any:
        token = parser.peek()
        if token is None:
            raise ProgramAlarm(ALARM_SYNTAX, "jump target expected")
        parser.pos += 1
        if token[0] == NAME and token[2] is None:
            return token[1]
        if token[0] == NUM and isinstance(token[1], int):
            return f"N{token[1]}"
        if token[0] == STR:
            return token[1].upper()
        raise ProgramAlarm(ALARM_SYNTAX, "jump target expected")

    def _case(self, parser: Parser) -> tuple[Any, list, Any]:
        parser.pos += 1
        # CASE (R1) OF ... as the manual writes it; shop programs also write CASE LADAO[37] OF ...,
        # which the control reads the same (the brackets are the expression's own)
        selector = parser.expression()
        if not parser.at_name("OF"):
            raise ProgramAlarm(ALARM_SYNTAX, "CASE needs OF")
        parser.pos += 1
        branches: list[tuple[Any, tuple[str, Any]]] = []
        default = None
        while not parser.at_end():
            if parser.at_name("DEFAULT"):
                parser.pos += 1
                default = self._jump(parser)
                continue
            value = parser.expression()
            if is_dynamic(value):
                raise ProgramAlarm(ALARM_SYNTAX, "CASE values are constants")
            branches.append((value, self._jump(parser)))
        return selector, branches, default

    def _def(self, parser: Parser) -> list[tuple[str, str, tuple, Any, bool]]:
        token = parser.peek()
        shared = False  # DEF NCK/CHAN: a global variable (GUD), seen by every program of the run
        if token is not None and token[0] == NAME and token[1] in ("NCK", "CHAN"):
            parser.pos += 1
            shared = True
        token = _skip_attributes(parser)
        if token is None or token[0] != NAME or token[1] not in ("INT", "REAL", "BOOL", "STRING", "CHAR", "AXIS"):
            found = token[1] if token else "end of block"
            raise ProgramAlarm(ALARM_SYNTAX, f"DEF: type expected, found {found!r}")
        kind = token[1]
        parser.pos += 1
        if kind == "STRING":
            parser.expect_op("[")
            length = parser.expression()
            parser.expect_op("]")
            if is_dynamic(length):
                raise ProgramAlarm(ALARM_SYNTAX, "DEF STRING[n]: n is a constant")
        declarations = []
        while True:
            token = _skip_attributes(parser)
            if token is None or token[0] != NAME or token[2] is not None:
                raise ProgramAlarm(ALARM_SYNTAX, "DEF: name expected")
            name = token[1]
            parser.pos += 1
            dims: tuple[int, ...] = ()
            if parser.at_op("["):
                sizes = parser.indices()
                if len(sizes) > 3 or any(is_dynamic(size) or not isinstance(size, int) for size in sizes):
                    raise ProgramAlarm(ALARM_SYNTAX, f"DEF {name}: up to three constant INT sizes")
                dims = tuple(sizes)
            init = None
            if parser.at_op("="):
                parser.pos += 1
                init = self._initialiser(parser)
            declarations.append((name, kind, dims, init, shared))
            if parser.at_op(","):
                parser.pos += 1
                continue
            self._end(parser)
            return declarations

    def _initialiser(self, parser: Parser) -> tuple[str, Any]:
        """("value", expr) or ("SET"/"REP", [exprs])."""
        if (parser.at_name("SET") or parser.at_name("REP")) and parser.pos + 1 < len(parser.tokens) \
                and parser.tokens[parser.pos + 1][1] == "(":
            which = parser.peek()[1]  # type: ignore[index]
            parser.pos += 1
            args = parser.arguments()
            if not args or any(arg is None for arg in args) or (which == "REP" and len(args) != 1):
                raise ProgramAlarm(ALARM_SYNTAX, f"{which}(...) needs values")
            return which, args
        return "value", parser.expression()

    def proc_header(self, parser: Parser) -> tuple[str, list[tuple[str, str, bool, tuple]]]:
        token = parser.peek()
        if token is None or token[0] != NAME:
            raise ProgramAlarm(ALARM_SYNTAX, "PROC: name expected")
        name = token[1]
        parser.pos += 1
        params: list[tuple[str, str, bool, tuple]] = []
        if parser.at_op("("):
            parser.pos += 1
            while not parser.at_op(")"):
                by_reference = False
                if parser.at_name("VAR"):
                    by_reference = True
                    parser.pos += 1
                token = parser.peek()
                if token is None or token[0] != NAME or token[1] not in ("INT", "REAL", "BOOL", "STRING",
                                                                         "CHAR", "AXIS"):
                    raise ProgramAlarm(ALARM_SYNTAX, "PROC: parameter type expected")
                kind = token[1]
                parser.pos += 1
                if kind == "STRING":
                    parser.expect_op("[")
                    parser.expression()
                    parser.expect_op("]")
                token = parser.peek()
                if token is None or token[0] != NAME:
                    raise ProgramAlarm(ALARM_SYNTAX, "PROC: parameter name expected")
                parser.pos += 1
                dims: tuple = ()
                if parser.at_op("["):
                    sizes = parser.indices()
                    dims = tuple(sizes)
                params.append((token[1], kind, by_reference, dims))
                if parser.at_op(","):
                    parser.pos += 1
                elif not parser.at_op(")"):
                    raise ProgramAlarm(ALARM_SYNTAX, "PROC: ',' or ')' expected")
            parser.pos += 1
        return name, params

    def _lvalue(self, parser: Parser) -> tuple[str, str, list]:
        """("R", index-expr, []) | ("VAR", name, [index exprs]) | ("SYS", name, [index exprs])."""
        token = parser.peek()
        if token is None or token[0] != NAME or token[2] is not None:
            raise ProgramAlarm(ALARM_SYNTAX, "variable expected")
        parser.pos += 1
        name = token[1]
        match = re.fullmatch(r"\$?R(\d+)", name)
        if match:
            return "R", int(match.group(1)), []
        indices = parser.indices() if parser.at_op("[") else []
        if name in ("R", "$R") and indices:
            return "R", indices[0], []
        if name.startswith("$"):
            return "SYS", name, indices
        return "VAR", name, indices

    def _value_after(self, parser: Parser, name: str, frac: str | None) -> Any:
        """The value of an address word: ``=expr``, a signed constant, or nothing (None)."""
        if frac is not None:
            return float(frac) if frac != "." else 0.0
        if parser.at_op("="):
            parser.pos += 1
            return parser.expression()
        token = parser.peek()
        if token is None:
            return None
        if token[0] == NUM:
            parser.pos += 1
            return token[1]
        if token[0] == OP and token[1] in ("-", "+") and parser.pos + 1 < len(parser.tokens) \
                and parser.tokens[parser.pos + 1][0] == NUM:
            parser.pos += 2
            value = parser.tokens[parser.pos - 1][1]
            return -value if token[1] == "-" else value
        return None

    def _axis_value(self, parser: Parser, frac: str | None) -> tuple[Any, str | None]:
        """An axis value and its dimension mode (None, "IC", "AC")."""
        if frac is None and parser.at_op("="):
            token = parser.tokens[parser.pos + 1] if parser.pos + 1 < len(parser.tokens) else None
            if token is not None and token[0] == NAME and token[1] in _DIMENSION_MODES and \
                    parser.pos + 2 < len(parser.tokens) and parser.tokens[parser.pos + 2][1] == "(":
                parser.pos += 2
                args = parser.arguments()
                if len(args) != 1 or args[0] is None:
                    raise ProgramAlarm(ALARM_SYNTAX, f"{token[1]}(...) takes one value")
                return args[0], _DIMENSION_MODES[token[1]]
        value = self._value_after(parser, "", frac)
        if value is None:
            raise ProgramAlarm(ALARM_SYNTAX, "axis value expected")
        return value, None

    def _words(self, parser: Parser) -> list[Word]:
        items: list[tuple] = []
        tokens = parser.tokens
        axes = self.axes
        while not parser.at_end():
            kind, value, frac = tokens[parser.pos]
            if kind != NAME:
                raise ProgramAlarm(ALARM_SYNTAX, f"unexpected {value!r}")
            parser.pos += 1
            name: str = value  # type: ignore[assignment]
            following = tokens[parser.pos] if parser.pos < len(tokens) else None
            is_assign = following is not None and following[0] == OP and following[1] == "="
            # axis words: X10, X=expr, X=IC(5), X-5
            if name in axes:
                axis_value, mode = self._axis_value(parser, frac)
                items.append(AxisWord(name, axis_value, mode))
                continue
            if frac is None and following is not None and following[0] == OP and following[1] == "(" \
                    and name not in ("MSG", "SETAL", "WAITP") and name not in FUNCTIONS and name not in NO_OP_WORDS:
                if name in ("IC", "AC"):
                    raise ProgramAlarm(ALARM_SYNTAX, f"{name}() stands after an address and '='")
                args = parser.arguments()
                repeat = self._repeat(parser)
                items.append(Call(name, args, repeat))
                continue
            split = _ADDRESS_WORD.fullmatch(name)
            if split and not is_assign:
                letters, digits = split.group(1), split.group(2)
                if letters in axes:
                    number_value = float(digits + frac) if frac else int(digits)
                    items.append(AxisWord(letters, number_value))
                    continue
                if letters in SINGLE_ADDRESSES or letters == "G" or letters == "N":
                    items.append(self._address(letters, digits, frac))
                    continue
            if split and is_assign and split.group(1) in EXTENDED:
                parser.pos += 1
                items.append(AddressWord(split.group(1), parser.expression(), int(split.group(2))))
                continue
            if split and is_assign and split.group(1) == "R":
                parser.pos += 1
                items.append(Assign(("R", int(split.group(2)), []), parser.expression()))
                continue
            if name == "G" and not is_assign:
                raise ProgramAlarm(ALARM_SYNTAX, "G needs a number")
            if name in ("I", "J", "K"):
                centre_value, mode = self._axis_value(parser, frac)
                items.append(CentreWord(name, centre_value, mode))
                continue
            if name in SINGLE_ADDRESSES or name in WORD_ADDRESSES:
                address_value = self._value_after(parser, name, frac)
                if address_value is None:
                    if name in ("L",):
                        raise ProgramAlarm(ALARM_SYNTAX, "L needs a number")
                    # a lone letter: a subprogram of that name, or nothing
                    items.append(Call(name))
                    continue
                if name in ("SPOS", "SPOSA"):
                    items.append(Spos(1, address_value))
                    continue
                items.append(AddressWord(name, address_value))
                continue
            if frac is not None:
                raise ProgramAlarm(ALARM_SYNTAX, f"unexpected {name}{frac}")
            if name in JUMPS:
                items.append(Jump(name, "" if name == "GOTOS" else self._target(parser)))
                continue
            if name == "MSG":
                args = parser.arguments()
                if len(args) > 2:
                    raise ProgramAlarm(ALARM_SYNTAX, "MSG takes a text")
                items.append(Msg(args[0] if args else ""))
                continue
            if name == "SETAL":
                args = parser.arguments()
                if not args or args[0] is None:
                    raise ProgramAlarm(ALARM_SYNTAX, "SETAL needs an alarm number")
                items.append(Setal(args[0]))
                continue
            if name in FRAME_WORDS:
                items.append(FrameWord(name, self._frame_axes(parser)))
                continue
            if name in ("SUPA", "G153"):
                items.append(Suppress(name))
                continue
            if name in ("RET",):
                items.append(Return())
                continue
            if name == "MCALL":
                token = parser.peek()
                if token is None:
                    items.append(ModalCall(None))
                    continue
                parser.pos += 1
                args = parser.arguments() if parser.at_op("(") else None
                items.append(ModalCall(token[1], args))
                continue
            if name == "CALL":
                target = parser.expression()
                items.append(Call(target))
                continue
            if name in SPLINES:
                items.append(GWord(1, name))
                continue
            if name in NOT_SUPPORTED_WORDS:
                entry = G_FUNCTIONS[name]
                raise ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"{name} (G group {entry.group}, "
                                   f"{GROUP_TITLES[entry.group]}) is not supported by the emulator")
            if name in NO_OP_WORDS:
                args = None
                if parser.at_op("("):
                    args = parser.arguments()  # kept: FGROUP(X, Y) names the feed group's axes
                elif parser.at_op("="):
                    parser.pos += 1
                    parser.expression()
                items.append(NoOp(name, args))
                continue
            if name == "AX" and frac is None and following is not None and following[1] == "[":
                indices = parser.indices()
                if len(indices) != 1:
                    raise ProgramAlarm(ALARM_SYNTAX, "AX[axis]=value")
                axis_value, mode = self._axis_value(parser, None)
                items.append(IndirectAxisWord(indices[0], axis_value, mode))
                continue
            if name in POSITIONING and frac is None and following is not None and following[1] == "[":
                items.append(self._positioning(parser, name))
                continue
            if name == "WAITP" and frac is None:
                items.append(WaitPosition(parser.arguments() if parser.at_op("(") else []))
                continue
            if name in AXIS_SETTINGS and following is not None and following[1] == "[":
                indices = parser.indices()
                parser.expect_op("=")
                items.append(AxisSetting(name, indices, parser.expression()))
                continue
            if is_assign or (following is not None and following[0] == OP and following[1] == "["):
                parser.pos -= 1
                target = self._lvalue(parser)
                parser.expect_op("=")
                if (parser.at_name("SET") or parser.at_name("REP")) and parser.pos + 1 < len(tokens) \
                        and tokens[parser.pos + 1][1] == "(":
                    which, args = self._initialiser(parser)
                    items.append(Fill(target, which, args))
                else:
                    items.append(Assign(target, parser.expression()))
                continue
            # a bare name: a subprogram without parameters (or a name the program never defined)
            items.append(Call(name, None, self._repeat(parser)))
        return items

    def _positioning(self, parser: Parser, name: str) -> PositionWord:
        """``POS[U]=value`` (or ``=IC(..)``, ``=AC(..)``), ``POSP[U]=(end, section length, mode)``."""
        indices = parser.indices()
        if len(indices) != 1 or indices[0] is None:
            raise ProgramAlarm(ALARM_SYNTAX, f"{name}[axis]=position")
        if name == "POSP":
            parser.expect_op("=")
            args = parser.arguments()
            if not args or args[0] is None:
                raise ProgramAlarm(ALARM_SYNTAX, "POSP[axis]=(end point, section length, mode)")
            return PositionWord(name, indices[0], args[0])
        if not parser.at_op("="):
            raise ProgramAlarm(ALARM_SYNTAX, f"{name}[axis]=position")
        value, mode = self._axis_value(parser, None)
        return PositionWord(name, indices[0], value, mode)

    def _repeat(self, parser: Parser) -> Any:
        token = parser.peek()
        if token is not None and token[0] == NAME and re.fullmatch(r"P\d+", token[1]):
            parser.pos += 1
            return int(token[1][1:])
        if parser.at_name("P") and parser.pos + 1 < len(parser.tokens) and parser.tokens[parser.pos + 1][1] == "=":
            parser.pos += 2
            return parser.expression()
        return None

    def _address(self, letters: str, digits: str, frac: str | None) -> GWord | NoOp | AddressWord | CentreWord:
        if letters == "G":
            if frac:
                raise ProgramAlarm(ALARM_SYNTAX, f"G{digits}{frac} is not a G function")
            return GWord(int(digits))
        if letters == "N":
            return NoOp("N")
        value: float | int = float(digits + frac) if frac else int(digits)
        if letters in ("I", "J", "K"):
            return CentreWord(letters, value)
        return AddressWord(letters, value)

    def _frame_axes(self, parser: Parser) -> list[tuple[str, Any]]:
        pairs = []
        while not parser.at_end():
            token = parser.peek()
            assert token is not None
            if token[0] != NAME:
                break
            name, frac = token[1], token[2]
            split = _ADDRESS_WORD.fullmatch(name)
            if name in self.axes:
                parser.pos += 1
                value = self._value_after(parser, name, frac)
                if value is None:
                    raise ProgramAlarm(ALARM_SYNTAX, f"{name}: value expected")
                pairs.append((name, value))
            elif split and split.group(1) in self.axes:
                parser.pos += 1
                pairs.append((split.group(1), float(split.group(2) + frac) if frac else int(split.group(2))))
            elif name == "RPL":
                parser.pos += 1
                value = self._value_after(parser, name, frac)
                pairs.append(("RPL", value))
            else:
                break
        return pairs



def _check_groups(items: list, every_group: bool = False) -> None:
    """The control's alarm for two G functions of one group in the block (gfunctions.check_block)."""
    names = []
    for item in items:
        kind = item.__class__
        if kind is GWord:
            names.append(item.spline or f"G{item.code}")
        elif (kind is Suppress or kind is NoOp) and item.name in G_FUNCTIONS:
            names.append(item.name)
        elif kind is FrameWord and item.word in G_FUNCTIONS:
            names.append(item.word)
    if len(names) > 1:
        check_block(names, every_group)


# Attributes a GUD declaration may carry before its type or name (access levels APR/APW.. n,
# physical unit PHU n, limits LLI/ULI n; synchronisation and protection flags): accepted, not modelled.
_VALUED_ATTRIBUTES = frozenset({"APR", "APW", "APRP", "APWP", "APRB", "APWB", "PHU", "LLI", "ULI"})
_FLAG_ATTRIBUTES = frozenset({"SYNR", "SYNW", "SYNRW", "PRLOC"})


def _skip_attributes(parser: Parser) -> tuple | None:
    while True:
        token = parser.peek()
        if token is None or token[0] != NAME:
            return token
        if token[1] in _FLAG_ATTRIBUTES:
            parser.pos += 1
        elif token[1] in _VALUED_ATTRIBUTES and _number_follows(parser.tokens, parser.pos + 1):
            parser.pos += 2 if parser.tokens[parser.pos + 1][0] == NUM else 3
        else:
            return token


def _number_follows(tokens: list, at: int) -> bool:
    if at < len(tokens) and tokens[at][0] == NUM:
        return True
    return (at + 1 < len(tokens) and tokens[at][0] == OP and tokens[at][1] in "+-"
            and tokens[at + 1][0] == NUM)
