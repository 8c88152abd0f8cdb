"""Stored and active NCK values by typed address: the plain datastore under the model's behaviour.

Values live per (variable, unit) as lists of lines. A write changes the stored value; it becomes
active at once, at reset or at power-on as the catalogue's ``effective`` says. Variables with a
``source`` are not stored here: the model's value sources compute them.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from nckemu.catalogue.table import VariableSpec, index_by_address
from nckemu.errors import (
    NckAddressOutOfRange,
    NckConfigError,
    NckItemError,
    NckObjectDoesNotExist,
)
from nckemu.protocol.addresses import NckAddress, NckArea, NckType

# Loggers keep their names from before the 0.2 layout, so logs and users' log filters stay as they were.
log = logging.getLogger("nckemu.emulator.nck.store")

# Hot addresses are cached; a flood of distinct ones is not.
MAX_CACHED_ADDRESSES = 4096

# The address index of a variable table (~3 MB for the built-in one: R parameters take one key per
# column) is the same for every machine serving that table: built once per table object, shared by
# all stores (a fleet of 100 machines would otherwise hold 100 copies). Specs are immutable; the
# values stay per store. Keyed by id, holding the table so the id stays its own; the few newest
# tables only (a process loading many machine files with their own rows keeps no garbage).
MAX_SHARED_INDEXES = 8
_SHARED_INDEXES: dict[int, tuple[tuple[VariableSpec, ...], dict[tuple[int, int, int], VariableSpec]]] = {}


def _shared_index(specs: tuple[VariableSpec, ...]) -> dict[tuple[int, int, int], VariableSpec]:
    entry = _SHARED_INDEXES.get(id(specs))
    if entry is None or entry[0] is not specs:
        entry = (specs, index_by_address(specs))
        while len(_SHARED_INDEXES) >= MAX_SHARED_INDEXES:
            del _SHARED_INDEXES[next(iter(_SHARED_INDEXES))]
        _SHARED_INDEXES[id(specs)] = entry
    return entry[1]


class VariableStore:
    """Specs by address, values by (name, unit), the retained snapshot of stored values."""

    def __init__(self, specs: Iterable[VariableSpec], units_of: Callable[[VariableSpec], list[int]],
                 limit_violation_return_code: int) -> None:
        self.specs = tuple(specs)
        self._index = _shared_index(self.specs)
        self._by_name = {spec.name: spec for spec in self.specs}
        self._modules = frozenset(spec.module for spec in self.specs)
        self._limit_rc = limit_violation_return_code
        self._valid_units = {spec.name: frozenset(units_of(spec)) for spec in self.specs}
        self._resolved: dict[NckAddress, tuple[VariableSpec, int]] = {}
        self.stored: dict[tuple[str, int], list[Any]] = {
            (spec.name, unit): list(spec.default) if isinstance(spec.default, tuple) else [spec.default] * spec.lines
            for spec in self.specs if not spec.computed for unit in units_of(spec)
        }
        self.active: dict[tuple[str, int], list[Any]] = {}
        self.activate_all()

    def spec(self, name: str) -> VariableSpec:
        return self._by_name[name]

    # ------------------------------------------------------------------ addressing
    def resolve(self, address: NckAddress) -> tuple[VariableSpec, int]:
        resolved = self._resolved.get(address)
        if resolved is None:
            resolved = self._resolve_uncached(address)
            if len(self._resolved) < MAX_CACHED_ADDRESSES:
                self._resolved[address] = resolved
        return resolved

    def _resolve_uncached(self, address: NckAddress) -> tuple[VariableSpec, int]:
        if address.module not in self._modules:
            raise NckObjectDoesNotExist(f"module 0x{address.module:02X} is not served")
        spec = self._index.get((address.module, address.column, address.area))
        if spec is None:
            raise NckObjectDoesNotExist(f"no variable at module 0x{address.module:02X} column "
                                        f"{address.column} in area {NckArea(address.area).name}")
        unit = address.unit
        if address.area in (NckArea.N, NckArea.B) and unit == 0:
            unit = 1
        if unit not in self._valid_units[spec.name]:
            raise NckObjectDoesNotExist(f"{spec.name}: unit {address.unit} does not exist")
        last = address.line + address.line_count - 1
        if address.line < 1 or address.line_count < 1 or last > spec.lines:
            raise NckAddressOutOfRange(f"{spec.name}: lines {address.line}..{last} outside 1..{spec.lines}")
        return spec, unit

    # ------------------------------------------------------------------ values
    def stored_value(self, name: str, unit: int, line: int = 1) -> Any:
        return self.stored[(name, unit)][line - 1]

    def active_value(self, name: str, unit: int, line: int = 1) -> Any:
        return self.active[(name, unit)][line - 1]

    def read_lines(self, spec: VariableSpec, unit: int, line: int, count: int) -> list[Any]:
        return self.stored[(spec.name, unit)][line - 1:line - 1 + count]

    def write_lines(self, spec: VariableSpec, unit: int, line: int, values: Sequence[object]) -> None:
        stored = self.stored[(spec.name, unit)]
        stored[line - 1:line - 1 + len(values)] = values
        if spec.effective in ("immediate", "reset"):
            active = self.active.get((spec.name, unit))
            if active is None or active is stored or len(active) != len(stored):
                self.active[(spec.name, unit)] = list(stored)
            else:  # the lines written, not a copy of all (a program writes R1 in every block)
                active[line - 1:line - 1 + len(values)] = values

    def checked_value(self, spec: VariableSpec, value: object) -> object:
        """The value as the variable stores it, or the item error a controller gives for it."""
        if spec.nck_type == NckType.STRING:
            return str(value)
        if spec.nck_type in (NckType.REAL4, NckType.REAL8):
            number = float(value)  # type: ignore[arg-type]
            if not math.isfinite(number):
                raise NckItemError(f"{spec.number}: {number} is not a finite number", return_code=self._limit_rc)
        else:
            number = int(value)  # type: ignore[call-overload]
        if ((spec.minimum is not None and number < spec.minimum)
                or (spec.maximum is not None and number > spec.maximum)):
            raise NckItemError(f"{spec.number} {spec.name}: {number} outside {spec.minimum}..{spec.maximum}",
                               return_code=self._limit_rc)
        return number

    def activate_all(self) -> None:
        """Stored values become active (power-on)."""
        self.active = {key: list(values) for key, values in self.stored.items()}

    def activate(self, effective: str) -> list[str]:
        """Stored values of the variables with this effectiveness become active (e.g. "new_conf" on
        PI _N_CONFIG); the names of those variables."""
        names = []
        for spec in self.specs:
            if spec.effective != effective or spec.computed:
                continue
            names.append(spec.name)
            for key, values in self.stored.items():
                if key[0] == spec.name:
                    self.active[key] = list(values)
        return names

    def apply_initial(self, initial: Mapping[str, Mapping[int, object]], find: Callable[[str], Any],
                      source: str) -> None:
        """A machine file's ``[initial]`` values, by Siemens number or name."""
        for name, per_unit in initial.items():
            spec = find(name)
            if spec is None or spec.computed or spec.name not in self._by_name:
                raise NckConfigError(f"no stored NCK variable {name!r}", path=source, field=f"initial.{name}")
            for unit, value in per_unit.items():
                key = (spec.name, unit)
                if key not in self.stored:
                    raise NckConfigError(f"{name} has no unit {unit}", path=source, field=f"initial.{name}")
                values = value if isinstance(value, list) else [value]
                for line, item in enumerate(values):
                    self.stored[key][line] = self.checked_value(spec, item)

    # ------------------------------------------------------------------ retained data
    def retained_values(self) -> dict[str, dict[str, list[Any]]]:
        values: dict[str, dict[str, list[Any]]] = {}
        for (name, unit), stored in self.stored.items():
            if self._by_name[name].retained:
                values.setdefault(name, {})[str(unit)] = list(stored)
        return values

    def restore_values(self, values: Mapping[str, Mapping[str, list[Any]]]) -> None:
        for name, per_unit in values.items():
            for unit_text, stored in per_unit.items():
                key = (name, int(unit_text))
                if key not in self.stored:
                    log.warning("retained %s unit %s is not on this machine; ignored", name, unit_text)
                    continue
                if len(stored) != len(self.stored[key]):
                    raise NckConfigError(f"{name}[{unit_text}] has {len(stored)} lines", field="values")
                self.stored[key] = list(stored)
