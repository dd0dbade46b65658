"""Units at the boundaries.

Inside the package everything is SI. Wherever a number enters from a file, a CSV header, a CLI
flag or a plugin config key, its unit is part of its name (``pressure_kPa``, ``length_m``); this
module turns such a suffixed name into a factor to SI, and refuses a name whose unit it does not
know instead of guessing.
"""

from __future__ import annotations

import json
import math
import unicodedata

# factor that converts a value in the suffix unit into the SI unit of its quantity
PRESSURE = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "bar": 1e5, "psi": 6894.757293168361}
LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254}
FORCE = {"N": 1.0, "kN": 1e3, "mN": 1e-3, "lbf": 4.4482216152605}
TIME = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0}
ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}
VOLUME = {"m3": 1.0, "L": 1e-3, "cm3": 1e-6, "mL": 1e-6}

QUANTITIES = {
    "pressure": PRESSURE,
    "length": LENGTH,
    "force": FORCE,
    "time": TIME,
    "angle": ANGLE,
    "volume": VOLUME,
}


class UnitError(ValueError):
    """A boundary value came without a unit, or with one this package does not know."""


def split_unit(name: str) -> tuple[str, str | None]:
    """``'pressure_kPa'`` -> ``('pressure', 'kPa')``; a name without an underscore has no unit."""
    base, sep, unit = name.rpartition("_")
    if not sep or not base:
        return name, None
    return base, unit


def factor(unit: str, quantity: str, where: str = "") -> float:
    """Factor from ``unit`` to SI for ``quantity``; a clear error when the unit is unknown."""
    table = QUANTITIES[quantity]
    if unit not in table:
        known = ", ".join(sorted(table))
        place = f"{where}: " if where else ""
        # a unit's case is its meaning (mPa, MPa), so it is never guessed; one that differs only
        # in case is named (a logger that writes every header in capitals: 'TIME_S')
        alike = [u for u in table if str(unit).lower() == u.lower()]
        hint = f"; units are case-sensitive: did you mean '{alike[0]}'?" if len(alike) == 1 else ""
        raise UnitError(f"{place}unknown {quantity} unit '{unit}' (known: {known}){hint}")
    return table[unit]


def unit_that_fits(value_si: float, target_si: float, column: str, table: dict, within=None) -> str:
    """The header (``'time_ms'``) under which ``column``'s numbers, read as ``value_si`` with the
    header's own unit, would be nearest ``target_si`` among the units of ``table``; with
    ``within`` (low, high in SI) only a unit under which the value falls inside it. Empty when
    that is the header's own unit, its unit is not in ``table``, or the value is 0 or not finite.
    The unit hint of every reader (a value 1000 x off: mm written as m)."""
    base, unit = split_unit(column)
    if unit not in table or not value_si or not math.isfinite(value_si):
        return ""
    raw = abs(value_si) / table[unit]
    best = min(table, key=lambda u: abs(math.log(raw * table[u] / target_si)))
    if best == unit or (within is not None and not within[0] <= raw * table[best] <= within[1]):
        return ""
    return f"{base}_{best}"


def was_it_in(header: str) -> str:
    """The hint a refusal adds for :func:`unit_that_fits`'s header (``'; was it in mm (write
    'length_mm')?'``), '' for none."""
    return f"; was it in {split_unit(header)[1]} (write '{header}')?" if header else ""


def is_odd_space(character: str) -> bool:
    """Whether a character the readers met outside ASCII is a space (a no-break, thin or
    zero-width one): no writer of CSV or JSON puts one round or inside a number."""
    return character.isspace() or unicodedata.category(character) in ("Zs", "Cf")


REQUIRED = object()


def read_quantity(mapping: dict, base: str, quantity: str, where: str, default=REQUIRED):
    """Read ``base_<unit>`` from a dict of boundary values and return it in SI.

    Exactly one unit variant may be present. ``default`` (already SI, may be None) is returned
    when none is; without a default a missing key is an error naming the key and an example unit.
    """
    table = QUANTITIES[quantity]
    found = [(k, u) for k in mapping for b, u in [split_unit(k)] if b == base and u is not None]
    if base in mapping:
        example = next(iter(table))
        raise UnitError(f"{where}: key '{base}' has no unit; write e.g. '{base}_{example}'")
    if len(found) > 1:
        raise UnitError(f"{where}: {base} given twice ({', '.join(k for k, _ in found)})")
    if not found:
        if default is not REQUIRED:
            return default
        example = "kPa" if quantity == "pressure" else next(iter(table))
        raise UnitError(f"{where}: missing key '{base}_<unit>' (e.g. '{base}_{example}')")
    key, unit = found[0]
    value = mapping[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise UnitError(f"{where}: key '{key}' must be a finite number, got {json_shown(value)}")
    return float(value) * factor(unit, quantity, f"{where}: key '{key}'")


# ------------------------------------------------------------- unit checks at Python entry points
#: Below this a gauge pressure handed to a Python entry point (in Pa) is most likely kPa or psi:
#: every muscle of the paper has a dead band of tens of kPa, so such a pressure does nothing.
SMALLEST_LIKELY_PRESSURE_PA = 1000.0


class PressureUnitWarning(UserWarning):
    """A pressure given in Pa that is so small it was probably meant in kPa (or psi)."""


def check_pressure_Pa(pressure_Pa, where: str, *, stacklevel: int = 3) -> None:
    """Warn (:class:`PressureUnitWarning`) when the largest non-zero pressure given to ``where``
    is below 1000 Pa: Python entry points take Pa, and 300 "Pa" is almost surely 300 kPa."""
    import warnings

    import numpy as np

    values = np.abs(np.asarray(pressure_Pa, dtype=float))
    values = values[np.isfinite(values) & (values > 0)]
    if values.size and float(values.max()) < SMALLEST_LIKELY_PRESSURE_PA:
        top = float(values.max())
        warnings.warn(
            f"{where}: pressure {top:g} Pa is below {SMALLEST_LIKELY_PRESSURE_PA:g} Pa; pressures are "
            f"in Pa here (did you mean {top:g} kPa = {top * 1e3:g} Pa?)",
            PressureUnitWarning,
            stacklevel=stacklevel,
        )


class RangeError(ValueError):
    """A value outside the range a model can take: it would be clamped (saturated) silently."""


def check_within(values, low: float, high: float, *, what: str, unit: str = "", scale: float = 1.0) -> None:
    """Raise :class:`RangeError` when a value is outside ``[low, high]`` (a model's control range,
    a size bound): MuJoCo would clamp a control silently, so the caller refuses instead. ``what``
    names the value the way the user gave it (``--pressures-kPa``); ``scale`` converts SI to the
    unit shown (1e-3 for kPa)."""
    import numpy as np

    array = np.atleast_1d(np.asarray(values, dtype=float))
    bad = ~np.isfinite(array) | (array < low) | (array > high)
    if bad.any():
        first = float(array[np.argmax(bad)])
        u = f" {unit}" if unit else ""
        raise RangeError(
            f"{what}: {first * scale:g}{u} is outside [{low * scale:g}, {high * scale:g}]{u} "
            "(it would be clamped silently)"
        )


def is_control(character: str) -> bool:
    """A control or format character (Unicode category C: an escape, a bell, a newline); a
    no-break space, an accent or a symbol is not."""
    return unicodedata.category(character)[0] == "C"


def visible(text: str) -> str:
    """``text`` with every control or format character written as its escape (a terminal escape
    sequence in a file name never reaches the screen as it is); the rest stays as written."""
    return "".join(c.encode("unicode_escape").decode("ascii") if is_control(c) else c for c in text)


def as_float(value) -> float:
    """``value`` as one float (a numpy scalar, a 0-d array, a Decimal are numbers), NaN when it
    is not a number (a bool or a text is not one, though Python would convert them)."""
    try:
        if isinstance(value, (bool, str, bytes)):
            raise TypeError
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return math.nan


def as_floats(value):
    """``value`` as a numpy array of floats, None when it is not numbers (None, a text, or
    anything numpy cannot read as numbers): the array twin of :func:`as_float`, for callers that
    name the argument in their own message."""
    import numpy as np

    try:
        if value is None or isinstance(value, (str, bytes)):
            raise TypeError
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None


def json_shown(value, limit: int = 60) -> str:
    """``value`` as the JSON file wrote it, for messages: ``null``, ``true``, ``"text"`` (Python's
    ``None``, ``True``, ``'text'`` are not what the user typed); cut to ``limit`` characters.
    A value JSON cannot spell (from a Python call) is shown as Python shows it."""
    try:
        text = json.dumps(value, allow_nan=True)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
