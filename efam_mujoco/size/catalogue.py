"""The parts catalogue (``catalogue.json``): braided sleeves and latex tubes as sold, the bladder
material's limits, and the manufacturing rules that turn a set of parts into a muscle.

Every number in the file carries its unit in its key (``reference_diameter_in``, ``wall_cm``);
inside, everything is SI. The sources are written in the file's ``sources`` block and in
docs/sizing.md. A user can pass their own file with the same layout (``efam size --catalogue``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ..units import UnitError, read_quantity

FORMAT = "efam_mujoco.catalogue/1"


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


def _number(block: dict, key: str, where: str, positive: bool = True) -> float:
    value = block.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CatalogueError(f"{where}: key '{key}' must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise CatalogueError(f"{where}: key '{key}' must be positive, got {value!r}")
    return float(value)


def _length(block: dict, base: str, where: str, default=...):
    try:
        if default is ...:
            value = read_quantity(block, base, "length", where)
        else:
            value = read_quantity(block, base, "length", where, default=default)
    except UnitError as err:
        raise CatalogueError(str(err)) from None
    if value is not None and not value > 0:
        raise CatalogueError(f"{where}: '{base}' must be positive")
    return value


def _rating(block: dict, where: str):
    try:
        return read_quantity(block, "pressure_rating", "pressure", where, default=None)
    except UnitError as err:
        raise CatalogueError(str(err)) from None


def _sleeve(entry: dict, where: str) -> Sleeve:
    sleeve = Sleeve(
        name=str(entry.get("name", where)),
        material=str(entry.get("material", "")),
        reference_diameter_m=_length(entry, "reference_diameter", where),
        min_diameter_m=_length(entry, "min_diameter", where),
        max_diameter_m=_length(entry, "max_diameter", where),
        thickness_m=_length(entry, "thickness", where),
        fibre_fraction=_number(entry, "fibre_fraction", where),
        density_kg_m3=_number(entry, "density_kg_per_m3", where),
        pressure_rating_Pa=_rating(entry, where),
    )
    if not sleeve.min_diameter_m <= sleeve.max_diameter_m:
        raise CatalogueError(f"{where}: min_diameter is above max_diameter")
    return sleeve


def _tubing(entry: dict, where: str) -> Tubing:
    inner = _length(entry, "inner_diameter", where)
    wall = _length(entry, "wall", where, default=None)
    outer = _length(entry, "outer_diameter", where, default=None)
    if (wall is None) == (outer is None):
        raise CatalogueError(f"{where}: give exactly one of 'wall_<unit>' and 'outer_diameter_<unit>'")
    outer = inner + 2 * wall if outer is None else outer
    if not outer > inner:
        raise CatalogueError(f"{where}: outer diameter must exceed the inner diameter")
    return Tubing(str(entry.get("name", where)), inner, outer, _rating(entry, where))


def load_catalogue(path: str | Path | None = None) -> Catalogue:
    """The built-in catalogue, or a user's file with the same layout (errors name entry and key)."""
    if path is None:
        text = resources.files("efam_mujoco.size").joinpath("catalogue.json").read_text()
        label = "built-in catalogue"
    else:
        p = Path(path)
        if not p.is_file():
            raise CatalogueError(f"catalogue file '{path}' does not exist")
        text, label = p.read_text(), str(p)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise CatalogueError(f"{label}: not valid JSON ({err})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CatalogueError(f"{label}: key 'format' must be '{FORMAT}'")
    for key in ("sleeves", "tubings", "latex", "rules"):
        if key not in doc:
            raise CatalogueError(f"{label}: missing key '{key}'")
    if not doc["sleeves"] or not doc["tubings"]:
        raise CatalogueError(f"{label}: 'sleeves' and 'tubings' must not be empty")
    sleeves = tuple(_sleeve(e, f"{label}: sleeves[{i}]") for i, e in enumerate(doc["sleeves"]))
    tubings = tuple(_tubing(e, f"{label}: tubings[{i}]") for i, e in enumerate(doc["tubings"]))
    lx, where = doc["latex"], f"{label}: latex"
    latex = Latex(
        _number(lx, "elongation_at_break", where),
        _number(lx, "density_kg_per_m3", where),
        _number(lx, "strain_safety_factor", where),
    )
    r, where = doc["rules"], f"{label}: rules"
    try:
        max_pressure = read_quantity(r, "max_pressure", "pressure", where)
    except UnitError as err:
        raise CatalogueError(str(err)) from None
    rules = Rules(
        length_growth=_number(r, "length_growth", where, positive=False),
        length_growth_spread=_number(r, "length_growth_spread", where, positive=False),
        diameter_growth=_number(r, "diameter_growth", where, positive=False),
        fitting_core_per_bladder_inner_diameter=_number(r, "fitting_core_per_bladder_inner_diameter", where),
        clamp_gap_per_wall=_number(r, "clamp_gap_per_wall", where),
        clamp_length_per_bladder_outer_diameter=_number(r, "clamp_length_per_bladder_outer_diameter", where),
        swage_wall_per_bladder_outer_diameter=_number(r, "swage_wall_per_bladder_outer_diameter", where),
        thread_thickness_m=_length(r, "thread_thickness", where),
        aluminium_density_kg_m3=_number(r, "aluminium_density_kg_per_m3", where),
        cut_resolution_m=_length(r, "cut_resolution", where),
        max_gather_ratio=_number(r, "max_gather_ratio", where),
        min_aspect_ratio=_number(r, "min_aspect_ratio", where),
        euler_length_factor=_number(r, "euler_length_factor", where),
        max_pressure_Pa=max_pressure,
    )
    return Catalogue(sleeves, tubings, latex, rules, dict(doc.get("sources", {})), label)
