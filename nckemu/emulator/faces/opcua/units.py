"""Engineering units of the OPC UA face, as OPC UA says to give them: UNECE Recommendation 20 common codes
(the table the OPC Foundation publishes for OPC UA, namespace ``http://www.opcfoundation.org/UA/units/un/
cefact``) with the UnitId computed from the code's letters (OPC 10000-8, EUInformation).

Every ``EUInformation`` the face serves is made here from its code, so a client that looks a unit up by
UnitId finds the unit the DisplayName shows.
"""

from __future__ import annotations

from asyncua import ua

UNECE_NAMESPACE = "http://www.opcfoundation.org/UA/units/un/cefact"

# code -> (symbol, name), as UNECE Recommendation 20 lists them
COMMON_CODES: dict[str, tuple[str, str]] = {
    "MMT": ("mm", "millimetre"),
    "DD": ("°", "degree [unit of angle]"),
    "H81": ("mm/min", "millimetre per minute"),
    "P1": ("%", "percent"),
    "RPM": ("r/min", "revolutions per minute"),
    "KWT": ("kW", "kilowatt"),
    "NU": ("N·m", "newton metre"),
}


def unit_id(code: str) -> int:
    """The UnitId of a common code: its letters' ASCII values, one byte each, the first the highest."""
    if not 1 <= len(code) <= 3 or not code.isascii() or not code.isalnum() or code.upper() != code:
        raise ValueError(f"{code!r} is no UNECE common code")
    value = 0
    for character in code:
        value = (value << 8) | ord(character)
    return value


def eu_information(code: str) -> ua.EUInformation:
    """The EUInformation of a common code of ``COMMON_CODES``."""
    symbol, name = COMMON_CODES[code]
    return ua.EUInformation(NamespaceUri=UNECE_NAMESPACE, UnitId=unit_id(code),
                            DisplayName=ua.LocalizedText(symbol), Description=ua.LocalizedText(name))


MILLIMETRE = eu_information("MMT")
DEGREE = eu_information("DD")
MILLIMETRE_PER_MINUTE = eu_information("H81")
PERCENT = eu_information("P1")
REVOLUTIONS_PER_MINUTE = eu_information("RPM")
KILOWATT = eu_information("KWT")
NEWTON_METRE = eu_information("NU")
