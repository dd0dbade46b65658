"""Muscle files: the paper's presets and calibrated muscles, as JSON.

A muscle file holds what a user measured or identified, with units in its keys::

    {
      "format": "efam_mujoco.muscle/1",
      "name": "FAM1",
      "geometry":  {"rest_length_m": ..., "rest_diameter_m": ..., "sleeve_length_ref_m": ...},
      "constants": {"theta_rest_deg": ..., "bladder_volume_m3": ...},
      "deadband_kPa": 33.62,
      "tension_only": false,
      "stress": {"default": "exponential_decay", "laws": {"linear": {"E1_Pa": ..., "E2": ...}}}
    }

``geometry`` (paper Table 2) derives the constants through Eqs. 3-8; ``constants`` gives them
directly (rest_length, rest_diameter, theta_rest, bladder_volume) and overrides what geometry
derives, which is how a calibration that re-estimated the braid angle from blocked forces
(Sec. 4.4) is stored. The resting length is measured, not re-estimated: given in both blocks,
the two must agree. Any key may use another unit of the same quantity (``rest_length_cm``).
"""

from __future__ import annotations

import copy
import errno
import json
import math
import os
import unicodedata
from importlib import resources
from pathlib import Path

import numpy as np

from .files import PRESET_NAMES, check_json_name, strict_json, write_json_atomic
from .muscle import (
    DEFAULT_LOCK_STIFFNESS,
    MAX_DEADBAND_PA,
    MAX_LOCK_STIFFNESS_N_PER_M,
    MIN_DEADBAND_PA,
    NEUTRAL_BRAID_ANGLE_DEG,
    SIZE_RANGE_M,
    Geometry,
    Muscle,
    MuscleError,
    deadband_problem,
    written_deadband_Pa,
)
from .stress import E1_PLAUSIBLE_PA, EXPONENT_E4_MAX, LAW_NAMES, StressLaw, StressLawError
from .units import (
    LENGTH,
    PRESSURE,
    REQUIRED,
    UnitError,
    is_odd_space,
    json_shown,
    read_quantity,
    split_unit,
    unit_that_fits,
    was_it_in,
)

FORMAT = "efam_mujoco.muscle/1"
PRESETS = PRESET_NAMES  # one list, kept beside the output policy that refuses those names

_GEOMETRY_LENGTHS = (
    "rest_length", "rest_diameter", "sleeve_length_ref", "sleeve_diameter_ref", "bladder_length",
    "bladder_inner_diameter", "bladder_outer_diameter", "clamp_length", "clamp_inner_diameter",
    "clamp_outer_diameter", "thread_thickness",
)  # fmt: skip


class MuscleFileError(ValueError):
    """A muscle file that cannot be read; the message names the file and the key."""


#: The pressure at which a law's pressure-stiffened modulus E1 + E2 P is checked against the
#: bladder's plausible range (1 MPa, the recordings' default rated pressure).
STIFFENING_PRESSURE_PA = 1.0e6

#: A muscle file is a few kB; anything above this is not one (and is not read into memory).
MAX_FILE_BYTES = 4_000_000

#: Every key a muscle file may hold at the top level (``deadband`` with any pressure unit).
TOP_LEVEL_KEYS = (
    "format", "name", "description", "geometry", "constants", "deadband_<unit>", "tension_only",
    "lock_stiffness_N_per_m", "stress", "published", "notes", "calibration",
)  # fmt: skip
_FREE_FORM = ("published", "calibration")  # informational blocks, not read by the model
_CONSTANTS = (("rest_length", "length"), ("rest_diameter", "length"), ("theta_rest", "angle"),
              ("bladder_volume", "volume"))  # fmt: skip
#: Plausible ranges (SI) of what a muscle file gives; outside them a value cannot be physical
#: for a fluidic muscle and is most likely in another unit than its key says.
PLAUSIBLE = {
    "length": SIZE_RANGE_M,  # 0.1 mm .. 10 m, the Muscle's own bounds (Festo sells DMSP up to 9 m)
    # a sleeve, bladder, clamp or muscle across: 0.1 mm .. 20 cm, five times the widest fluidic
    # muscle sold (Festo DMSP-40, 40 mm bore; the paper's is 2.9 cm): 12.7 "in" is 12.7 mm
    "diameter": (SIZE_RANGE_M[0], 0.2),
    # a braid's thread: 0 (no thickness modelled, see geometry_from_dict), or from a 10 um
    # filament to 5 mm (the paper's 0.15 mm, the sleeve 0.28 mm; the catalogue's own bound)
    "thickness": (1e-5, 5e-3),
    "volume": (1e-12, 1.0),
    "pressure": (0.0, 10e6),  # a dead band up to 10 MPa
    "angle": (0.0, 3.141592653589793 / 2),
}
#: Braid angles at rest (deg) a braided sleeve is wound at, and the thinnest bladder wall (m):
#: outside them a muscle file's constants describe nothing that could be built.
BRAID_ANGLE_DEG = (2.0, 88.0)
MIN_WALL_M = 1e-5
#: No stress-law coefficient of a rubber bladder comes near this (1 TPa, stiffer than diamond).
MAX_COEFFICIENT = 1e12
#: Pressures at which a muscle file's model must give a finite force at every admissible length.
CHECK_PRESSURES_PA = (0.0, 50e3, 200e3, 500e3, 1e6)
#: A dead band must lie below the largest pressure the package drives a muscle with
#: (``muscle.MAX_DEADBAND_PA``): the rig's control range and the recordings' default rated
#: pressure (``rig.RigOptions.max_pressure_Pa``, ``recordings.DEFAULT_RATED_PRESSURE_PA``, both
#: 1000 kPa; the paper's dead bands are 34 kPa). At or above it the muscle is never inflated.
#: The resting length over the bladder's working length (its length less what the
#: fittings take, Eq. 7) is at most this, and at least its inverse. The model takes the bladder
#: as unstrained at the resting length (Eq. 12); fabrication and cycling lengthen it by
#: +3.7 % and +5.39 % (paper Sec. 4.2), so a factor of 1.5 is ten times that creep, and a
#: muscle much longer than its bladder is a unit slip or the wrong key, not a muscle.
MAX_REST_OVER_BLADDER = 1.5


def preset_names() -> tuple[str, ...]:
    """The presets shipped with the package (``fam1``, ``fam2``), usable wherever a file is."""
    return PRESETS


def _reject_constant(name: str):
    raise ValueError(f"'{name}' is not a JSON number (use a finite number)")


#: an integer with more digits than this is no count or value these files hold (a float()
#: of it overflowed with Python's bare "int too large to convert to float")
MAX_INTEGER_DIGITS = 15


def _bounded_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INTEGER_DIGITS:
        raise ValueError(f"an integer of {len(text.lstrip('-'))} digits cannot be a value here")
    return int(text)


def _no_duplicates(pairs):
    seen = {}
    for key, value in pairs:
        if key in seen:
            raise ValueError(f"key '{key}' appears twice in one object")
        seen[key] = value
    return seen


def _string_at(text: str, i: int) -> tuple[int, bool]:
    """(index of the closing quote, whether a ':' follows it) of the JSON string opening at
    ``text[i]``: the scans below skip strings whole and tell keys from values."""
    n = len(text)
    end = i + 1
    while end < n and text[end] != '"':
        end += 2 if text[end] == "\\" else 1
    after = end + 1
    while after < n and text[after] in " \t\r\n":
        after += 1
    return end, after < n and text[after] == ":"


def _where_refused(text: str) -> tuple[int, int]:
    """(line, column) of the first NaN/Infinity token, over-long integer or key repeated in its object in ``text``
    (JSON the standard decoder accepts but the hooks refuse); (1, 1) when not found."""
    objects: list[set | None] = []  # per open bracket: the keys of an object, None for an array
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == '"':
            end, is_key = _string_at(text, i)
            if objects and objects[-1] is not None and is_key:
                key = text[i + 1 : end]
                if key in objects[-1]:
                    break
                objects[-1].add(key)
            i = end + 1
            continue
        if c in "{[":
            objects.append(set() if c == "{" else None)
        elif c in "}]" and objects:
            objects.pop()
        elif text.startswith(("NaN", "Infinity", "-Infinity"), i):
            break
        elif c.isdigit() and not text[i - 1 : i].isdigit():
            digits = len(text[i:]) - len(text[i:].lstrip("0123456789"))
            follows = text[i + digits : i + digits + 1]
            if digits > MAX_INTEGER_DIGITS and follows not in (".", "e", "E"):
                break
            i += digits
            continue
        i += 1
    else:
        return 1, 1
    line = text.count("\n", 0, i) + 1
    return line, i - (text.rfind("\n", 0, i) + 1) + 1


def _stray_character(text: str) -> tuple[int, str] | None:
    """(index, key) of the first non-ASCII character outside a JSON string in ``text`` (a no-break
    or thin space inside a number, a typographic quote) and the last key before it ('' if none):
    JSON takes none there, and its decoder's "Expecting ',' delimiter" did not say what it met."""
    i, n, key = 0, len(text), ""
    while i < n:
        c = text[i]
        if c == '"':
            end, is_key = _string_at(text, i)
            if is_key:
                key = text[i + 1 : end]
            i = end + 1
            continue
        if ord(c) > 127:
            return i, key
        i += 1
    return None


def _stray_message(text: str, label: str) -> str | None:
    """The error naming line, column, key and character of :func:`_stray_character`, or None."""
    found = _stray_character(text)
    if found is None:
        return None
    i, key = found
    c = text[i]
    line, column = text.count("\n", 0, i) + 1, i - (text.rfind("\n", 0, i) + 1) + 1
    name = unicodedata.name(c, "unnamed").lower()
    after = f" after key '{key}'" if key else ""
    if is_odd_space(c):
        why = "JSON's only spaces are the ASCII space, tab and line break, and a number holds none"
    else:
        why = "JSON's quotes, brackets and digits are ASCII (a typographic quote?)"
    return (
        f"{label}: line {line}, column {column}: not valid JSON: the character U+{ord(c):04X} ({name}){after} "
        f"is outside a string; {why}"
    )


def parse_json_text(data: bytes, label: str) -> object:
    """Strict JSON from bytes: UTF-8 (a BOM is allowed), no NaN/Infinity, no duplicate keys;
    errors name ``label``, the line and the column."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        column = err.start - (data.rfind(b"\n", 0, err.start) + 1) + 1
        raise MuscleFileError(
            f"{label}: line {line}, column {column}: byte 0x{data[err.start]:02x} is not UTF-8 "
            "(save the file as UTF-8)"
        ) from None
    try:
        return json.loads(
            text, parse_constant=_reject_constant, object_pairs_hook=_no_duplicates, parse_int=_bounded_int
        )
    except json.JSONDecodeError as err:
        # a non-ASCII character outside a string is never JSON: name it, where the decoder
        # only said what it expected (a no-break space inside 33.62 was "Expecting ',' delimiter")
        stray = _stray_message(text, label)
        raise MuscleFileError(
            stray or f"{label}: line {err.lineno}, column {err.colno}: not valid JSON ({err.msg})"
        ) from None
    except ValueError as err:  # the hooks' refusals (NaN, a key twice) know no position: find it
        line, column = _where_refused(text)
        raise MuscleFileError(f"{label}: line {line}, column {column}: not valid JSON ({err})") from None
    except RecursionError:
        raise MuscleFileError(f"{label}: not valid JSON: nested too deeply") from None


def _why_link_fails(path: Path) -> str:
    """Why the link ``path`` leads to no file: it loops back on itself, or its target is missing
    (a loop was called "a broken link")."""
    try:
        path.resolve(strict=True)
    except RuntimeError:  # pathlib's word for a loop before Python 3.13
        return "a link that loops back on itself, not a file"
    except OSError as err:
        if err.errno == errno.ELOOP:
            return "a link that loops back on itself, not a file"
    return "no such file (a broken link: what it points to does not exist)"


def read_small_file(path: str | Path, what: str, max_bytes: int = MAX_FILE_BYTES) -> tuple[bytes, str]:
    """The bytes of a small input file (``what``: "a muscle file", "an arm spec file") and its label,
    refused, naming it, when it is a folder, not a regular file (a pipe would block, /dev/zero
    never end) or larger than ``max_bytes`` (not read into memory)."""
    path = Path(path)
    label = str(path)
    try:
        if path.is_dir():
            raise MuscleFileError(f"{label}: is a folder, not {what}")
        if not path.exists():
            raise MuscleFileError(
                f"{label}: " + (_why_link_fails(path) if path.is_symlink() else "no such file")
            )
        if not path.is_file():
            raise MuscleFileError(f"{label}: not a regular file (a pipe or a device?), not {what}")
        size = path.stat().st_size
        if size > max_bytes:
            raise MuscleFileError(f"{label}: {size} bytes is not {what} (at most {max_bytes} bytes)")
        return path.read_bytes(), label
    except OSError as err:  # a link loop, no permission, an I/O error
        raise MuscleFileError(f"{label}: cannot read ({err.strerror or err})") from None


def read_document(source: str | Path) -> tuple[dict, str]:
    """The parsed JSON of a preset name or a file path, and a label for messages."""
    if not isinstance(source, (str, os.PathLike)):
        raise MuscleFileError(f"a muscle is a preset name or a file path, got {type(source).__name__}")
    if isinstance(source, str) and not source.strip():  # Path('') is '.': "is a folder" hid the mistake
        raise MuscleFileError("a muscle is a preset name or a file path, got an empty name")
    key = str(source).lower()
    if key in PRESETS and Path(source).exists():
        raise MuscleFileError(
            f"'{source}' is both a preset and a file here; write ./{source} for the file or "
            f"{key.upper()} for the preset (and not a file of that name)"
        )
    if key in PRESETS:
        data = resources.files("efam_mujoco.presets").joinpath(f"{key}.json").read_bytes()
        label = f"preset {key.upper()}"
    else:
        path = Path(source)
        if not path.exists() and not path.is_symlink():
            raise MuscleFileError(
                f"'{source}' is neither a preset ({', '.join(p.upper() for p in PRESETS)}) nor a file"
            )
        data, label = read_small_file(path, "a muscle file")
    doc = parse_json_text(data, label)
    if not isinstance(doc, dict):
        raise MuscleFileError(f"{label}: expected a JSON object at the top level")
    fmt = doc.get("format")
    if fmt != FORMAT:
        raise MuscleFileError(f"{label}: key 'format' must be '{FORMAT}', got {json_shown(fmt)}")
    return doc, label


def _block(doc: dict, key: str, label: str) -> dict:
    value = doc[key]
    if not isinstance(value, dict):
        raise MuscleFileError(f"{label}: key '{key}' must be a JSON object, got {_json_type(value)}")
    return value


def _json_type(value) -> str:
    names = {bool: "a boolean", str: "a string", list: "a list", dict: "an object", type(None): "null"}
    for kind, name in names.items():
        if isinstance(value, kind):
            return f"{name} ({json.dumps(value)[:40]})"
    return f"{value!r}"


def _check_keys(block: dict, allowed_bases: dict[str, str | None], where: str) -> None:
    """Every key of ``block`` is ``<base>_<unit>`` for a known base (or exactly a known plain key)."""
    for key in block:
        if key in allowed_bases and allowed_bases[key] is None:
            continue
        base, unit = split_unit(key)
        if base in allowed_bases and allowed_bases[base] is not None and unit:
            continue
        if key in allowed_bases:  # a base without its unit
            continue  # read_quantity names it ("has no unit")
        known = ", ".join(f"{b}_<unit>" if q else b for b, q in allowed_bases.items())
        raise MuscleFileError(f"{where}: unknown key '{key}' (known: {known})")


_SI_UNIT = {
    "length": "m",
    "diameter": "m",
    "thickness": "m",
    "volume": "m3",
    "pressure": "Pa",
    "angle": "rad",
}


def _plausible(value: float, block: dict, base: str, quantity: str, where: str) -> float:
    """``value`` (SI) when plausible for a fluidic muscle (``quantity``: a key of PLAUSIBLE), else
    an error naming the key as the file wrote it, the range and the unit that would fit."""
    lo, hi = PLAUSIBLE[quantity]
    if lo < value <= hi or (quantity == "pressure" and value == 0.0):
        return value
    key = next((k for k in block if split_unit(k)[0] == base), base)
    unit = split_unit(key)[1] or ""
    hint = ""
    if quantity in ("length", "diameter", "thickness"):  # mm, cm, m or in: the one that fits
        hint = was_it_in(unit_that_fits(value, math.sqrt(lo * hi), key, LENGTH, within=(lo, hi)))
    elif value > hi and lo < value / 1000 <= hi:
        smaller = {"m": "mm", "Pa": "", "kPa": "Pa", "MPa": "kPa", "m3": "L"}.get(unit, "")
        if quantity == "volume":
            smaller = "L" if unit == "m3" else ""
        if smaller:
            hint = f"; was it in {smaller} (write '{base}_{smaller}')?"
    raise MuscleFileError(
        f"{where}: key '{key}' = {block.get(key)!r} cannot be physical for a fluidic muscle "
        f"({value:g} {_SI_UNIT[quantity]}; expected {lo:g} .. {hi:g} {_SI_UNIT[quantity]}){hint}"
    )


def _quantity(block: dict, base: str, quantity: str, where: str, default=REQUIRED, kind: str | None = None):
    """``<base>_<unit>`` of ``block`` in SI, plausible as ``kind`` (default: ``quantity``)."""
    value = read_quantity(block, base, quantity, where, default)
    if value is None or value is default:
        return value
    return _plausible(value, block, base, kind or quantity, where)


def geometry_from_dict(g: dict, where: str) -> Geometry:
    """The ``geometry`` block (paper Table 2) -> :class:`Geometry`; every key known, with units."""
    if not isinstance(g, dict):
        raise MuscleFileError(f"{where}: must be a JSON object, got {_json_type(g)}")
    allowed = {k: "length" for k in _GEOMETRY_LENGTHS} | {"sleeve_angle_ref": "angle", "fittings": None}
    _check_keys(g, allowed, where)
    values = {}
    for k in _GEOMETRY_LENGTHS:
        value = read_quantity(g, k, "length", where)
        # A thread thickness of 0 is kept as a legitimate idealisation: it enters only Eq. 6,
        # as the room the sleeve takes in the clamping channel, and 0 says it takes none (a
        # channel measured inside the sleeve, or fittings that clamp the bladder alone). Any
        # other value must be a thread that could exist.
        if k == "thread_thickness" and value == 0:
            values[f"{k}_m"] = 0.0
            continue
        kind = "thickness" if k == "thread_thickness" else "diameter" if "diameter" in k else "length"
        values[f"{k}_m"] = _plausible(value, g, k, kind, where)
    angle = _quantity(g, "sleeve_angle_ref", "angle", where, default=None)
    if angle is not None:
        values["sleeve_angle_ref_deg"] = angle * 180.0 / 3.141592653589793
    fittings = g.get("fittings", 2)
    if isinstance(fittings, bool) or not isinstance(fittings, int) or not 1 <= fittings <= 16:
        raise MuscleFileError(
            f"{where}: key 'fittings' must be a whole number of end fittings (1 .. 16), got {_json_type(fittings)}"
        )
    values["fittings"] = fittings
    geometry = Geometry(**values)
    _check_parts(geometry, g, where)
    return geometry


#: Unicode's bidirectional embeddings, overrides and isolates (U+202A-U+202E, U+2066-U+2069)
BIDI_CONTROLS = frozenset(map(chr, (*range(0x202A, 0x202F), *range(0x2066, 0x206A))))


def check_text(value: str, key: str, label: str, one_line: bool = True) -> None:
    """Refuse a string holding a control character or half a surrogate pair (JSON's \\u0000,
    \\ud800): it is not text, and breaks the XML models, reports and file names a name goes into.
    A name is one line (it heads tables and names files); other text (``one_line`` False) may
    hold tabs and line breaks. :class:`MuscleFileError` names ``label`` and ``key``."""
    allowed = "" if one_line else "\t\n"
    bad = next((ch for ch in value if unicodedata.category(ch) in ("Cc", "Cs") and ch not in allowed), None)
    if bad is not None:
        raise MuscleFileError(
            f"{label}: key '{key}' holds the character U+{ord(bad):04X}, which is not text (a control "
            "character or half a surrogate pair)"
        )
    # a bidirectional embedding, override or isolate reorders what a terminal or a report shows
    # after it (a name printed as another): not text a muscle's name or description needs
    bidi = next((ch for ch in value if ch in BIDI_CONTROLS), None)
    if bidi is not None:
        raise MuscleFileError(
            f"{label}: key '{key}' holds the character U+{ord(bidi):04X}, a bidirectional control that "
            "reorders the text shown after it; remove it"
        )


def _validate_top_level(doc: dict, label: str) -> None:
    for key in doc:
        base, unit = split_unit(key)
        if key in TOP_LEVEL_KEYS or (base == "deadband" and unit) or key == "deadband":
            continue
        raise MuscleFileError(
            f"{label}: unknown key '{key}' (known: {', '.join(TOP_LEVEL_KEYS)}); a misspelled or "
            "unit-less key is an error, never ignored"
        )
    for key in ("name", "description"):
        if key in doc and not isinstance(doc[key], str):
            raise MuscleFileError(f"{label}: key '{key}' must be a string, got {_json_type(doc[key])}")
        check_text(doc.get(key, ""), key, label, one_line=key == "name")
    if "notes" in doc and not (
        isinstance(doc["notes"], list) and all(isinstance(n, str) for n in doc["notes"])
    ):
        raise MuscleFileError(f"{label}: key 'notes' must be a list of strings")
    for key in _FREE_FORM:
        if key in doc:
            _block(doc, key, label)
    if "tension_only" in doc and not isinstance(doc["tension_only"], bool):
        raise MuscleFileError(
            f"{label}: key 'tension_only' must be a JSON boolean (true or false, no quotes), got "
            f"{_json_type(doc['tension_only'])}"
        )


def muscle_from_document(doc: dict, label: str, law: str | None = None) -> Muscle:
    """Build a :class:`Muscle` from a parsed muscle file, with the named (or default) law.

    Strict: every key must be known and carry its unit, of the right JSON type (booleans only
    as JSON booleans), and plausible for a fluidic muscle; the law must give a finite force at
    every admissible length. Any problem is a :class:`MuscleFileError` naming the file and key.
    """
    try:
        _validate_top_level(doc, label)
        constants: dict[str, float] = {}
        if "geometry" in doc:
            geometry = geometry_from_dict(doc["geometry"], f"{label}: geometry")
            constants = {
                "rest_length_m": geometry.rest_length_m,
                "rest_diameter_m": geometry.rest_diameter_m,
                "theta_rest_deg": geometry.theta_rest_deg,
                "bladder_volume_m3": geometry.bladder_volume_m3,
            }
        given = _block(doc, "constants", label) if "constants" in doc else {}
        where = f"{label}: constants"
        _check_keys(given, dict(_CONSTANTS), where)
        for base, quantity in _CONSTANTS[:2] + _CONSTANTS[3:]:
            key = f"{base}_{'m3' if quantity == 'volume' else 'm'}"
            derived = constants.get(key)  # from the geometry block, if any
            kind = "diameter" if base == "rest_diameter" else quantity
            value = _quantity(given, base, quantity, where, default=derived, kind=kind)
            if value is None:
                raise MuscleFileError(f"{where}: missing key '{key}' (or a 'geometry' block)")
            if (
                key == "rest_length_m"
                and derived is not None
                and not math.isclose(value, derived, rel_tol=1e-6)
            ):
                # the resting length is measured, not calibrated: the geometry derived the braid
                # angle and the bladder volume from its own, so another one here contradicts them
                raise MuscleFileError(
                    f"{where}: rest_length = {value:.6g} m contradicts the 'geometry' block's "
                    f"{derived:.6g} m, from which the braid angle and bladder volume were derived: give "
                    "the resting length once (the constants block may override the braid angle, the "
                    "diameter and the bladder volume that a calibration re-estimates)"
                )
            constants[key] = value
        theta = _quantity(given, "theta_rest", "angle", where, default=None)
        if theta is not None:
            constants["theta_rest_deg"] = theta * 180.0 / 3.141592653589793
        if "theta_rest_deg" not in constants:
            raise MuscleFileError(f"{where}: missing key 'theta_rest_deg' (or a 'geometry' block)")
        if constants["rest_diameter_m"] >= constants["rest_length_m"]:
            # Eqs. 3-8 treat the braid as a long cylinder; a muscle wider than long loaded, then
            # the rig could not settle it and blamed a load that was never given
            raise MuscleFileError(
                f"{label}: a resting diameter of {constants['rest_diameter_m']:.6g} m is not below the resting "
                f"length {constants['rest_length_m']:.6g} m: a fluidic muscle is a braided tube longer than it is "
                "wide (is one of them in another unit?)"
            )
        deadband = _quantity(doc, "deadband", "pressure", label)
        # the key as the file wrote it, for the messages below (``deadband_kPa`` when absent)
        deadband_key = next((k for k in doc if split_unit(k)[0] == "deadband"), "deadband_kPa")
        if deadband < 0:
            raise MuscleFileError(f"{label}: deadband must not be negative, got {deadband:g} Pa")
        if deadband >= MAX_DEADBAND_PA:
            smaller = {"kPa": "Pa", "MPa": "kPa"}.get(split_unit(deadband_key)[1] or "", "")
            hint = f"; was it in {smaller} (write 'deadband_{smaller}')?" if smaller else ""
            raise MuscleFileError(
                f"{label}: key '{deadband_key}' = {doc.get(deadband_key)!r} is a dead band of {deadband / 1e3:g} kPa, not below "
                f"the {MAX_DEADBAND_PA / 1e3:g} kPa the package drives a muscle with at most (the rig's "
                f"control range and the rated pressure): the muscle would never inflate{hint}"
            )
        if deadband_problem(deadband):  # a kPa value written as Pa (33.62 for 33.62 kPa)
            hint = was_it_in(
                unit_that_fits(
                    deadband, 34e3, deadband_key, PRESSURE, within=(MIN_DEADBAND_PA, MAX_DEADBAND_PA)
                )
            )
            raise MuscleFileError(
                f"{label}: key '{deadband_key}' = {doc.get(deadband_key)!r} is a dead band of {deadband:g} Pa, which cannot be "
                f"physical: expected 0 (none) or {MIN_DEADBAND_PA:g} Pa .. {MAX_DEADBAND_PA / 1e3:g} kPa (the "
                f"paper's are 34 kPa; below {MIN_DEADBAND_PA:g} Pa no pressure sensor tells one from none){hint}"
            )
        stress = stress_from_document(doc, label, law)
        lock = doc.get("lock_stiffness_N_per_m", DEFAULT_LOCK_STIFFNESS)
        if (
            isinstance(lock, bool)
            or not isinstance(lock, (int, float))
            or not 0 <= lock <= MAX_LOCK_STIFFNESS_N_PER_M
        ):
            raise MuscleFileError(
                f"{label}: key 'lock_stiffness_N_per_m' must be a number in [0, 1e9], got {_json_type(lock)}"
            )
        muscle = Muscle(
            **constants,
            deadband_Pa=deadband,
            stress=stress,
            tension_only=doc.get("tension_only", False),
            lock_stiffness_N_per_m=float(lock),
            name=str(doc.get("name", label)),
        )
        check_tension_only(muscle, f"{label}: key 'tension_only' = true")
        check_finite_forces(muscle, f"{label}: stress law '{stress.name}'")
        for name, coefficients in doc["stress"]["laws"].items():  # every law, not only the one used
            if name != stress.name:
                other = StressLaw.from_dict(name, coefficients, where=f"{label}: stress law '{name}'")
                check_finite_forces(_with_law(muscle, other), f"{label}: stress law '{name}'")
        _check_build(muscle, given, label)
        return muscle
    except (MuscleError, StressLawError, UnitError, OverflowError, ZeroDivisionError) as err:
        msg = " ".join(str(err).split()) or type(err).__name__
        if isinstance(err, (OverflowError, ZeroDivisionError)):
            msg = f"the muscle's constants overflow ({msg}): a value is far too large or small"
        raise MuscleFileError(msg if msg.startswith(label) else f"{label}: {msg}") from None
    except ValueError as err:  # scipy's root finders on degenerate constants
        if isinstance(err, MuscleFileError):
            raise
        raise MuscleFileError(f"{label}: the constants give no valid muscle ({err})") from None


def _with_law(muscle: Muscle, law: StressLaw) -> Muscle:
    """``muscle`` with ``law``, for evaluating forces only. Not :meth:`Muscle.with_stress`: that
    re-runs the Drucker check, which a law meets or fails when it is the one chosen; a law the
    file holds but the user did not choose must still give finite forces."""
    probe = copy.copy(muscle)
    object.__setattr__(probe, "stress", law)  # a frozen dataclass; the copy is private to the check
    return probe


def _check_parts(g: Geometry, block: dict, where: str) -> None:
    """Parts that can be assembled into the muscle the geometry block describes (paper Secs.
    2, 4.1, 4.2), each refusal naming the keys:

    * the resting length below the braid thread length B = L_ref / sin(theta_ref) (Eq. 3 at the
      sleeve's reference angle; this model measures the braid angle from the circumference):
      a muscle longer than its sleeve's threads cannot be sheathed by them (Eq. 10 has no radius);
    * the bladder longer than its clamping channels together: it is pushed through the whole
      length of each channel before swaging (Sec. 4.2: the excess is then pushed out);
    * the resting length within a factor MAX_REST_OVER_BLADDER of the working bladder length."""

    def key(base):
        return next((k for k in block if split_unit(k)[0] == base), f"{base}_m")

    ref = math.radians(g.sleeve_angle_ref_deg)
    thread = g.sleeve_length_ref_m / math.sin(ref)
    if not g.rest_length_m < thread:
        raise MuscleFileError(
            f"{where}: key '{key('rest_length')}' = {block.get(key('rest_length'))!r} gives a resting length of "
            f"{g.rest_length_m * 100:.4g} cm, not shorter than the sleeve's braid threads "
            f"({thread * 100:.4g} cm = '{key('sleeve_length_ref')}' / sin({g.sleeve_angle_ref_deg:g} deg), Eq. 3): "
            "no muscle that long can be built from this sleeve"
        )
    clamped = g.fittings * g.clamp_length_m
    if not clamped < g.bladder_length_m:
        raise MuscleFileError(
            f"{where}: key '{key('clamp_length')}' = {block.get(key('clamp_length'))!r}: {g.fittings} clamping "
            f"channels of {g.clamp_length_m * 100:.4g} cm take {clamped * 100:.4g} cm, not shorter than the "
            f"bladder ('{key('bladder_length')}', {g.bladder_length_m * 100:.4g} cm), which runs through each "
            "channel before swaging (Sec. 4.2)"
        )
    working = g.bladder_length_m - g.bladder_length_lost_m
    if not working > 0:
        raise MuscleFileError(
            f"{where}: keys '{key('clamp_length')}', '{key('clamp_inner_diameter')}', "
            f"'{key('clamp_outer_diameter')}': the clamping channels take {g.bladder_length_lost_m * 100:.4g} cm "
            f"of bladder (Eq. 7), the whole '{key('bladder_length')}' ({g.bladder_length_m * 100:.4g} cm)"
        )
    ratio = g.rest_length_m / working
    if not 1 / MAX_REST_OVER_BLADDER <= ratio <= MAX_REST_OVER_BLADDER:
        raise MuscleFileError(
            f"{where}: key '{key('rest_length')}' = {block.get(key('rest_length'))!r} gives a resting length of "
            f"{g.rest_length_m * 100:.4g} cm, {ratio:.3g} x the working bladder length {working * 100:.4g} cm "
            f"('{key('bladder_length')}' less what the fittings take, Eq. 7); the model takes the bladder as "
            f"unstretched at rest, and cycling lengthens it by a few % (Sec. 4.2), so the two must agree "
            f"within a factor {MAX_REST_OVER_BLADDER:g}"
        )


def _check_build(muscle: Muscle, given: dict, label: str) -> None:
    """A braid and a bladder that could be built: the rest angle inside ``BRAID_ANGLE_DEG`` (near 0
    the threads run along the axis and hold no hoop load, near 90 they wind in rings) and the wall
    at least ``MIN_WALL_M`` thick. Each key is in range on its own; together they can still
    describe no muscle (a 1e-11 m^3 bladder in a 23 mm sleeve: a wall a thousandth of a micron
    thick, which the diagnosis then met with effects on clean data)."""
    lo, hi = BRAID_ANGLE_DEG
    if not lo <= muscle.theta_rest_deg <= hi:
        key = next((k for k in given if split_unit(k)[0] == "theta_rest"), "theta_rest_deg")
        raise MuscleFileError(
            f"{label}: constants: key '{key}' gives a braid angle of {muscle.theta_rest_deg:.4g} deg at rest; a "
            f"braided sleeve is wound at {lo:g} .. {hi:g} deg (was it in radians, or the complement?)"
        )
    if not muscle.rest_wall_thickness_m >= MIN_WALL_M:
        key = next((k for k in given if split_unit(k)[0] == "bladder_volume"), "bladder_volume_m3")
        raise MuscleFileError(
            f"{label}: constants: key '{key}' = {muscle.bladder_volume_m3:.4g} m^3 gives a bladder wall "
            f"{muscle.rest_wall_thickness_m * 1e3:.3g} mm thick at rest, thinner than any bladder "
            f"({MIN_WALL_M * 1e3:g} mm); the key is the volume of the bladder's rubber, not of the air inside"
        )


def check_finite_forces(muscle: Muscle, where: str, pressures_Pa=CHECK_PRESSURES_PA) -> None:
    """Raise :class:`MuscleFileError` when ``muscle`` gives a non-finite force anywhere on its
    admissible lengths at the given pressures (e.g. an exponential-decay law whose large E4
    overflows ``exp`` in compression): MuJoCo would get 0 from the plugin and NaN from Python."""
    lengths = np.linspace(muscle.min_length_m, muscle.max_length_m, 401)
    with np.errstate(all="ignore"):
        for p in pressures_Pa:
            force = np.asarray(muscle.tension(p, lengths), dtype=float)
            bad = ~np.isfinite(force)
            if bad.any():
                L = float(lengths[np.argmax(bad)])
                raise MuscleFileError(
                    f"{where}: the force is not finite at length {L:.6g} m, pressure {p / 1e3:g} kPa "
                    f"(coefficients {muscle.stress.to_dict()}): a coefficient is too large for this muscle"
                )


def stress_from_document(doc: dict, label: str, law: str | None = None) -> StressLaw:
    """The named (or the file's default) stress law of a muscle file; every law in the file is
    checked for known names and coefficient keys."""
    block = doc.get("stress")
    if not isinstance(block, dict) or not isinstance(block.get("laws"), dict) or not block["laws"]:
        raise MuscleFileError(f"{label}: missing 'stress' block with a non-empty 'laws' object")
    for key in block:
        if key not in ("default", "laws"):
            raise MuscleFileError(f"{label}: stress: unknown key '{key}' (known: default, laws)")
    for name, coefficients in block["laws"].items():
        if name not in LAW_NAMES:
            raise MuscleFileError(f"{label}: stress: unknown law '{name}' (known: {', '.join(LAW_NAMES)})")
        if not isinstance(coefficients, dict):
            raise MuscleFileError(
                f"{label}: stress law '{name}' must be an object of coefficients, got {_json_type(coefficients)}"
            )
    default = block.get("default")
    if default is not None and not isinstance(default, str):
        raise MuscleFileError(f"{label}: stress: 'default' must be a law's name, got {_json_type(default)}")
    if default is not None and default not in block["laws"]:
        raise MuscleFileError(
            f"{label}: stress: 'default': no coefficients for stress law '{default}' "
            f"(has: {', '.join(block['laws'])})"
        )
    if law is None and default is None and len(block["laws"]) > 1:
        # which law the file means is not ours to guess: the first one written is no choice
        raise MuscleFileError(
            f"{label}: stress: {len(block['laws'])} laws ({', '.join(block['laws'])}) and no 'default': "
            'name the one to use with "default"'
        )
    name = law or default or next(iter(block["laws"]))
    if name not in block["laws"]:
        raise MuscleFileError(
            f"{label}: no coefficients for stress law '{name}' (has: {', '.join(block['laws'])})"
        )
    for other, coefficients in block["laws"].items():  # every law in the file must be readable
        StressLaw.from_dict(other, coefficients, where=f"{label}: stress law '{other}'")
        for key, value in coefficients.items():
            if abs(value) > MAX_COEFFICIENT:
                raise MuscleFileError(
                    f"{label}: stress law '{other}': coefficient '{key}' = {value:g} cannot be physical "
                    f"(|value| above {MAX_COEFFICIENT:g}; a bladder's moduli are MPa)"
                )
        if other == "exponent" and coefficients["E4"] > EXPONENT_E4_MAX:
            raise MuscleFileError(
                f"{label}: stress law 'exponent': coefficient 'E4' = {coefficients['E4']:g} cannot be physical: "
                f"the strain-stiffening exponent (dimensionless) of a rubber bladder lies in 1 .. "
                f"{EXPONENT_E4_MAX:g} (the paper's are 1.35 and 1.52; Ogden's largest for rubber about 5)"
            )
        modulus = coefficients["E1_Pa"]  # every law's first coefficient: the bladder's modulus
        low, high = E1_PLAUSIBLE_PA
        if not low <= modulus <= high:
            # a value in MPa or kPa written as Pa is the mistake a unit in the key's name invites
            unit = next((u for u, f in (("MPa", 1e6), ("kPa", 1e3)) if low <= modulus * f <= high), None)
            hint = f"; was it in {unit}?" if unit else ""
            raise MuscleFileError(
                f"{label}: stress law '{other}': coefficient 'E1_Pa' = {modulus:g} Pa cannot be physical for a "
                f"bladder (its modulus lies in {low:g} .. {high:g} Pa: soft silicone to stiff rubber){hint}"
            )
        # the pressure stiffens the modulus to E1 + E2 P: at a megapascal (the recordings' default
        # rated pressure) it must still be a rubber's, or every force at pressure is nonsense
        stiffened = modulus + coefficients.get("E2", 0.0) * STIFFENING_PRESSURE_PA
        if stiffened > high:
            raise MuscleFileError(
                f"{label}: stress law '{other}': coefficient 'E2' = {coefficients['E2']:g} cannot be physical for "
                f"a bladder: its modulus E1 + E2 P would reach {stiffened:.3g} Pa at {STIFFENING_PRESSURE_PA / 1e3:g} "
                f"kPa, above {high:g} Pa (stiff rubber); E2 is dimensionless (Pa of modulus per Pa of pressure, "
                "about 0 .. 20)"
            )
    return StressLaw.from_dict(name, block["laws"][name], where=f"{label}: stress law '{name}'")


def load_muscle(source: str | Path, law: str | None = None) -> Muscle:
    """A preset name (``FAM1``, ``fam2``) or a muscle file path -> :class:`Muscle`."""
    doc, label = read_document(source)
    return muscle_from_document(doc, label, law)


def available_laws(source: str | Path) -> tuple[str, ...]:
    """The stress laws a preset or muscle file has coefficients for."""
    doc, label = read_document(source)
    return tuple(doc.get("stress", {}).get("laws", {}))


def check_tension_only(muscle: Muscle, where: str) -> None:
    """Refuse a tension-only extensile muscle (braid angle below the neutral 35.26 deg, the angle
    of Eq. 3-4 here): it pushes
    its ends apart when pressurised, so as tension-only it would carry force only when stretched
    past its free length (the table of ``efam muscle`` read blocked force 40.7 N analytic, 0 N
    MuJoCo, without a word). The Python model and the plugin still take one (a slack extensile
    muscle is a test of the clamp); a user's file or flag is refused. Tension-only is for contractile (McKibben) muscles, whose braid buckles."""
    if muscle.tension_only and muscle.theta_rest_deg < NEUTRAL_BRAID_ANGLE_DEG:
        raise MuscleFileError(
            f"{where}, but the muscle is extensile (braid angle {muscle.theta_rest_deg:.4g} deg, below the "
            f"neutral {NEUTRAL_BRAID_ANGLE_DEG:.2f} deg): it pushes its ends apart when pressurised and, "
            "tension-only, would carry force only when stretched past its free length; tension-only is for "
            "contractile (McKibben) muscles"
        )


def muscle_document(muscle: Muscle, laws: dict[str, StressLaw] | None = None, **extra) -> dict:
    """A muscle file (as a dict) holding ``muscle``'s constants and one or more stress laws."""
    laws = dict(laws or {muscle.stress.name: muscle.stress})
    laws.setdefault(muscle.stress.name, muscle.stress)
    doc = {
        "format": FORMAT,
        "name": muscle.name,
        "constants": {
            "rest_length_m": muscle.rest_length_m,
            "rest_diameter_m": muscle.rest_diameter_m,
            "theta_rest_deg": muscle.theta_rest_deg,
            "bladder_volume_m3": muscle.bladder_volume_m3,
        },
        "deadband_kPa": written_deadband_Pa(muscle.deadband_Pa) / 1e3,
        "tension_only": muscle.tension_only,
        "lock_stiffness_N_per_m": muscle.lock_stiffness_N_per_m,
        "stress": {"default": muscle.stress.name, "laws": {k: v.to_dict() for k, v in laws.items()}},
    }
    doc.update(extra)
    return doc


def save_muscle(path: str | Path, muscle: Muscle, laws: dict[str, StressLaw] | None = None, **extra) -> Path:
    """Write a muscle file atomically (a failed write never leaves a half file). The document
    is read back through the file reader's checks first: a muscle the reader would refuse (a
    1 deg braid, a dead band above the rated pressure) is an error here, not a file that every
    later command refuses. A name with a recording's suffix (``.csv``) is refused."""
    if not isinstance(muscle, Muscle):
        raise TypeError(
            f"save_muscle(path, muscle, ...): muscle must be a Muscle, got {type(muscle).__name__}"
        )
    check_json_name("save_muscle", path)
    doc = muscle_document(muscle, laws, **extra)
    muscle_from_document(json.loads(strict_json(doc)), f"save_muscle({str(path)!r})")
    return write_json_atomic(path, doc)
