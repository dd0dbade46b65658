"""The named constraints a design must meet, each with its value, limit and margin.

Definitions (docs/sizing.md has the derivations)::

    ``force_at_stroke``  push(P, L_rest (1 + stroke)) >= force: the muscle, extended by the stroke at
                         the pressure, still pushes the required force. With force 0 this is a free
                         stroke, and the margin is in stroke: free_stroke / stroke - 1.
    ``blocked_force``    push(P, L_rest) (Eq. 9) >= the requested blocked force (when one is asked).
    ``length_range``     the required length and the free length at P lie inside the model's
                         admissible range (threads inextensible, bladder fits: ``Muscle.max_length_m``),
                         and L_rest >= min_aspect_ratio x D_rest (shorter muscles are mostly end region).
    ``bladder_strain``   the largest |strain| (Eqs. 12-13) between rest and the longest length in
                         service <= latex elongation at break / safety factor.
    ``pressure_rating``  P <= the lowest known rating of the parts (n/a where none is known).
    ``drucker``          d sigma/d eps > 0 over the design's strain range, at P = 0 (the worst).
    ``buckling``         unguided: blocked force <= Euler load pi^2 E I / (K L_rest)^2, E the law's
                         tangent modulus at zero strain and P, I the bladder wall's (n/a when guided).
    ``sleeve_fit``       sleeve min diameter <= tube outer diameter, resting diameter <= sleeve max.
    ``sleeve_gather``    L_45 / L_rest <= max_gather_ratio (the sleeve that must be gathered on).
    ``max_diameter``     D_rest <= the requested maximum (when one is asked).

A margin is (capacity - demand) / demand: positive passes. A constraint without a requirement
reports its value with status ``n/a``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ..muscle import Geometry, Muscle
from .catalogue import Catalogue, Sleeve, Tubing
from .request import Request

OK, FAIL, NA = "ok", "fail", "n/a"


@dataclass(frozen=True)
class Check:
    """One named constraint: its value, limit (unit), margin and status (ok / fail / n/a)."""

    name: str
    status: str
    value: float
    limit: float | None
    unit: str
    margin: float | None
    note: str = ""

    @property
    def passed(self) -> bool:
        """Whether the check holds (a warning counts as passed)."""
        return self.status != FAIL

    def to_dict(self) -> dict:
        """The check as plain JSON types."""
        return {
            "status": self.status,
            "value": self.value,
            "limit": self.limit,
            "unit": self.unit,
            "margin": self.margin,
            "note": self.note,
        }


def _check(name, value, limit, unit, upper: bool, note="") -> Check:
    """``upper``: value must stay below limit; else value must reach limit."""
    if limit is None:
        return Check(name, NA, float(value), None, unit, None, note)
    margin = (limit / value - 1.0 if value > 0 else math.inf) if upper else value / limit - 1.0
    return Check(name, OK if margin >= 0 else FAIL, float(value), float(limit), unit, float(margin), note)


@dataclass(frozen=True)
class Performance:
    """What a muscle does at the request's pressure (push positive, strokes as fractions)."""

    force_at_stroke_N: float
    blocked_force_N: float
    free_stroke: float
    stroke_at_force: float  # extension while pushing the requested force (= free stroke at 0 N)
    max_strain: float
    euler_load_N: float


def stroke_at_force(muscle: Muscle, pressure_Pa: float, force_N: float, free_length: float) -> float:
    """Extension at which the muscle pushes exactly ``force_N`` (0 when it cannot even at rest)."""
    rest = muscle.rest_length_m
    if force_N <= 0:
        return free_length / rest - 1.0
    if muscle.push(pressure_Pa, rest) <= force_N:
        return 0.0
    if muscle.push(pressure_Pa, free_length) >= force_N:
        # a force within the rounding of the free length's zero (--force 5e-324): the free
        # stroke, where the root search found no sign change and said so in scipy's words
        return free_length / rest - 1.0
    length = brentq(lambda L: muscle.push(pressure_Pa, L) - force_N, rest, free_length, xtol=1e-12)
    return length / rest - 1.0


def euler_load(muscle: Muscle, pressure_Pa: float, length_factor: float) -> float:
    """Euler load of the muscle as a column: the bladder wall (tangent modulus of the law at zero
    strain and this pressure) is the only bending stiffness; the braid, near-circumferential at
    an EFAM's braid angle, adds little (a documented estimate)."""
    r_out = muscle.rest_outer_radius_m
    r_in = r_out - muscle.rest_wall_thickness_m
    inertia = math.pi / 4 * (r_out**4 - r_in**4)
    modulus = float(muscle.stress.slope(0.0, pressure_Pa))
    return math.pi**2 * modulus * inertia / (length_factor * muscle.rest_length_m) ** 2


def performance(muscle: Muscle, request: Request, catalogue: Catalogue) -> Performance:
    """What the muscle delivers for the request: forces at the required stroke, blocked force, free stroke and strain range."""
    P = request.pressure_Pa
    rest = muscle.rest_length_m
    free = float(muscle.free_length(P))
    top = max(free, rest * (1 + request.stroke))
    lengths = np.linspace(rest, min(top, muscle.max_length_m), 41)
    ez, ec = muscle.strains(lengths)
    return Performance(
        force_at_stroke_N=float(muscle.push(P, rest * (1 + request.stroke))),
        blocked_force_N=float(muscle.blocked_push(P)),
        free_stroke=free / rest - 1.0,
        stroke_at_force=stroke_at_force(muscle, P, request.muscle_force_N, free),
        max_strain=float(max(np.abs(ez).max(), np.abs(ec).max())),
        euler_load_N=euler_load(muscle, P, catalogue.rules.euler_length_factor),
    )


def evaluate(
    muscle: Muscle,
    geometry: Geometry | None,
    tubing: Tubing,
    sleeve: Sleeve | None,
    request: Request,
    catalogue: Catalogue,
    perf: Performance | None = None,
) -> tuple[tuple[Check, ...], Performance]:
    """Every named constraint of a design (``sleeve``/``geometry`` None: the sleeve-free checks)."""
    perf = perf or performance(muscle, request, catalogue)
    rules, P = catalogue.rules, request.pressure_Pa
    checks = []
    F = request.muscle_force_N
    if F > 0:
        checks.append(_check("force_at_stroke", perf.force_at_stroke_N, F, "N", upper=False))
    else:
        checks.append(
            _check(
                "force_at_stroke", perf.free_stroke, request.stroke, "stroke", upper=False, note="free stroke"
            )
        )
    checks.append(
        _check("blocked_force", perf.blocked_force_N, request.muscle_blocked_force_N, "N", upper=False)
    )
    rest = muscle.rest_length_m
    longest = max(rest * (1 + request.stroke), rest * (1 + perf.free_stroke))
    aspect = rest / muscle.rest_diameter_m
    note = f"admissible {muscle.min_length_m * 1e3:.1f}-{muscle.max_length_m * 1e3:.1f} mm; L/D {aspect:.2f}"
    length = _check("length_range", longest, muscle.max_length_m, "m", upper=True, note=note)
    if aspect < rules.min_aspect_ratio:
        note += f" < {rules.min_aspect_ratio:g}"
        length = Check(
            "length_range", FAIL, length.value, length.limit, "m", aspect / rules.min_aspect_ratio - 1, note
        )
    checks.append(length)
    checks.append(_check("bladder_strain", perf.max_strain, catalogue.latex.strain_limit, "strain", upper=True,
                         note=f"elongation at break {catalogue.latex.elongation_at_break:g} / safety factor "
                         f"{catalogue.latex.strain_safety_factor:g}"))  # fmt: skip
    ratings = [r for r in (tubing.pressure_rating_Pa, sleeve.pressure_rating_Pa if sleeve else None) if r]
    rating_note = "" if ratings else "no rating known for these parts"
    checks.append(
        _check("pressure_rating", P, min(ratings) if ratings else None, "Pa", upper=True, note=rating_note)
    )
    ez, ec = muscle.strains(np.linspace(rest, min(longest, muscle.max_length_m), 41))
    lo, hi = float(min(ez.min(), ec.min())), float(max(ez.max(), ec.max()))
    slope = muscle.stress.min_slope(lo, hi)
    zero = float(muscle.stress.slope(0.0, 0.0))
    checks.append(Check("drucker", OK if slope > 0 else FAIL, slope, 0.0, "Pa", slope / zero,
                        note=f"min d sigma/d eps over strains [{lo:.3g}, {hi:.3g}] at P = 0"))  # fmt: skip
    if request.bundle:
        checks.append(
            Check("buckling", NA, perf.euler_load_N, None, "N", None, "guided by the section's disks")
        )
    elif request.unguided:
        checks.append(
            _check(
                "buckling", perf.blocked_force_N, perf.euler_load_N, "N", upper=True, note="Euler, unguided"
            )
        )
    else:
        checks.append(Check("buckling", NA, perf.euler_load_N, None, "N", None,
                            f"guided (a tube, as the paper's test); unguided it buckles above {perf.euler_load_N:.1f} N"))  # fmt: skip
    if sleeve is not None:
        tight = tubing.outer_diameter_m / sleeve.min_diameter_m - 1
        opens = sleeve.max_diameter_m / muscle.rest_diameter_m - 1
        margin = min(tight, opens)
        note = (f"sleeve {sleeve.min_diameter_m * 1e3:.1f}-{sleeve.max_diameter_m * 1e3:.1f} mm, "
                f"tube {tubing.outer_diameter_m * 1e3:.1f} mm, rest {muscle.rest_diameter_m * 1e3:.1f} mm")  # fmt: skip
        checks.append(Check("sleeve_fit", OK if margin >= 0 else FAIL, margin, 0.0, "", margin, note))
    if geometry is not None:
        gather = geometry.sleeve_length_ref_m / geometry.rest_length_m
        checks.append(_check("sleeve_gather", gather, rules.max_gather_ratio, "", upper=True))
    checks.append(_check("max_diameter", muscle.rest_diameter_m, request.max_diameter_m, "m", upper=True))
    return tuple(checks), perf


def binding(checks) -> Check | None:
    """The applicable check with the smallest margin (the one that limits the design)."""
    live = [c for c in checks if c.margin is not None and c.status != NA]
    return min(live, key=lambda c: c.margin) if live else None
