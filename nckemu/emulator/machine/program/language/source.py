"""One program's text as the interpreter walks it: one string, offsets into it, and what a cheap scan
of the whole text finds up front (which control-structure line closes which).

Lines are never split into a list: a 400 000-line CAM program is one string plus nothing per line,
so its memory is its text. Labels and block numbers are searched when a jump executes (a regex over
the text in the jump's direction) and remembered per jump.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

_PREFIX = r"^[ \t]*(?:/\d?[ \t]*)?(?:[N:]\d+[ \t]*)?(?:[A-Z_][A-Z0-9_]*:[ \t]*)?"
# REPEAT opens a REPEAT ... UNTIL loop only when it stands alone; ``REPEAT LABEL P=3`` repeats a
# program section (no closer).
_STRUCTURE = re.compile(
    _PREFIX + r"(IF|ELSE|ENDIF|WHILE|ENDWHILE|FOR|ENDFOR|REPEAT(?=[ \t]*(?:;|$))|UNTIL|LOOP|ENDLOOP)\b(?![ \t]*:)",
    re.IGNORECASE | re.MULTILINE)
_JUMP_IN_LINE = re.compile(r"\bGOTO[FBCS]?\b", re.IGNORECASE)
_PROC = re.compile(_PREFIX + r"PROC\b", re.IGNORECASE | re.MULTILINE)

# Every structure keyword contains one of these (ENDIF contains IF, ENDFOR FOR, ...).
_KEYWORD_STEMS = ("IF", "ELSE", "WHILE", "FOR", "REPEAT", "UNTIL", "LOOP")

_OPENERS = {"IF": "ENDIF", "WHILE": "ENDWHILE", "FOR": "ENDFOR", "REPEAT": "UNTIL", "LOOP": "ENDLOOP"}
_CLOSERS = {closer: opener for opener, closer in _OPENERS.items()}


def structure_matches(text: str, upper: str) -> Iterator[re.Match[str]]:
    """``_STRUCTURE.finditer(text)`` (``upper`` is ``text.upper()``), found faster: a match starts a line
    and lies within it, so only the lines holding a keyword's letters are tried (found with str.find at
    C speed; the anchored regex tried at every offset of a 17 MB CAM program whose comment says "for"
    took half a second). Text that is not ASCII, whose upper case may move offsets, takes the regex."""
    if not text.isascii() or len(upper) != len(text):
        yield from _STRUCTURE.finditer(text)
        return
    starts: set[int] = set()
    for stem in _KEYWORD_STEMS:
        at = upper.find(stem)
        while at >= 0:
            starts.add(upper.rfind("\n", 0, at) + 1)
            line_end = upper.find("\n", at)
            if line_end < 0:
                break
            at = upper.find(stem, line_end)
    for start in sorted(starts):
        match = _STRUCTURE.match(text, start)
        if match is not None:
            yield match


BYTE_ORDER_MARK = "\ufeff"


def decode_program(data: bytes) -> str:
    """A program file's bytes as text: UTF-8 where they are (a CAM post's or an editor's "°"), else
    Latin-1 (every byte is a character: an old control's or a Windows editor's file)."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def normalized(text: str) -> str:
    """The text the interpreter walks: no byte-order mark (Windows editors write one), LF line ends."""
    if text.startswith(BYTE_ORDER_MARK):
        text = text[1:]
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


class ProgramSource:
    """A program's text and the structure of its control blocks (offsets of line starts)."""

    def __init__(self, path: str, text: str, *, subprogram: bool = False) -> None:
        text = normalized(text)
        self.path = path
        self.text = text
        self.subprogram = subprogram
        # opener line -> its closer line; closer -> opener; IF -> ELSE; ELSE -> ENDIF
        self.partner: dict[int, int] = {}
        self.else_of: dict[int, int] = {}
        self.bad_nesting: set[int] = set()
        self.loop_spans: list[tuple[int, int]] = []
        self.jump_cache: dict[tuple[int, str, str], int | None] = {}
        self.line_of: dict[int, int] = {0: 1}
        # blocks kept compiled, by line offset (the interpreter fills it for lines that can run again)
        self.compiled: dict[int, Any] = {}
        # Plain substring tests on an upper-case copy (freed at once) decide which regex scans are
        # needed: a CAM program without control structures costs a few passes at C speed.
        upper = text.upper()
        self.has_jumps = "GOTO" in upper
        structures = any(word in upper for word in _KEYWORD_STEMS)
        has_proc = "PROC" in upper
        if structures:
            self._scan(upper)
        del upper
        self.proc_offset = self._find_proc() if has_proc else -1
        body_from = 0
        if self.proc_offset >= 0:
            end = text.find("\n", self.proc_offset)
            body_from = len(text) if end < 0 else end + 1
        # a line that is a block (not blank, not only a comment, not a % header)
        self.has_blocks = re.compile(r"^[ \t]*[^ \t;%\n]", re.MULTILINE).search(text, body_from) is not None

    def _scan(self, upper: str) -> None:
        text = self.text
        stack: list[tuple[str, int]] = []
        for match in structure_matches(text, upper):
            keyword = match.group(1).upper()
            start = match.start()
            if keyword == "IF":
                end = text.find("\n", start)
                rest = text[match.end(): end if end >= 0 else len(text)]
                comment = rest.find(";")
                if _JUMP_IN_LINE.search(rest if comment < 0 else rest[:comment]):
                    continue  # IF ... GOTOF: a conditional jump, not a structure
            if keyword in _OPENERS:
                stack.append((keyword, start))
            elif keyword == "ELSE":
                if stack and stack[-1][0] == "IF" and stack[-1][1] not in self.else_of:
                    self.else_of[stack[-1][1]] = start
                    self.partner[start] = -1  # filled when ENDIF comes
                else:
                    self.bad_nesting.add(start)
            else:
                opener = _CLOSERS[keyword]
                if stack and stack[-1][0] == opener:
                    _, open_at = stack.pop()
                    self.partner[open_at] = start
                    self.partner[start] = open_at
                    if opener == "IF" and open_at in self.else_of:
                        self.partner[self.else_of[open_at]] = start
                    if opener != "IF":
                        self.loop_spans.append((open_at, start))
                else:
                    self.bad_nesting.add(start)
        for _, open_at in stack:
            self.bad_nesting.add(open_at)
            self.else_of.pop(open_at, None)

    def _find_proc(self) -> int:
        match = _PROC.search(self.text)
        return match.start() if match else -1

    def line_number(self, offset: int) -> int:
        """1-based line of the line starting at ``offset`` (remembered: jump targets recur)."""
        line = self.line_of.get(offset)
        if line is None:
            line = self.text.count("\n", 0, offset) + 1
            if len(self.line_of) < 100_000:
                self.line_of[offset] = line
        return line

    def in_loop(self, offset: int) -> bool:
        if not self.loop_spans:
            return False
        return any(start <= offset <= end for start, end in self.loop_spans)

    def find_target(self, target: str, current: int, direction: str) -> int | None:
        """Offset of the line a jump to ``target`` (label or N-number) lands on, or None.

        ``direction``: "F" forward from the line after ``current``, "B" backward from ``current``
        itself (nearest first), "" forward then backward (GOTO, GOTOC).
        """
        key = (current, target, direction)
        if key in self.jump_cache:
            return self.jump_cache[key]
        if re.fullmatch(r"N\d+", target):
            pattern = re.compile(r"^[ \t]*(?:/\d?[ \t]*)?N0*" + target[1:] + r"(?![0-9])",
                                 re.IGNORECASE | re.MULTILINE)
        elif re.fullmatch(r":\d+", target):
            pattern = re.compile(r"^[ \t]*(?:/\d?[ \t]*)?:0*" + target[1:] + r"(?![0-9])", re.MULTILINE)
        else:
            pattern = re.compile(r"^[ \t]*(?:/\d?[ \t]*)?(?:[N:]\d+[ \t]*)?" + re.escape(target) + r"[ \t]*:",
                                 re.IGNORECASE | re.MULTILINE)
        text = self.text
        line_end = text.find("\n", current)
        after = len(text) if line_end < 0 else line_end + 1
        found: int | None = None
        if direction in ("F", ""):
            match = pattern.search(text, after)
            found = match.start() if match else None
        if found is None and direction in ("B", ""):
            last = None
            for match in pattern.finditer(text, 0, after):
                last = match.start()
            found = last
        if len(self.jump_cache) < 10_000:
            self.jump_cache[key] = found
        return found
