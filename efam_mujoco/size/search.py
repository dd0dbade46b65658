"""The search: every catalogue tube, every sleeve that fits it, the braid angle that meets the
request; ranked designs (an infeasible request goes on to ``relax.py``).

Per tube the design has one free parameter, the resting braid angle (set by the sleeve length
cut at 45 deg). A smaller angle gives more force and more stroke, but more bladder strain, a
larger blocked force (buckling) and more sleeve to gather. So the search takes, per tube, the
largest angle that meets every requirement (the least sleeve, strain and buckling load), cuts
the parts to the catalogue's resolution, and checks every named constraint on the cut design.

Ranking: first how tightly a design meets the request (``excess``: the largest margin of the
requirements other than the binding one, at the exact angle; a design that overshoots one
requirement by 30 % is oversized for it), then mass.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import brentq

from ..muscle import NEUTRAL_BRAID_ANGLE_DEG, Geometry, Muscle, MuscleError
from ..stress import StressLawError
from . import constraints as con
from .catalogue import Catalogue, Sleeve, Tubing, load_catalogue
from .design import Material, fast_muscle, geometry_for, muscle_for, part_masses, rest_diameter
from .request import Request

#: the largest braid angle searched: just below the angle where an EFAM stops pushing
THETA_MAX_DEG = NEUTRAL_BRAID_ANGLE_DEG - 0.5
GRID = 16


@dataclass(frozen=True)
class Design:
    """One proposed muscle: its parts, Table 2 parameters, mass, constraints and performance."""

    tubing: Tubing
    sleeve: Sleeve
    geometry: Geometry
    muscle: Muscle
    masses: dict
    checks: tuple
    performance: con.Performance
    excess: float
    verification: object = None  # a verify.Verification once checked in MuJoCo

    @property
    def mass_kg(self) -> float:
        """Total mass of the muscle (kg): bladder, sleeve and fittings."""
        return sum(self.masses.values())

    @property
    def feasible(self) -> bool:
        """Whether every named constraint holds."""
        return all(c.passed for c in self.checks)

    @property
    def binding(self) -> con.Check | None:
        """The constraint with the smallest margin (None when there are no checks)."""
        return con.binding(self.checks)

    def to_dict(self) -> dict:
        """The design as plain JSON types: parts, Table 2 parameters, margins and masses."""
        g = self.geometry
        b = self.binding
        out = {
            "tubing": self.tubing.name,
            "sleeve": self.sleeve.name,
            "manufacturing": {
                "sleeve_length_45deg_m": g.sleeve_length_ref_m,
                "sleeve_diameter_45deg_m": g.sleeve_diameter_ref_m,
                "bladder_length_m": g.bladder_length_m,
                "bladder_inner_diameter_m": g.bladder_inner_diameter_m,
                "bladder_outer_diameter_m": g.bladder_outer_diameter_m,
                "clamp_length_m": g.clamp_length_m,
                "clamp_inner_diameter_m": g.clamp_inner_diameter_m,
                "clamp_outer_diameter_m": g.clamp_outer_diameter_m,
                "thread_thickness_m": g.thread_thickness_m,
                "rest_length_m": g.rest_length_m,
                "rest_diameter_m": g.rest_diameter_m,
            },
            "theta_rest_deg": self.muscle.theta_rest_deg,
            "bladder_volume_m3": self.muscle.bladder_volume_m3,
            "mass_kg": self.mass_kg,
            "masses_kg": {k.removesuffix("_kg"): v for k, v in self.masses.items()},
            "excess": self.excess,
            "binding": b.name if b else None,
            "performance": {
                "force_at_stroke_N": self.performance.force_at_stroke_N,
                "blocked_force_N": self.performance.blocked_force_N,
                "free_stroke": self.performance.free_stroke,
                "stroke_at_force": self.performance.stroke_at_force,
                "max_strain": self.performance.max_strain,
                "euler_load_N": self.performance.euler_load_N,
            },
            "constraints": {c.name: c.to_dict() for c in self.checks},
        }
        if self.verification is not None:
            out["verification"] = self.verification.to_dict()
        return out


@dataclass(frozen=True)
class SizingResult:
    request: Request
    material: Material
    designs: tuple  # feasible, ranked, best first
    closest: object  # a relax.ClosestPoint when infeasible
    relax: tuple
    candidates: int  # (tube, sleeve) pairs that fit, searched
    seconds: float
    catalogue: str
    notes: tuple = field(default_factory=tuple)
    bundle: object = None  # a bundle.BundleReport for a bundle request

    @property
    def feasible(self) -> bool:
        """Whether at least one design meets every requirement."""
        return bool(self.designs)

    @property
    def best(self) -> Design | None:
        """The best-ranked feasible design, or None."""
        return self.designs[0] if self.designs else None

    def to_dict(self, top: int | None = None) -> dict:
        """JSON-ready (non-finite numbers as null); ``top``: the designs proposed."""
        return _finite(self._dict(top))

    def _dict(self, top: int | None) -> dict:
        r = self.request
        return {
            "request": {
                "stroke": r.stroke, "force_N": r.force_N, "pressure_kPa": r.pressure_Pa / 1e3,
                "length_m": r.length_m, "max_diameter_m": r.max_diameter_m, "blocked_force_N": r.blocked_force_N,
                "bundle": r.bundle, "payload_kg": r.payload_kg, "unguided": r.unguided,
            },
            "material": self.material.source,
            "catalogue": self.catalogue,
            "feasible": self.feasible,
            "feasible_designs": len(self.designs),
            "designs": [d.to_dict() for d in self.designs[:top]],
            "closest": self.closest.to_dict() if self.closest else None,
            "relax": [x.to_dict() for x in self.relax],
            "candidates": self.candidates,
            "seconds": self.seconds,
            "notes": list(self.notes),
            "bundle": self.bundle.to_dict() if self.bundle is not None else None,
        }  # fmt: skip


def _finite(value):
    """NaN and infinities become None, so the JSON stays standard."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


# --------------------------------------------------------------------------------- search


def _rest_length(request: Request, tubing: Tubing, catalogue: Catalogue) -> float:
    """The requested resting length, or the shortest the aspect-ratio rule allows (one cut step
    longer, so that cutting the bladder to the nearest step cannot land below it)."""
    if request.length_m is not None:
        return request.length_m
    rules = catalogue.rules
    return (
        rules.min_aspect_ratio * rest_diameter(tubing, rules)
        + (1 + rules.length_growth) * rules.cut_resolution_m
    )


def _fits(sleeve: Sleeve, tubing: Tubing, catalogue: Catalogue) -> bool:
    return (
        sleeve.min_diameter_m <= tubing.outer_diameter_m
        and rest_diameter(tubing, catalogue.rules) <= sleeve.max_diameter_m
    )


def _safe_muscle(tubing, rest, theta, material, rules) -> Muscle | None:
    try:
        return fast_muscle(tubing, rest, theta, material, rules)
    except (MuscleError, StressLawError):
        return None


def _requirements(muscle: Muscle, request: Request, exact: bool = False) -> dict[str, float]:
    """Margin of each requirement (>= 0 met) of a muscle. A free stroke is met when the muscle
    still pushes at the stroke (push falls with length); ``exact`` gives its margin in stroke,
    which needs the free length (a root find, the search's slowest step)."""
    P, rest = request.pressure_Pa, muscle.rest_length_m
    out = {}
    F = request.muscle_force_N
    if F > 0:
        out["force"] = float(muscle.push(P, rest * (1 + request.stroke))) / F - 1
    elif exact:
        out["stroke"] = float(muscle.free_extension(P)) / request.stroke - 1
    else:
        scale = max(abs(float(muscle.blocked_push(P))), 1e-9)
        out["stroke"] = float(muscle.push(P, rest * (1 + request.stroke))) / scale
    if request.muscle_blocked_force_N:
        out["blocked"] = float(muscle.blocked_push(P)) / request.muscle_blocked_force_N - 1
    return out


def _theta_floor(tubing: Tubing, sleeves, rest_length_m: float, catalogue: Catalogue) -> float:
    """The smallest angle any fitting sleeve can be gathered to (max_gather_ratio), with room for
    the sleeve's cut rounding up by one step."""
    rules = catalogue.rules
    d_rest = rest_diameter(tubing, rules)
    d_ref = min(s.reference_diameter_m for s in sleeves)
    gather = rules.max_gather_ratio - 2 * rules.cut_resolution_m / rest_length_m
    return math.degrees(math.atan(d_ref / (d_rest * gather)))


def _largest_angle(tubing, rest, lo, request, material, rules):
    """Largest braid angle in [lo, THETA_MAX_DEG] meeting every requirement, or None."""
    thetas = np.linspace(lo, THETA_MAX_DEG, GRID)
    ok = []
    for t in thetas:
        m = _safe_muscle(tubing, rest, t, material, rules)
        ok.append(m is not None and min(_requirements(m, request).values()) >= 0)
    if not any(ok):
        return None
    i = max(k for k, good in enumerate(ok) if good)
    if i == GRID - 1:
        return float(thetas[-1])

    def worst(t):
        m = _safe_muscle(tubing, rest, t, material, rules)
        return -1.0 if m is None else min(_requirements(m, request).values())

    return float(brentq(worst, thetas[i], thetas[i + 1], xtol=1e-6))


def _excess(margins: dict[str, float]) -> float:
    """Over-design: the largest requirement margin apart from the binding (smallest) one."""
    values = sorted(margins.values())
    return max(values[1:]) if len(values) > 1 else 0.0


def size(
    request: Request,
    material: Material | None = None,
    catalogue: Catalogue | None = None,
    verify: int = 3,
    relax: bool = True,
) -> SizingResult:
    """Size an EFAM (or, with ``request.bundle``, the muscles of a section) from the catalogue.

    ``verify``: how many of the best designs to check in the MuJoCo rig (analytic beside
    simulated). An infeasible request gets the closest achievable point and per requirement how
    far to relax it (``relax=False`` skips that analysis).
    """
    t0 = time.perf_counter()
    material = material or Material.from_muscle("FAM1")
    catalogue = catalogue or load_catalogue()
    rules = catalogue.rules
    if request.pressure_Pa > rules.max_pressure_Pa:
        raise ValueError(
            f"pressure {request.pressure_Pa / 1e3:g} kPa is above the sizing's limit "
            f"{rules.max_pressure_Pa / 1e3:g} kPa (catalogue rule max_pressure)"
        )
    notes = []
    if request.pressure_Pa > 517.107e3 * 1.0001:
        notes.append("pressure above the paper's tested 517.1 kPa: the stress law is extrapolated")
    if request.pressure_Pa <= material.deadband_Pa:
        notes.append(f"pressure at or below the dead band ({material.deadband_Pa / 1e3:.2f} kPa): no force")
    designs, candidates = [], 0
    for tubing in catalogue.tubings:
        sleeves = [s for s in catalogue.sleeves if _fits(s, tubing, catalogue)]
        if not sleeves:
            continue
        candidates += len(sleeves)
        rest = _rest_length(request, tubing, catalogue)
        floor = _theta_floor(tubing, sleeves, rest, catalogue)
        theta = _largest_angle(tubing, rest, floor, request, material, rules)
        if theta is None:
            continue
        exact = fast_muscle(tubing, rest, theta, material, rules)
        excess = _excess(_requirements(exact, request, exact=True))
        for sleeve in sleeves:
            design = _design(tubing, sleeve, rest, theta, excess, request, material, catalogue)
            if design is not None and design.feasible:
                designs.append(design)
    designs.sort(key=lambda d: (round(d.excess, 6), d.mass_kg))
    closest, relaxations = None, ()
    if not designs:
        notes += _unstable_law_notes(request, material, catalogue)
    if not designs and relax:
        from .relax import relax_request

        closest, relaxations = relax_request(request, material, catalogue)
    if verify and designs:
        from .verify import verify_design

        designs[:verify] = [
            replace(d, verification=verify_design(d.muscle, request)) for d in designs[:verify]
        ]
    result = SizingResult(
        request, material, tuple(designs), closest, tuple(relaxations), candidates,
        time.perf_counter() - t0, catalogue.label, tuple(notes),
    )  # fmt: skip
    if request.bundle and designs:
        from .bundle import bundle_report

        result = replace(result, bundle=bundle_report(designs[0].muscle, request))
    return result


def _unstable_law_notes(request: Request, material: Material, catalogue: Catalogue) -> list[str]:
    """Why designs could not even be built: the law is not Drucker-stable over their strains."""
    rules, bad, tubes, message = catalogue.rules, 0, 0, ""
    for tubing in catalogue.tubings:
        sleeves = [s for s in catalogue.sleeves if _fits(s, tubing, catalogue)]
        if not sleeves:
            continue
        tubes += 1
        rest = _rest_length(request, tubing, catalogue)
        for theta in (_theta_floor(tubing, sleeves, rest, catalogue), THETA_MAX_DEG):
            try:
                fast_muscle(tubing, rest, theta, material, rules)
            except StressLawError as err:
                bad, message = bad + 1, str(err)
                break
            except MuscleError:
                pass
    if not bad:
        return []
    return [
        f"drucker: the stress law is not stable over the admissible strains of {bad} of {tubes} tubes' "
        f"designs, which cannot be built ({message}); use a stable law (--stress) or recalibrate"
    ]


def _design(tubing, sleeve, rest, theta, excess, request, material, catalogue) -> Design | None:
    """The cut design of one (tube, sleeve) at ``theta``; None when the parts make no muscle."""
    try:
        geometry = geometry_for(tubing, sleeve, rest, theta, catalogue.rules)
        muscle = muscle_for(geometry, material, name=f"{tubing.name} in {sleeve.name}")
    except (MuscleError, StressLawError):
        return None
    checks, perf = con.evaluate(muscle, geometry, tubing, sleeve, request, catalogue)
    masses = part_masses(geometry, tubing, sleeve, catalogue)
    return Design(tubing, sleeve, geometry, muscle, masses, checks, perf, excess)
