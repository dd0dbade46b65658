"""From parts to a muscle: the manufacturing parameters of paper Table 2 for a sleeve, a tube, a
resting length and a braid angle, and the muscle they make.

The manufacturing model (docs/sizing.md), scaled from the paper's FAM1/FAM2:

* end fittings (Table 1) scale with the tube: core diameter = 1.1226 x tube bore, clamping
  channel outer diameter = core + 2 (t_TH + 0.256 x tube wall), channel length = 1.144 x tube
  outer diameter (for the paper's tube these give Table 1's 2.133 cm, 0.884 in and 2.54 cm);
* the finished, cycled muscle is longer than its working bladder and fatter than its tube
  (Sec. 4.2): L_rest = (1 + g_L)(L_B - Delta L_B,FIX), g_L = 4.5 % (FAM1 3.7 %, FAM2 5.39 %);
  D_rest = (1 + g_D) D_B,OUT, g_D = 29 % (both);
* the braid angle follows from the sleeve length cut at 45 deg (Eq. 5):
  L_45 = L_rest D_45 / (D_rest tan(theta_rest)).

With these rules a muscle's force at a given strain does not depend on its length (Eq. 2 scales:
B, N and V_B / L all follow L_rest), so length matters only for mass, buckling and fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..muscle import Geometry, Muscle
from ..musclefile import load_muscle
from ..stress import StressLaw
from .catalogue import Catalogue, Rules, Sleeve, Tubing


@dataclass(frozen=True)
class Material:
    """The bladder's stress law and the dead band, taken from a calibrated muscle (the default is
    the paper's FAM1 with its exponential-decay law, Table 4)."""

    stress: StressLaw
    deadband_Pa: float
    source: str

    @classmethod
    def from_muscle(cls, source: str = "FAM1", law: str | None = None) -> Material:
        """From a preset name or a muscle file (its default law unless ``law`` is given)."""
        muscle = load_muscle(source, law)
        return cls(muscle.stress, muscle.deadband_Pa, f"{muscle.name or source} ({muscle.stress.name} law)")


@dataclass(frozen=True)
class Fitting:
    """One end fitting's clamping channel and swage tube, from the tube (Table 1 scaled)."""

    core_diameter_m: float
    channel_outer_diameter_m: float
    length_m: float
    swage_outer_diameter_m: float


def fitting_for(tubing: Tubing, rules: Rules) -> Fitting:
    """The end fitting (channel and clamp length) that the manufacturing rules give for a tubing size."""
    core = rules.fitting_core_per_bladder_inner_diameter * tubing.inner_diameter_m
    channel = core + 2 * (rules.thread_thickness_m + rules.clamp_gap_per_wall * tubing.wall_m)
    length = rules.clamp_length_per_bladder_outer_diameter * tubing.outer_diameter_m
    swage = channel + 2 * rules.swage_wall_per_bladder_outer_diameter * tubing.outer_diameter_m
    return Fitting(core, channel, length, swage)


def rest_diameter(tubing: Tubing, rules: Rules) -> float:
    """The resting outer diameter of a muscle made from this tubing (bladder plus sleeve)."""
    return (1 + rules.diameter_growth) * tubing.outer_diameter_m


def length_lost(tubing: Tubing, rules: Rules) -> float:
    """Eqs. 6-7 for both fittings: the bladder length the fittings take, Delta L_B,FIX."""
    f = fitting_for(tubing, rules)
    r_out = f.channel_outer_diameter_m / 2 - rules.thread_thickness_m
    volume = 2 * math.pi * (r_out**2 - (f.core_diameter_m / 2) ** 2) * f.length_m
    return volume / tubing.section_m2


def _round_up(value: float, step: float) -> float:
    return math.ceil(value / step - 1e-9) * step


def _round(value: float, step: float) -> float:
    return round(value / step) * step


def geometry_for(
    tubing: Tubing,
    sleeve: Sleeve,
    rest_length_m: float,
    theta_deg: float,
    rules: Rules,
    cut: bool = True,
) -> Geometry:
    """Table 2's parameters for a target resting length and braid angle. With ``cut`` the bladder
    is cut to the nearest and the sleeve up to the next ``cut_resolution_m`` (a longer sleeve
    means a smaller angle: more force and stroke), and the resting length is what the cut bladder
    makes; without, the exact continuous values."""
    lost = length_lost(tubing, rules)
    d_rest = rest_diameter(tubing, rules)
    bladder = rest_length_m / (1 + rules.length_growth) + lost
    if cut:
        bladder = _round(bladder, rules.cut_resolution_m)
    rest = (1 + rules.length_growth) * (bladder - lost)
    sleeve_length = rest * sleeve.reference_diameter_m / (d_rest * math.tan(math.radians(theta_deg)))
    if cut:
        sleeve_length = _round_up(sleeve_length, rules.cut_resolution_m)
    fitting = fitting_for(tubing, rules)
    return Geometry(
        rest_length_m=rest,
        rest_diameter_m=d_rest,
        sleeve_length_ref_m=sleeve_length,
        sleeve_diameter_ref_m=sleeve.reference_diameter_m,
        bladder_length_m=bladder,
        bladder_inner_diameter_m=tubing.inner_diameter_m,
        bladder_outer_diameter_m=tubing.outer_diameter_m,
        clamp_length_m=fitting.length_m,
        clamp_inner_diameter_m=fitting.core_diameter_m,
        clamp_outer_diameter_m=fitting.channel_outer_diameter_m,
        thread_thickness_m=rules.thread_thickness_m,
    )


def muscle_for(geometry: Geometry, material: Material, name: str = "sized") -> Muscle:
    """The muscle Table 2's parameters make (Eqs. 3-8), with the material's law and dead band."""
    return Muscle.from_geometry(geometry, material.deadband_Pa, material.stress, name=name)


def fast_muscle(tubing: Tubing, rest_length_m: float, theta_deg: float, material: Material, rules: Rules):
    """The continuous (uncut) design's muscle straight from its constants: what the search
    evaluates many times (the same numbers :func:`geometry_for` with ``cut=False`` gives)."""
    # V_B = A_B (L_B - Delta L_B,FIX) = A_B L_rest / (1 + g_L): the fittings drop out
    volume = tubing.section_m2 * rest_length_m / (1 + rules.length_growth)
    return Muscle(
        rest_length_m=rest_length_m,
        rest_diameter_m=rest_diameter(tubing, rules),
        theta_rest_deg=theta_deg,
        bladder_volume_m3=volume,
        deadband_Pa=material.deadband_Pa,
        stress=material.stress,
    )


def part_masses(geometry: Geometry, tubing: Tubing, sleeve: Sleeve, catalogue: Catalogue) -> dict[str, float]:
    """Masses in kg: two fittings (solid aluminium core + swage tube), the bladder, the sleeve."""
    rules = catalogue.rules
    f = fitting_for(tubing, rules)
    al = rules.aluminium_density_kg_m3
    core = al * math.pi / 4 * f.core_diameter_m**2 * f.length_m
    swage = al * math.pi / 4 * (f.swage_outer_diameter_m**2 - f.channel_outer_diameter_m**2) * f.length_m
    return {
        "fittings_kg": 2 * (core + swage),
        "bladder_kg": catalogue.latex.density_kg_m3 * tubing.section_m2 * geometry.bladder_length_m,
        "sleeve_kg": sleeve.mass_per_length_kg_m() * geometry.sleeve_length_ref_m,
    }
