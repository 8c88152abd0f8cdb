"""Expressions of the SINUMERIK language compiled to Python closures.

A compiled expression is either a constant (int, float, bool, str) or a function of the names it reads
(``expr(ev)``, ``ev`` a :class:`Names`: the running program's, names.py); :func:`is_dynamic` tells them
apart. Constant sub-expressions are folded when the
block is compiled, so a CAM block ``X10.5`` costs no evaluation at all.

Operator priority (SINUMERIK programming manual, job planning, "priority of operators"), highest
first: NOT B_NOT and unary signs; * / DIV MOD; + -; B_AND; B_XOR; B_OR; AND; XOR; OR; << (string
concatenation); comparisons == <> > < >= <=. Comparisons bind loosest, which is why Siemens writes
``IF (R1==1) AND (R2==2)`` with brackets; without them ``A==1 AND B==2`` means ``A==(1 AND B)==2``
on the control and here alike.
"""

from __future__ import annotations

import math
import operator
from types import FunctionType
from typing import Any, Protocol

from ..motions import ALARM_NAME_NOT_DEFINED, ALARM_SYNTAX, ProgramAlarm
from .alarms import ALARM_ARITHMETIC, ALARM_DIVISION_BY_ZERO, ALARM_TYPE
from .framing import FRAME_FUNCTIONS, chained
from .lexer import NAME, NUM, OP, STR

Expr = Any  # a constant or a FunctionType taking the Names


class Names(Protocol):
    """What a compiled expression reads when it runs: the closures the parser's resolver builds and the
    parser's own index items call only these (the interpreter's ProgramNames is one)."""

    def read_r(self, index: Any) -> float:
        """R parameter ``index`` (R1, R[expr], $R[expr])."""
        ...

    def read_variable(self, name: str, indices: tuple) -> Any:
        """A variable (DEF, PROC parameter, GUD) or an element of an array variable; an axis name as itself."""
        ...

    def read_system(self, name: str, indices: tuple) -> Any:
        """A system variable ($AA_IM[X], $P_F ...)."""
        ...

    def read_setting(self, name: str, indices: tuple) -> Any:
        """An axis setting word as a value (ACC[X])."""
        ...

    def name_or_value(self, name: str) -> Any:
        """An index written as a bare name: a variable's value, else the name itself (an axis)."""
        ...


def is_dynamic(expr: Expr) -> bool:
    return type(expr) is FunctionType


def evaluate(expr: Expr, ev: Names) -> Any:
    return expr(ev) if type(expr) is FunctionType else expr


# --- values -----------------------------------------------------------------------------------------

def number(value: Any) -> float | int:
    """A value as a number (BOOL is 0/1); a STRING in arithmetic is alarm ALARM_TYPE."""
    if value.__class__ is float or value.__class__ is int:
        return value
    if value.__class__ is bool:
        return int(value)
    raise ProgramAlarm(ALARM_TYPE, f"{value!r} is not a number")


def truth(value: Any) -> bool:
    if value.__class__ is str:
        return value != ""
    return value != 0


def round_half_away(value: float) -> int:
    """SINUMERIK ROUND and the REAL -> INT conversion: .5 goes away from zero."""
    return int(math.floor(value + 0.5)) if value >= 0 else -int(math.floor(-value + 0.5))


def _check(value: float, what: str) -> float:
    if math.isfinite(value):
        return value
    raise ProgramAlarm(ALARM_ARITHMETIC, f"{what}: result is not a finite number")


def _divide(a: Any, b: Any) -> float:
    a, b = number(a), number(b)
    if b == 0:
        raise ProgramAlarm(ALARM_DIVISION_BY_ZERO, "division by zero")
    return _check(a / b, "/")


def _div(a: Any, b: Any) -> int:
    a, b = number(a), number(b)
    if b == 0:
        raise ProgramAlarm(ALARM_DIVISION_BY_ZERO, "division by zero (DIV)")
    return int(_check(a / b, "DIV")) if (a.__class__ is float or b.__class__ is float) else _int_div(a, b)


def _int_div(a: int, b: int) -> int:
    quotient = abs(a) // abs(b)
    return quotient if (a >= 0) == (b >= 0) else -quotient


def _mod(a: Any, b: Any) -> float | int:
    a, b = number(a), number(b)
    if b == 0:
        raise ProgramAlarm(ALARM_DIVISION_BY_ZERO, "division by zero (MOD)")
    result = math.fmod(a, b)
    return int(result) if (a.__class__ is int and b.__class__ is int) else result


def _arith(op: str):
    if op == "+":
        def add(a, b):
            return _check_num(number(a) + number(b))
        return add
    if op == "-":
        def sub(a, b):
            return _check_num(number(a) - number(b))
        return sub
    if op == "*":
        def mul(a, b):
            return _check_num(number(a) * number(b))
        return mul
    raise AssertionError(op)


def _check_num(value: float | int) -> float | int:
    if value.__class__ is float and not math.isfinite(value):
        raise ProgramAlarm(ALARM_ARITHMETIC, "result is not a finite number")
    return value


def _bits(a: Any) -> int:
    value = number(a)
    if value.__class__ is float:
        value = round_half_away(value)
    return value


def _concat(a: Any, b: Any) -> str:
    return to_text(a) + to_text(b)


def to_text(value: Any) -> str:
    """A value as ``<<`` and MSG show it: REAL with up to six decimals, BOOL as 1/0."""
    if value.__class__ is str:
        return value
    if value.__class__ is bool:
        return "1" if value else "0"
    if value.__class__ is int:
        return str(value)
    text = f"{value:.6f}".rstrip("0")
    return text + "0" if text.endswith(".") else text


def _compare(op: str):
    test = {"==": operator.eq, "<>": operator.ne, "<": operator.lt, ">": operator.gt,
            "<=": operator.le, ">=": operator.ge}[op]

    def compare(a: Any, b: Any) -> bool:
        if (a.__class__ is str) != (b.__class__ is str):
            raise ProgramAlarm(ALARM_TYPE, f"cannot compare {a!r} with {b!r}")
        return test(a, b)
    return compare


BINARY: dict[str, tuple[int, Any]] = {
    ":": (1, chained),  # the frame chain: CTRANS(X, 10) : CROT(Z, 45)
    "==": (1, _compare("==")), "<>": (1, _compare("<>")), "<": (1, _compare("<")),
    ">": (1, _compare(">")), "<=": (1, _compare("<=")), ">=": (1, _compare(">=")),
    "<<": (2, _concat),
    "OR": (3, lambda a, b: truth(a) or truth(b)),
    "XOR": (4, lambda a, b: truth(a) != truth(b)),
    "AND": (5, lambda a, b: truth(a) and truth(b)),
    "B_OR": (6, lambda a, b: _bits(a) | _bits(b)),
    "B_XOR": (7, lambda a, b: _bits(a) ^ _bits(b)),
    "B_AND": (8, lambda a, b: _bits(a) & _bits(b)),
    "+": (9, _arith("+")), "-": (9, _arith("-")),
    "*": (10, _arith("*")), "/": (10, _divide), "DIV": (10, _div), "MOD": (10, _mod),
}
UNARY_PRIORITY = 11


# --- functions ---------------------------------------------------------------------------------------

def _real(fn, what: str):
    def call(*args):
        try:
            return _check(float(fn(*(number(a) for a in args))), what)
        except (ValueError, OverflowError) as exc:
            raise ProgramAlarm(ALARM_ARITHMETIC, f"{what}: argument out of range") from exc
    return call


def _deg(fn):
    return lambda x: fn(math.radians(x))


def _trunc(x: Any) -> int:
    value = number(x)
    if value.__class__ is float and not math.isfinite(value):
        raise ProgramAlarm(ALARM_ARITHMETIC, "TRUNC of a non-finite number")
    return math.trunc(value)


def _round(x: Any) -> int:
    value = float(number(x))
    if not math.isfinite(value):
        raise ProgramAlarm(ALARM_ARITHMETIC, "ROUND of a non-finite number")
    return round_half_away(value)


def _roundup(x: Any) -> int:
    value = float(number(x))
    if not math.isfinite(value):
        raise ProgramAlarm(ALARM_ARITHMETIC, "ROUNDUP of a non-finite number")
    return math.ceil(value) if value >= 0 else math.floor(value)


def _string_arg(value: Any) -> str:
    if value.__class__ is not str:
        raise ProgramAlarm(ALARM_TYPE, f"{value!r} is not a STRING")
    return value


def _number_of(text: Any) -> float:
    try:
        return _check(float(_string_arg(text).strip().upper().replace("EX", "E")), "NUMBER")
    except ValueError as exc:
        raise ProgramAlarm(ALARM_TYPE, f"NUMBER({text!r}): not a number") from exc


def _is_number(text: Any) -> bool:
    try:
        _number_of(text)
    except ProgramAlarm:
        return False
    return True


def _substr(text: Any, start: Any, length: Any = None) -> str:
    text = _string_arg(text)
    first = _bits(start)
    if length is None:
        return text[first:]
    return text[first:first + _bits(length)]


def _index(text: Any, char: Any) -> int:
    return _string_arg(text).find(_string_arg(char))


def _rindex(text: Any, char: Any) -> int:
    return _string_arg(text).rfind(_string_arg(char))


def _bound(low: Any, high: Any, value: Any) -> float | int:
    return min(max(number(value), number(low)), number(high))


def _minmax(fn):
    return lambda a, b: fn(number(a), number(b))


# name -> (minimum args, maximum args, implementation)
FUNCTIONS: dict[str, tuple[int, int, Any]] = {
    "SIN": (1, 1, _real(_deg(math.sin), "SIN")),
    "COS": (1, 1, _real(_deg(math.cos), "COS")),
    "TAN": (1, 1, _real(_deg(math.tan), "TAN")),
    "ASIN": (1, 1, _real(lambda x: math.degrees(math.asin(x)), "ASIN")),
    "ACOS": (1, 1, _real(lambda x: math.degrees(math.acos(x)), "ACOS")),
    "ATAN2": (2, 2, _real(lambda y, x: math.degrees(math.atan2(y, x)), "ATAN2")),
    "SQRT": (1, 1, _real(math.sqrt, "SQRT")),
    "ABS": (1, 1, lambda x: abs(number(x))),
    "POT": (1, 1, lambda x: _check_num(number(x) * number(x))),
    "TRUNC": (1, 1, _trunc),
    "ROUND": (1, 1, _round),
    "ROUNDUP": (1, 1, _roundup),
    "LN": (1, 1, _real(math.log, "LN")),
    "EXP": (1, 1, _real(math.exp, "EXP")),
    "MINVAL": (2, 2, _minmax(min)),
    "MAXVAL": (2, 2, _minmax(max)),
    "BOUND": (3, 3, _bound),
    "STRLEN": (1, 1, lambda s: len(_string_arg(s))),
    "TOUPPER": (1, 1, lambda s: _string_arg(s).upper()),
    "TOLOWER": (1, 1, lambda s: _string_arg(s).lower()),
    "NUMBER": (1, 1, _number_of),
    "ISNUMBER": (1, 1, _is_number),
    "SUBSTR": (2, 3, _substr),
    "INDEX": (2, 2, _index),
    "RINDEX": (2, 2, _rindex),
    # axis names as values of type AXIS: AXNAME("X") is the axis X, AXSTRING(X) its name as text
    "AXNAME": (1, 1, lambda s: _string_arg(s).upper()),
    "AXSTRING": (1, 1, lambda s: to_text(s).upper()),
    # FRAME values (framing.py): CTRANS(X, 10, Y, 5), CROT(Z, 45), CSCALE(X, 2), CMIRROR(X), CTRANS()
    **{name: (0, 24, build) for name, build in FRAME_FUNCTIONS.items()},
}

# Keywords that end an expression (they follow one in IF ... GOTOF, FOR ... TO, CASE ... OF)
STOP_WORDS = frozenset({"GOTOF", "GOTOB", "GOTO", "GOTOC", "TO", "OF", "DEFAULT"})


class Parser:
    """Recursive-descent/Pratt parser over the tokens of one block.

    ``resolver`` turns names into compiled operands (variables, R parameters, system variables); it
    belongs to the interpreter, which knows what a name means.
    """

    __slots__ = ("tokens", "pos", "resolver")

    def __init__(self, tokens: list, resolver: Any, pos: int = 0) -> None:
        self.tokens = tokens
        self.pos = pos
        self.resolver = resolver

    # token helpers
    def peek(self) -> tuple | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def at_op(self, op: str) -> bool:
        token = self.peek()
        return token is not None and token[0] == OP and token[1] == op

    def at_name(self, name: str) -> bool:
        token = self.peek()
        return token is not None and token[0] == NAME and token[1] == name and token[2] is None

    def expect_op(self, op: str) -> None:
        if not self.at_op(op):
            found = self.peek()
            raise ProgramAlarm(ALARM_SYNTAX, f"expected {op!r}, found {found[1] if found else 'end of block'!r}")
        self.pos += 1

    def at_end(self) -> bool:
        return self.pos >= len(self.tokens)

    # expressions
    def expression(self, min_priority: int = 0) -> Expr:
        left = self.unary()
        while True:
            token = self.peek()
            if token is None:
                return left
            kind, value, frac = token
            if kind == OP or (kind == NAME and frac is None):
                entry = BINARY.get(value)  # type: ignore[arg-type]
            else:
                entry = None
            if entry is None or entry[0] <= min_priority:
                return left
            priority, fn = entry
            self.pos += 1
            right = self.expression(priority)
            left = combine(fn, left, right)

    def unary(self) -> Expr:
        token = self.peek()
        if token is None:
            raise ProgramAlarm(ALARM_SYNTAX, "expression expected")
        kind, value, frac = token
        if kind == OP and value in ("-", "+"):
            self.pos += 1
            operand = self.expression(UNARY_PRIORITY)
            if value == "+":
                return combine1(number, operand)
            return combine1(_negate, operand)
        if kind == NAME and value in ("NOT", "B_NOT") and frac is None:
            self.pos += 1
            operand = self.expression(UNARY_PRIORITY)
            return combine1(_not if value == "NOT" else _bnot, operand)
        return self.primary()

    def primary(self) -> Expr:
        token = self.peek()
        assert token is not None
        kind, value, frac = token
        self.pos += 1
        if kind == NUM or kind == STR:
            return value
        if kind == OP:
            if value == "(":
                inner = self.expression()
                self.expect_op(")")
                return inner
            raise ProgramAlarm(ALARM_SYNTAX, f"unexpected {value!r} in an expression")
        if frac is not None:
            raise ProgramAlarm(ALARM_SYNTAX, f"unexpected {value}{frac} in an expression")
        if value in STOP_WORDS or value in BINARY:
            raise ProgramAlarm(ALARM_SYNTAX, f"unexpected {value} in an expression")
        if value == "TRUE":
            return True
        if value == "FALSE":
            return False
        if value in FUNCTIONS and self.at_op("("):
            return self.call(value)
        return self.resolver(self, value)

    def arguments(self) -> list[Expr]:
        """``( a, b, , d )``: empty places are None."""
        self.expect_op("(")
        args: list[Expr] = []
        if self.at_op(")"):
            self.pos += 1
            return args
        while True:
            if self.at_op(",") or self.at_op(")"):
                args.append(None)
            else:
                args.append(self.expression())
            if self.at_op(","):
                self.pos += 1
                continue
            self.expect_op(")")
            return args

    def indices(self) -> list[Expr]:
        """``[a, b]`` after a name."""
        self.expect_op("[")
        items = [self.index_item()]
        while self.at_op(","):
            self.pos += 1
            items.append(self.index_item())
        self.expect_op("]")
        return items

    def index_item(self) -> Expr:
        """An index: an expression; a bare name no variable has is kept as a name (an axis: $AA_IM[X])."""
        token = self.peek()
        following = self.tokens[self.pos + 1] if self.pos + 1 < len(self.tokens) else None
        if (token is not None and token[0] == NAME and token[2] is None and following is not None
                and following[0] == OP and following[1] in (",", "]")):
            self.pos += 1
            name = token[1]
            return lambda ev, _name=name: ev.name_or_value(_name)
        return self.expression()

    def call(self, name: str) -> Expr:
        low, high, fn = FUNCTIONS[name]
        args = self.arguments()
        if not low <= len(args) <= high or any(arg is None for arg in args):
            raise ProgramAlarm(ALARM_SYNTAX, f"{name} takes {low}..{high} arguments")
        if not any(is_dynamic(arg) for arg in args):
            return fn(*args)
        if len(args) == 1:
            (arg,) = args
            return lambda ev: fn(arg(ev) if type(arg) is FunctionType else arg)
        return lambda ev: fn(*[a(ev) if type(a) is FunctionType else a for a in args])


def _negate(value: Any) -> float | int:
    return -number(value)


def _not(value: Any) -> bool:
    return not truth(value)


def _bnot(value: Any) -> int:
    return ~_bits(value)


def combine1(fn: Any, operand: Expr) -> Expr:
    if type(operand) is not FunctionType:
        return fn(operand)
    return lambda ev: fn(operand(ev))


def combine(fn: Any, left: Expr, right: Expr) -> Expr:
    dynamic_left = type(left) is FunctionType
    dynamic_right = type(right) is FunctionType
    if not dynamic_left and not dynamic_right:
        return fn(left, right)
    if dynamic_left and dynamic_right:
        return lambda ev: fn(left(ev), right(ev))
    if dynamic_left:
        return lambda ev: fn(left(ev), right)
    return lambda ev: fn(left, right(ev))


def undefined(name: str) -> ProgramAlarm:
    return ProgramAlarm(ALARM_NAME_NOT_DEFINED, f"name {name} not defined")


__all__ = ["Parser", "evaluate", "is_dynamic", "number", "truth", "to_text", "round_half_away",
           "FUNCTIONS", "NAME", "NUM", "OP", "STR", "undefined"]
