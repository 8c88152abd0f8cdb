"""The program source's structure scan (lines holding a keyword's letters, tried with the anchored
regex) finds exactly what the regex run over the whole text finds, on random programs."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from nckemu.emulator.machine.program.language.source import _STRUCTURE, structure_matches

PIECES = ["IF", "if", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "FOR", "endfor", "REPEAT", "UNTIL", "LOOP", "ENDLOOP",
          "N10", ":20", "/", "/1", "LABEL:", "FOR:", " ", "\t", "R1", "=", "1", "GOTOF", "G1", "X5", ";", "for the",
          "PLATFORM", "ß", "ı", "\n", "\r\n", "IF R1>2 GOTOF END", "_X"]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(PIECES), max_size=60))
def test_scan_equals_the_regex_over_the_text(pieces: list[str]) -> None:
    text = "".join(pieces)
    expected = [(match.start(), match.end(), match.group(1)) for match in _STRUCTURE.finditer(text)]
    found = [(match.start(), match.end(), match.group(1)) for match in structure_matches(text, text.upper())]
    assert found == expected
