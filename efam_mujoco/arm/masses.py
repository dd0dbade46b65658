"""The arm's mass table: what the muscles' parts weigh (paper Table 1) and where the model puts it.

Per muscle, the end fittings and swage tubes sit on the plates at the muscle's two ends; the
latex bladder and the braided sleeve are spread along the muscle. The MuJoCo arm lumps the
spread part on its nodes (trapezoidal rule over the half-links, see ``builder``); the continuum
reference keeps it as a line density.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

DENSITY_KG_M3 = {
    "aluminium": 2700.0,
    "latex": 930.0,  # natural rubber latex
    "aramid": 1440.0,  # Kevlar 49 fibre
}
#: braided sleeve: fraction of the envelope (diameter x thickness x length) that is fibre. Not in
#: the paper; a biaxial braid of multi-filament yarns is about half fibre by volume.
SLEEVE_FIBRE_FRACTION = 0.5
SLEEVE_THICKNESS_M = 0.279e-3  # paper Sec. 2


@dataclass(frozen=True)
class MuscleParts:
    """The parts of one muscle (paper Table 1), SI. Defaults are the paper's FAM1/FAM2 parts."""

    fitting_length_m: float = 0.0254
    fitting_diameter_m: float = 0.02133
    swage_length_m: float = 0.0254
    swage_inner_diameter_m: float = 0.884 * 0.0254
    swage_outer_diameter_m: float = 0.0254
    bladder_length_m: float = 0.1778
    bladder_inner_diameter_m: float = 0.019
    bladder_outer_diameter_m: float = 0.0222
    sleeve_length_m: float = 0.508  # at 45 deg
    sleeve_diameter_m: float = 0.0222  # at 45 deg
    sleeve_thickness_m: float = SLEEVE_THICKNESS_M
    sleeve_fibre_fraction: float = SLEEVE_FIBRE_FRACTION


def _annulus_volume(length, inner_d, outer_d):
    return math.pi / 4 * (outer_d**2 - inner_d**2) * length


def muscle_part_masses(parts: MuscleParts = MuscleParts()) -> tuple[float, float]:
    """(mass at each end: end fitting + swage tube, mass along the muscle: bladder + sleeve), kg.

    End fittings are taken as solid aluminium cylinders (their fluid channel is not given), swage
    tubes as aluminium tubes, the bladder as a latex tube, the sleeve as an aramid tube of the
    sleeve's thickness holding ``sleeve_fibre_fraction`` fibre. The working fluid (air) is
    neglected.
    """
    al, latex, aramid = (DENSITY_KG_M3[k] for k in ("aluminium", "latex", "aramid"))
    fitting = al * math.pi / 4 * parts.fitting_diameter_m**2 * parts.fitting_length_m
    swage = al * _annulus_volume(
        parts.swage_length_m, parts.swage_inner_diameter_m, parts.swage_outer_diameter_m
    )
    bladder = latex * _annulus_volume(
        parts.bladder_length_m, parts.bladder_inner_diameter_m, parts.bladder_outer_diameter_m
    )
    sleeve = (
        aramid
        * parts.sleeve_fibre_fraction
        * math.pi
        * parts.sleeve_diameter_m
        * parts.sleeve_thickness_m
        * parts.sleeve_length_m
    )
    return fitting + swage, bladder + sleeve


FITTING_RADIUS_M = MuscleParts().fitting_diameter_m / 2
FITTING_LENGTH_M = MuscleParts().fitting_length_m
