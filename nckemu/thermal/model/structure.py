"""What a machine's structure allows a term to be (issue 51): sizes from the expansion of its material
over the length of the structure between the sensor's heat and the tool, and a room temperature that
acts through the structure (a lag), never as hysteresis of the air. Sources in docs/thermal.md.

A model file may set it in a ``[structure]`` table::

    [structure]
    material = "cast_iron"     # or expansion_um_per_m_K = 10.5
    length_m = 1.2             # the longest structure in the loop from the heat to the tool
    ambient_sensors = ["hall"] # sensors of the room (default: names with ambient, room, hall or air)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from nckemu.errors import NckConfigError

# Linear expansion near 20 C, um per metre per kelvin (ISO/TR 16015; handbook values of the materials).
MATERIALS_UM_PER_M_K = {"steel": 11.5, "cast_iron": 10.5, "mineral_cast": 12.0, "granite": 7.0, "aluminium": 23.0}
ROOM_WORDS = ("ambient", "room", "hall", "air")


# A structure nobody declared is taken as this long: a loop from the heat to the tool longer than the
# longest axis and column of the large machining centres the tool is written for, so that only sizes no
# machine tool of that class can have are refused (docs/thermal.md: on the measured recordings it refuses
# no term the admission names). Our choice, not a handbook value: a model file's [structure] says better.
UNDECLARED_LENGTH_M = 3.0


@dataclass(frozen=True)
class Structure:
    expansion_um_per_m_K: float = MATERIALS_UM_PER_M_K["steel"]
    # None: the machine's structure was not declared (no [structure] table): sizes are bounded by
    # undeclared_length_m of the material, generous on purpose; a model file's [structure] declares it.
    length_m: float | None = None
    ambient_sensors: tuple[str, ...] = ()
    material: str = "steel"
    undeclared_length_m: float = UNDECLARED_LENGTH_M

    @property
    def declared(self) -> bool:
        """A model's [structure] table (or --structure) gave it, not the default."""
        return self.length_m is not None

    @property
    def judged_length_m(self) -> float:
        """The length sizes are judged by: the declared one, else undeclared_length_m."""
        return self.length_m if self.length_m is not None else self.undeclared_length_m

    @property
    def um_per_K(self) -> float:
        """What a kelvin does to the whole structure: its expansion over its length."""
        return self.expansion_um_per_m_K * self.judged_length_m

    def is_room(self, sensor: str) -> bool:
        if self.ambient_sensors:
            return sensor in self.ambient_sensors
        return any(word in sensor.lower() for word in ROOM_WORDS)

    def words(self) -> str:
        undeclared = "" if self.declared else " (no [structure] declared)"
        return (f"{self.judged_length_m:g} m of {self.material.replace('_', ' ')}{undeclared} at "
                f"{self.expansion_um_per_m_K:g} um/(m K)")


def parse_structure(table: Any, source: str) -> Structure:
    """A model file's ``[structure]`` table."""
    if not isinstance(table, dict):
        raise NckConfigError("structure must be a table", path=source, field="structure")
    allowed = {"material", "expansion_um_per_m_K", "length_m", "ambient_sensors"}
    for key in table:
        if key not in allowed:
            raise NckConfigError(f"structure has no {key!r} (it takes {', '.join(sorted(allowed))})", path=source,
                                 field=f"structure.{key}")
    material = table.get("material", "steel")
    if material not in MATERIALS_UM_PER_M_K and "expansion_um_per_m_K" not in table:
        raise NckConfigError(f"unknown material {material!r} (known: {', '.join(MATERIALS_UM_PER_M_K)}; or give "
                             f"expansion_um_per_m_K)", path=source, field="structure.material")
    expansion = table.get("expansion_um_per_m_K", MATERIALS_UM_PER_M_K.get(material, math.nan))
    length = table.get("length_m", 1.0)  # a declared structure without its length: a metre
    for key, value in (("expansion_um_per_m_K", expansion), ("length_m", length)):
        if not isinstance(value, int | float) or isinstance(value, bool) or not value > 0:
            raise NckConfigError(f"{key} must be a positive number", path=source, field=f"structure.{key}")
    rooms = table.get("ambient_sensors", [])
    if not isinstance(rooms, list) or not all(isinstance(r, str) for r in rooms):
        raise NckConfigError("ambient_sensors must be a list of sensor names", path=source,
                             field="structure.ambient_sensors")
    return Structure(float(expansion), float(length), tuple(rooms), str(material))


def render_structure(structure: Structure) -> list[str]:
    rooms = ", ".join(f'"{r}"' for r in structure.ambient_sensors)
    return ["[structure]", f'material = "{structure.material}"',
            f"expansion_um_per_m_K = {structure.expansion_um_per_m_K!r}"] \
        + ([f"length_m = {structure.length_m!r}"] if structure.length_m is not None else []) \
        + ([f"ambient_sensors = [{rooms}]"] if structure.ambient_sensors else [])
