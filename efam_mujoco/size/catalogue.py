"""The parts catalogue (``catalogue.json``): braided sleeves and latex tubes as sold, the bladder
material's limits, and the manufacturing rules that turn a set of parts into a muscle.

Every number in the file carries its unit in its key (``reference_diameter_in``, ``wall_cm``);
inside, everything is SI. The sources are written in the file's ``sources`` block and in
docs/sizing.md. A user can pass their own file with the same layout (``efam size --catalogue``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ..musclefile import (
    MAX_REST_OVER_BLADDER,
    MIN_WALL_M,
    PLAUSIBLE,
    MuscleFileError,
    parse_json_text,
    read_small_file,
)
from ..units import (
    LENGTH,
    UnitError,
    is_control,
    json_shown,
    read_quantity,
    split_unit,
    unit_that_fits,
    was_it_in,
)

FORMAT = "efam_mujoco.catalogue/1"

#: Physical ranges of every catalogue quantity, SI: ``(low, high, low_open)``; a value outside
#: cannot describe a part (most likely another unit than its key says, or a percentage written
#: for a fraction). Lengths: a sleeve or tube from 0.1 mm to 20 cm across (a muscle file's own
#: bound, five times the widest fluidic muscle sold, Festo's DMSP-40: a tube of 12.7 "in" is
#: 12.7 mm); a braid from 0.01 mm to 10 mm thick; a bladder wall at least what a muscle file
#: accepts (MIN_WALL_M).
RANGES = {
    "diameter": (PLAUSIBLE["diameter"][0], PLAUSIBLE["diameter"][1], False),
    "thickness": (1e-5, 0.01, False),
    "wall": (MIN_WALL_M, 0.05, False),
    # no solid is lighter than 100 or denser than osmium's 22 590 kg/m^3
    "density": (100.0, 25_000.0, False),
    "fraction": (0.0, 1.0, True),  # a share of a volume: (0, 1]
    # a rating up to 100 MPa (hydraulics); the sizing itself stops at rules.max_pressure
    "pressure": (0.0, 100e6, True),
    # latex breaks at 7.5 (750 %); no elastomer stretches 20 times its length (2000 %)
    "elongation_at_break": (0.0, 20.0, True),
    "strain_safety_factor": (1.0, 100.0, False),  # below 1 it is not a safety factor
    # resting length over working bladder length, minus one: the muscle file's own bound
    "length_growth": (1 / MAX_REST_OVER_BLADDER - 1, MAX_REST_OVER_BLADDER - 1, False),
    "length_growth_spread": (0.0, MAX_REST_OVER_BLADDER - 1, False),
    # the braid sits on the bladder, so the resting diameter is at least the tube's; at most 3x
    "diameter_growth": (0.0, 2.0, False),
    # the fitting core goes into the bladder's bore: about its size (Table 1: 1.12)
    "fitting_core_per_bladder_inner_diameter": (0.5, 2.0, False),
    "clamp_gap_per_wall": (0.0, 1.0, True),  # the clamp squeezes the wall: thinner, never thicker
    "clamp_length_per_bladder_outer_diameter": (0.0, 20.0, True),
    "swage_wall_per_bladder_outer_diameter": (0.0, 1.0, True),
    "thread_thickness": (0.0, 0.005, True),
    "cut_resolution": (0.0, 0.01, True),
    # an EFAM's sleeve is gathered: at 45 deg at least as long as the muscle (Sec. 2)
    "max_gather_ratio": (1.0, 50.0, False),
    "min_aspect_ratio": (0.0, 100.0, True),
    # Euler's effective-length factor: 0.5 (both ends fixed) .. 2 (one end free)
    "euler_length_factor": (0.5, 2.0, False),
}
#: A sleeve's reference diameter (D_45) lies in its diameter range: the braid passes through 45 deg
#: as it opens from ``min_diameter`` to ``max_diameter``. It may lie this factor outside, as the
#: range is a maker's listing or what a paper evidences and D_45 a convention (the paper's Kevlar
#: sleeve: D_45 1.905 cm by the project's convention, drawn tight on 2.22 cm, 0.86 x its range's
#: low end); a length-unit mix-up moves it by 2.54 x (in/cm) or more, beyond this factor.
REFERENCE_DIAMETER_SLACK = 1.25
#: How a quantity is shown in messages: (unit, factor from SI).
_SHOW = {"length": ("mm", 1e3), "pressure": ("kPa", 1e-3), "density": ("kg/m^3", 1.0), "": ("", 1.0)}


class CatalogueError(ValueError):
    """A catalogue file that cannot be used; the message names the file, entry and key."""


@dataclass(frozen=True)
class Sleeve:
    """A braided sleeve size. ``reference_diameter_m`` is its diameter at the reference braid angle
    (45 deg), the D_45 of Table 2; for sleeving sold by nominal size the project takes the nominal
    size (README, 'Inputs the paper does not state'). The sleeve fits a muscle when it can be
    drawn tight on the bladder (``min_diameter_m`` <= tube outer diameter) and open to the cycled
    muscle's resting diameter (<= ``max_diameter_m``)."""

    name: str
    material: str
    reference_diameter_m: float
    min_diameter_m: float
    max_diameter_m: float
    thickness_m: float
    fibre_fraction: float
    density_kg_m3: float
    pressure_rating_Pa: float | None = None

    def mass_per_length_kg_m(self) -> float:
        """Mass of one metre of sleeve at its reference diameter (a tube of the braid's thickness
        holding ``fibre_fraction`` fibre)."""
        return (
            self.density_kg_m3 * self.fibre_fraction * math.pi * self.reference_diameter_m * self.thickness_m
        )


@dataclass(frozen=True)
class Tubing:
    """A latex tube size: the bladder (Table 2's D_B,IN and D_B,OUT)."""

    name: str
    inner_diameter_m: float
    outer_diameter_m: float
    pressure_rating_Pa: float | None = None

    @property
    def wall_m(self) -> float:
        """Wall thickness of the tubing (m)."""
        return (self.outer_diameter_m - self.inner_diameter_m) / 2

    @property
    def section_m2(self) -> float:
        """Cross-section area of the tubing wall (m^2)."""
        return math.pi / 4 * (self.outer_diameter_m**2 - self.inner_diameter_m**2)


@dataclass(frozen=True)
class Rules:
    """How parts become a muscle, scaled from the paper's FAM1/FAM2 (docs/sizing.md)."""

    length_growth: float  # resting length over the working bladder length, minus one (Sec. 4.2)
    length_growth_spread: float  # half the FAM1-FAM2 difference: the rule's uncertainty
    diameter_growth: float  # resting diameter over the tube's outer diameter, minus one (Sec. 4.2)
    fitting_core_per_bladder_inner_diameter: float  # Table 1: 2.133 cm core on a 1.9 cm bore
    clamp_gap_per_wall: float  # squeezed bladder wall in the channel per tube wall (FAM1)
    clamp_length_per_bladder_outer_diameter: float  # Table 1: 2.54 cm on a 2.22 cm tube
    swage_wall_per_bladder_outer_diameter: float  # Table 1: swage tube 0.884 in bore, 1 in outside
    thread_thickness_m: float  # t_TH (README: 0.1524 mm)
    aluminium_density_kg_m3: float
    cut_resolution_m: float  # sleeve and tube are cut to this; L_45 rounds up, L_B to nearest
    max_gather_ratio: float  # sleeve length at 45 deg over resting length, at most
    min_aspect_ratio: float  # resting length over resting diameter, at least
    euler_length_factor: float  # K in P_cr = pi^2 EI / (K L)^2 (1: both ends pinned)
    max_pressure_Pa: float  # the largest pressure budget the sizing accepts


@dataclass(frozen=True)
class Latex:
    """The bladder material's limits (a supplier's specification sheet)."""

    elongation_at_break: float  # as a strain (7.5 = 750 %)
    density_kg_m3: float
    strain_safety_factor: float

    @property
    def strain_limit(self) -> float:
        """Largest admissible bladder strain: elongation at break over the safety factor."""
        return self.elongation_at_break / self.strain_safety_factor


@dataclass(frozen=True)
class Catalogue:
    sleeves: tuple[Sleeve, ...]
    tubings: tuple[Tubing, ...]
    latex: Latex
    rules: Rules
    sources: dict
    label: str = "built-in catalogue"


def _in_range(value: float, block: dict, base: str, where: str, kind: str, quantity: str = "") -> float:
    """``value`` (SI) when inside ``RANGES[kind]``, else an error naming the entry, the key as the
    file wrote it, the value in a readable unit and the range."""
    lo, hi, low_open = RANGES[kind]
    if (lo < value if low_open else lo <= value) and value <= hi:
        return value
    key = base if base in block else next((k for k in block if split_unit(k)[0] == base), base)
    unit, scale = _SHOW[quantity]
    u = f" {unit}" if unit else ""
    shown = f" ({value * scale:g}{u})" if quantity in ("length", "pressure") else ""
    bracket = "(" if low_open else "["
    hint = (
        "; a fraction, not a percentage" if kind in ("fraction", "elongation_at_break") and value > 1 else ""
    )
    if quantity == "length" and lo > 0:  # the length unit under which the number would fit
        hint = was_it_in(unit_that_fits(value, math.sqrt(lo * hi), key, LENGTH, within=(lo, hi))) or hint
    raise CatalogueError(
        f"{where}: key '{key}' = {block.get(key)!r}{shown} is outside the physical range "
        f"{bracket}{lo * scale:g}, {hi * scale:g}]{u}{hint}"
    )


def _number(block: dict, key: str, where: str, kind: str | None = None) -> float:
    if key not in block:
        raise CatalogueError(f"{where}: missing key '{key}'")
    value = block.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CatalogueError(f"{where}: key '{key}' must be a finite number, got {json_shown(value)}")
    quantity = "density" if kind == "density" else ""
    return _in_range(float(value), block, key, where, kind or key, quantity)


def _quantity(block: dict, base: str, where: str, quantity: str, kind: str, default=...):
    """``<base>_<unit>`` of ``block`` in SI (``quantity``: "length" or "pressure"), inside
    ``RANGES[kind]``; ``default`` when absent (required when not given)."""
    try:
        if default is ...:
            value = read_quantity(block, base, quantity, where)
        else:
            value = read_quantity(block, base, quantity, where, default=default)
    except UnitError as err:
        raise CatalogueError(str(err)) from None
    return None if value is None else _in_range(value, block, base, where, kind, quantity)


def _length(block: dict, base: str, where: str, kind: str, default=...):
    return _quantity(block, base, where, "length", kind, default)


def _pressure(block: dict, base: str, where: str, default=...):
    return _quantity(block, base, where, "pressure", "pressure", default)


def _rating(block: dict, where: str):
    return _pressure(block, "pressure_rating", where, default=None)


def _entries(doc: dict, key: str, label: str) -> list:
    entries = doc[key]
    if not isinstance(entries, list) or not entries:
        raise CatalogueError(f"{label}: '{key}' must be a non-empty list of entries")
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise CatalogueError(f"{label}: {key}[{i}] must be a JSON object")
    return entries


def _where(label: str, key: str, i: int, entry: dict) -> str:
    name = entry.get("name")
    # else _name refuses it (a control or format character, Unicode category C; a no-break space is fine)
    shown = isinstance(name, str) and name.strip() and not any(map(is_control, name))
    return f"{label}: {key}[{i}]" + (f" ('{name}')" if shown else "")


def _name(entry: dict, where: str) -> str:
    """The entry's ``name`` (``where`` when it has none). A design names its parts by it in tables
    and JSON, so it must be visible text: a blank name cannot be told apart, and control characters
    (a terminal escape sequence) would reach the user's screen as they are."""
    if "name" not in entry:
        return where
    name = entry["name"]
    if not isinstance(name, str) or not name.strip() or any(map(is_control, name)):
        raise CatalogueError(
            f"{where}: key 'name' must be non-blank text without control characters, got {name!r}"
        )
    return name


def _known_keys(block: dict, plain: tuple, bases: tuple, where: str) -> None:
    """Every key of ``block`` is one of ``plain`` or ``<base>_<unit>`` for one of ``bases``: a
    misspelled key (``fibre_fracton``) is an error naming it, never ignored (as in muscle files)."""
    for key in block:
        if key in plain or key in bases:  # a base without its unit: read_quantity says "has no unit"
            continue
        base, unit = split_unit(key)
        if unit and base in bases:
            continue
        known = ", ".join([*plain, *(f"{b}_<unit>" for b in bases)])
        raise CatalogueError(f"{where}: unknown key '{key}' (known: {known})")


_SLEEVE_KEYS = (("name", "material", "note", "fibre_fraction", "density_kg_per_m3"),
                ("reference_diameter", "min_diameter", "max_diameter", "thickness", "pressure_rating"))  # fmt: skip
_TUBING_KEYS = (("name", "note"), ("inner_diameter", "wall", "outer_diameter", "pressure_rating"))
_LATEX_KEYS = (("elongation_at_break", "density_kg_per_m3", "strain_safety_factor"), ())
_RULES_KEYS = (
    ("length_growth", "length_growth_spread", "diameter_growth", "fitting_core_per_bladder_inner_diameter",
     "clamp_gap_per_wall", "clamp_length_per_bladder_outer_diameter", "swage_wall_per_bladder_outer_diameter",
     "aluminium_density_kg_per_m3", "max_gather_ratio", "min_aspect_ratio", "euler_length_factor"),
    ("thread_thickness", "cut_resolution", "max_pressure"),
)  # fmt: skip
_TOP_KEYS = ("format", "description", "sources", "sleeves", "tubings", "latex", "rules")


def _sleeve(entry: dict, where: str) -> Sleeve:
    _known_keys(entry, *_SLEEVE_KEYS, where)
    sleeve = Sleeve(
        name=_name(entry, where),
        material=str(entry.get("material", "")),
        reference_diameter_m=_length(entry, "reference_diameter", where, "diameter"),
        min_diameter_m=_length(entry, "min_diameter", where, "diameter"),
        max_diameter_m=_length(entry, "max_diameter", where, "diameter"),
        thickness_m=_length(entry, "thickness", where, "thickness"),
        fibre_fraction=_number(entry, "fibre_fraction", where, "fraction"),
        density_kg_m3=_number(entry, "density_kg_per_m3", where, "density"),
        pressure_rating_Pa=_rating(entry, where),
    )
    if not sleeve.min_diameter_m <= sleeve.max_diameter_m:
        raise CatalogueError(f"{where}: min_diameter is above max_diameter")
    low = sleeve.min_diameter_m / REFERENCE_DIAMETER_SLACK
    high = sleeve.max_diameter_m * REFERENCE_DIAMETER_SLACK
    if not low <= sleeve.reference_diameter_m <= high:
        keys = [next((k for k in entry if split_unit(k)[0] == base), base)
                for base in ("reference_diameter", "min_diameter", "max_diameter")]  # fmt: skip
        raise CatalogueError(
            f"{where}: key '{keys[0]}' = {entry.get(keys[0])!r} ({sleeve.reference_diameter_m * 1e3:g} mm) lies "
            f"outside the sleeve's diameter range '{keys[1]}' .. '{keys[2]}' ({sleeve.min_diameter_m * 1e3:g} .. "
            f"{sleeve.max_diameter_m * 1e3:g} mm, give or take {REFERENCE_DIAMETER_SLACK:g} x): the sleeve "
            "passes through its reference diameter as it opens, so it lies in that range (another unit?)"
        )
    return sleeve


def _tubing(entry: dict, where: str) -> Tubing:
    _known_keys(entry, *_TUBING_KEYS, where)
    inner = _length(entry, "inner_diameter", where, "diameter")
    wall = _length(entry, "wall", where, "wall", default=None)
    outer = _length(entry, "outer_diameter", where, "diameter", default=None)
    if (wall is None) == (outer is None):
        raise CatalogueError(f"{where}: give exactly one of 'wall_<unit>' and 'outer_diameter_<unit>'")
    outer = inner + 2 * wall if outer is None else outer
    if not outer - inner >= 2 * MIN_WALL_M:
        raise CatalogueError(
            f"{where}: the outer diameter ({outer * 1e3:g} mm) must exceed the inner diameter "
            f"({inner * 1e3:g} mm) by twice the thinnest wall ({MIN_WALL_M * 1e3:g} mm)"
        )
    return Tubing(_name(entry, where), inner, outer, _rating(entry, where))


def load_catalogue(path: str | Path | None = None) -> Catalogue:
    """The built-in catalogue, or a user's file with the same layout (errors name entry and key)."""
    if path is None:
        data = resources.files("efam_mujoco.size").joinpath("catalogue.json").read_bytes()
        label = "built-in catalogue"
    else:
        if not Path(path).exists() and not Path(path).is_symlink():
            raise CatalogueError(f"catalogue file '{path}' does not exist")
        try:  # a folder, a pipe, /dev/zero or a huge file is refused, never read (musclefile's rule)
            data, label = read_small_file(path, "a catalogue file")
        except MuscleFileError as err:
            raise CatalogueError(str(err)) from None
    try:  # the muscle files' reader: UTF-8, strict JSON, errors with line and column
        doc = parse_json_text(data, label)
    except MuscleFileError as err:
        raise CatalogueError(str(err)) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CatalogueError(f"{label}: key 'format' must be '{FORMAT}'")
    for key in ("sleeves", "tubings", "latex", "rules"):
        if key not in doc:
            raise CatalogueError(f"{label}: missing key '{key}'")
    _known_keys(doc, _TOP_KEYS, (), label)
    for key in ("latex", "rules", "sources"):  # 'sources' is optional, and an object when given
        if key in doc and not isinstance(doc[key], dict):
            raise CatalogueError(f"{label}: '{key}' must be a JSON object")
    _known_keys(doc["latex"], *_LATEX_KEYS, f"{label}: latex")
    _known_keys(doc["rules"], *_RULES_KEYS, f"{label}: rules")
    sleeves = tuple(
        _sleeve(e, _where(label, "sleeves", i, e)) for i, e in enumerate(_entries(doc, "sleeves", label))
    )
    tubings = tuple(
        _tubing(e, _where(label, "tubings", i, e)) for i, e in enumerate(_entries(doc, "tubings", label))
    )
    for key, entries in (("sleeves", sleeves), ("tubings", tubings)):
        names = [e.name for e in entries]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:  # a design names its parts: two of one name could not be told apart
            raise CatalogueError(
                f"{label}: {key}: the name '{twice[0]}' is given to {names.count(twice[0])} entries"
            )
    lx, where = doc["latex"], f"{label}: latex"
    latex = Latex(
        _number(lx, "elongation_at_break", where),
        _number(lx, "density_kg_per_m3", where, "density"),
        _number(lx, "strain_safety_factor", where),
    )
    r, where = doc["rules"], f"{label}: rules"
    rules = Rules(
        length_growth=_number(r, "length_growth", where),
        length_growth_spread=_number(r, "length_growth_spread", where),
        diameter_growth=_number(r, "diameter_growth", where),
        fitting_core_per_bladder_inner_diameter=_number(r, "fitting_core_per_bladder_inner_diameter", where),
        clamp_gap_per_wall=_number(r, "clamp_gap_per_wall", where),
        clamp_length_per_bladder_outer_diameter=_number(r, "clamp_length_per_bladder_outer_diameter", where),
        swage_wall_per_bladder_outer_diameter=_number(r, "swage_wall_per_bladder_outer_diameter", where),
        thread_thickness_m=_length(r, "thread_thickness", where, "thread_thickness"),
        aluminium_density_kg_m3=_number(r, "aluminium_density_kg_per_m3", where, "density"),
        cut_resolution_m=_length(r, "cut_resolution", where, "cut_resolution"),
        max_gather_ratio=_number(r, "max_gather_ratio", where),
        min_aspect_ratio=_number(r, "min_aspect_ratio", where),
        euler_length_factor=_number(r, "euler_length_factor", where),
        max_pressure_Pa=_pressure(r, "max_pressure", where),
    )
    return Catalogue(sleeves, tubings, latex, rules, dict(doc.get("sources", {})), label)
