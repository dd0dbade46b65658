"""The search: every catalogue tube, every sleeve that fits it, the braid angle that meets the
request; ranked designs, or for an infeasible request the closest point and what to relax.

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
        return sum(self.masses.values())

    @property
    def feasible(self) -> bool:
        return all(c.passed for c in self.checks)

    @property
    def binding(self) -> con.Check | None:
        return con.binding(self.checks)

    def to_dict(self) -> dict:
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
class Relaxation:
    """How far one requirement must move for some catalogue design to meet the request."""

    requirement: str  # the CLI flag
    requested: float
    achievable: float
    unit: str
    change_pct: float
    confirmed: bool | None = None  # a re-run search at the relaxed value found a design

    @property
    def message(self) -> str:
        if self.requirement == "--unguided":
            return "guide the muscle (drop --unguided: a guide tube, as the paper's test; a search finds a design)"
        verb = "raise" if self.achievable > self.requested else "lower"
        tail = {True: " (a search at that value finds a design)", False: " (not confirmed by a search)"}
        return (
            f"{verb} {self.requirement} from {self.requested:.4g} to {self.achievable:.4g} {self.unit} "
            f"({self.change_pct:+.1f} %){tail.get(self.confirmed, '')}"
        )

    def to_dict(self) -> dict:
        return {
            "requirement": self.requirement, "requested": self.requested, "achievable": self.achievable,
            "unit": self.unit, "change_pct": None if math.isnan(self.change_pct) else self.change_pct, "confirmed": self.confirmed, "message": self.message,
        }  # fmt: skip


@dataclass(frozen=True)
class ClosestPoint:
    """The achievable point nearest the request along the line to it: lambda x (stroke, force)."""

    fraction: float  # lambda, < 1 when infeasible
    stroke: float
    force_N: float
    tubing: str
    theta_rest_deg: float
    muscle: Muscle | None = None  # the closest design's muscle (for the figure; not in JSON)

    def to_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "muscle"}


@dataclass(frozen=True)
class SizingResult:
    request: Request
    material: Material
    designs: tuple  # feasible, ranked, best first
    closest: ClosestPoint | None
    relax: tuple
    candidates: int  # (tube, sleeve) pairs that fit, searched
    seconds: float
    catalogue: str
    notes: tuple = field(default_factory=tuple)
    bundle: object = None  # a bundle.BundleReport for a bundle request

    @property
    def feasible(self) -> bool:
        return bool(self.designs)

    @property
    def best(self) -> Design | None:
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
        scale = max(abs(float(muscle.blocked_force(P))), 1e-9)
        out["stroke"] = float(muscle.push(P, rest * (1 + request.stroke))) / scale
    if request.muscle_blocked_force_N:
        out["blocked"] = float(-muscle.blocked_force(P)) / request.muscle_blocked_force_N - 1
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
        closest, relaxations = _relax(request, material, catalogue)
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


# ------------------------------------------------------------------------- infeasible requests


@dataclass(frozen=True)
class _Capability:
    tubing: Tubing
    theta: float
    muscle: Muscle
    force_N: float  # push at the requested stroke (per muscle)
    stroke: float  # stroke at the requested force
    blocked_N: float
    fraction: float  # lambda along the line to the request
    work_ok: bool  # meets the force-at-stroke requirement here
    blocked_ok: bool  # meets the blocked-force requirement (if any) here


def _limits_ok(muscle: Muscle, tubing: Tubing, request: Request, catalogue: Catalogue) -> bool:
    """The limits (not the requirements, not the part-specific checks) hold for this muscle."""
    # judged in service up to the free length, whatever stroke was asked
    checks, _ = con.evaluate(muscle, None, tubing, None, replace(request, stroke=1e-9), catalogue)
    skip = {"force_at_stroke", "blocked_force", "max_diameter", "pressure_rating"}
    return all(c.passed for c in checks if c.name not in skip)


def _capabilities(request: Request, material: Material, catalogue: Catalogue, respect_diameter: bool):
    """Per tube: the most capable angle the limits allow and what it achieves."""
    rules, P = catalogue.rules, request.pressure_Pa
    F, S = request.muscle_force_N, request.stroke
    out = []
    for tubing in catalogue.tubings:
        sleeves = [s for s in catalogue.sleeves if _fits(s, tubing, catalogue)]
        if not sleeves:
            continue
        if (
            respect_diameter
            and request.max_diameter_m
            and rest_diameter(tubing, rules) > request.max_diameter_m
        ):
            continue
        rest = _rest_length(request, tubing, catalogue)
        for theta in np.linspace(_theta_floor(tubing, sleeves, rest, catalogue), THETA_MAX_DEG, GRID):
            m = _safe_muscle(tubing, rest, float(theta), material, rules)
            if m is None or not _limits_ok(m, tubing, request, catalogue):
                continue
            free = float(m.free_length(P))
            stroke = con.stroke_at_force(m, P, F, free)
            blocked = float(-m.blocked_force(P))

            def gap(lam, m=m):
                return float(m.push(P, m.rest_length_m * (1 + lam * S))) - lam * F

            if F > 0:
                lam = 1.0 if gap(1.0) >= 0 else brentq(gap, 0.0, 1.0, xtol=1e-9) if gap(0.0) > 0 else 0.0
            else:
                lam = min(1.0, (free / m.rest_length_m - 1) / S)
            if request.muscle_blocked_force_N:
                lam = min(lam, blocked / request.muscle_blocked_force_N)
            force = float(m.push(P, rest * (1 + S)))
            work_ok = force >= F if F > 0 else free / m.rest_length_m - 1 >= S
            blocked_ok = blocked >= (request.muscle_blocked_force_N or 0.0)
            out.append(_Capability(tubing, float(theta), m, force, stroke, blocked, lam, work_ok, blocked_ok))
            break
    return out


def _relax(request: Request, material: Material, catalogue: Catalogue):
    M = request.muscles
    caps = _capabilities(request, material, catalogue, respect_diameter=True)
    closest = None
    if caps:
        best = max(caps, key=lambda c: c.fraction)
        closest = ClosestPoint(best.fraction, best.fraction * request.stroke, best.fraction * request.force_N,
                               best.tubing.name, best.theta, best.muscle)  # fmt: skip
    out = []

    def confirm(**kw) -> bool:
        trial = replace(request, **kw)
        return size(trial, material, catalogue, verify=0, relax=False).feasible

    # each requirement alone: its best value among designs that still meet the others
    held = [c for c in caps if c.blocked_ok]
    if held and request.force_N > 0:
        force = max(c.force_N for c in held) * M
        if force < request.force_N:
            value = math.floor(force * 0.999 * 10) / 10
            if value > 0:
                out.append(Relaxation("--force", request.force_N, value, "N",
                                      100 * (value / request.force_N - 1), confirm(force_N=value)))  # fmt: skip
    if held:
        stroke = max(c.stroke for c in held)
        if stroke < request.stroke:
            value = math.floor(stroke * 0.999 * 1000) / 1000
            if value > 0:
                out.append(Relaxation("--stroke", request.stroke, value, "", 100 * (value / request.stroke - 1),
                                      confirm(stroke=value)))  # fmt: skip
    working = [c for c in caps if c.work_ok]
    if working and request.blocked_force_N:
        blocked = max(c.blocked_N for c in working) * M
        if blocked < request.blocked_force_N:
            value = math.floor(blocked * 0.999 * 10) / 10
            out.append(Relaxation("--blocked-force", request.blocked_force_N, value, "N",
                                  100 * (value / request.blocked_force_N - 1), confirm(blocked_force_N=value)))  # fmt: skip
    if request.unguided and not request.bundle:
        out += _unguided_relaxations(request, material, catalogue, confirm)
    pressure = _pressure_needed(request, material, catalogue)
    if pressure is not None:
        out.append(Relaxation("--pressure", request.pressure_Pa / 1e3, pressure / 1e3, "kPa",
                              100 * (pressure / request.pressure_Pa - 1), confirm(pressure_Pa=pressure)))  # fmt: skip
    if request.max_diameter_m:
        wider = [
            c for c in _capabilities(request, material, catalogue, respect_diameter=False) if c.fraction >= 1
        ]
        if wider:
            d = min(rest_diameter(c.tubing, catalogue.rules) for c in wider)
            value = math.ceil(d * 1e4) / 10  # mm, up to 0.1 mm
            out.append(Relaxation("--max-diameter", request.max_diameter_m * 1e3, value, "mm",
                                  100 * (value / (request.max_diameter_m * 1e3) - 1),
                                  confirm(max_diameter_m=value / 1e3)))  # fmt: skip
    return closest, out


def _unguided_relaxations(request: Request, material: Material, catalogue: Catalogue, confirm) -> list:
    """For an unguided muscle: guide it, or shorten it until its Euler load carries its blocked
    force (P_cr scales as 1 / L^2; force per strain does not depend on length)."""
    out = []
    guided = size(replace(request, unguided=False), material, catalogue, verify=0, relax=False)
    if guided.feasible:
        out.append(Relaxation("--unguided", 1.0, 0.0, "", math.nan, True))
        if request.length_m is not None:
            rules = catalogue.rules
            best = None
            for d in guided.designs:
                perf = d.performance
                shorter = d.muscle.rest_length_m * math.sqrt(perf.euler_load_N / perf.blocked_force_N)
                if shorter >= rules.min_aspect_ratio * d.muscle.rest_diameter_m:
                    best = shorter if best is None else max(best, shorter)
            if best is not None and best < request.length_m:
                value = math.floor(best * 0.98 * 1e3) / 1e3  # whole mm, clear of the cut rounding
                if value > 0:
                    out.append(Relaxation("--length", request.length_m, value, "m",
                                          100 * (value / request.length_m - 1), confirm(length_m=value)))  # fmt: skip
    return out


def _pressure_needed(request: Request, material: Material, catalogue: Catalogue) -> float | None:
    """The lowest pressure (to 1 kPa, within the catalogue's max) at which some design is feasible:
    bisection on the full search (feasibility rises with pressure until a limit binds)."""
    hi = catalogue.rules.max_pressure_Pa
    lo = request.pressure_Pa

    def feasible(p):
        return size(replace(request, pressure_Pa=p), material, catalogue, verify=0, relax=False).feasible

    # feasibility is not monotone in pressure once the strain or buckling limits bind: scan first
    grid = np.linspace(lo, hi, 7)[1:]
    first = next((p for p in grid if feasible(p)), None)
    if first is None:
        return None
    below = max([lo] + [p for p in grid if p < first])
    hi = first
    while hi - below > 1e3:
        mid = 0.5 * (hi + below)
        if feasible(mid):
            hi = mid
        else:
            below = mid
    return math.ceil(hi / 1e3) * 1e3
