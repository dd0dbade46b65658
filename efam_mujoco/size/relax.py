"""An infeasible request: the closest achievable point, and per requirement how far to relax it.

Per tube the most capable design the limits allow (the smallest braid angle at which bladder
strain, length range, Drucker stability and, unguided, buckling still hold) is what that tube
can do. The closest point is the best of these along the line from the origin to the request,
lambda x (stroke, force). Each relaxation moves one requirement, holding the others, to the best
value any tube reaches, and is confirmed by re-running the search at that value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq

from ..muscle import Muscle
from . import constraints as con
from .catalogue import Catalogue, Tubing
from .design import Material, rest_diameter
from .request import Request
from .search import GRID, THETA_MAX_DEG, _fits, _rest_length, _safe_muscle, _theta_floor, size


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
        """One sentence telling the user what to change and by how much."""
        if self.requirement == "--unguided":
            return "guide the muscle (drop --unguided: a guide tube, as the paper's test; a search finds a design)"
        verb = "raise" if self.achievable > self.requested else "lower"
        tail = {True: " (a search at that value finds a design)", False: " (not confirmed by a search)"}
        # a change of a thousand-fold or more reads better as a factor (1e-300 kPa to 114 kPa
        # printed a 300-digit percentage)
        if abs(self.change_pct) < 1e5 or not self.requested:
            change = f"{self.change_pct:+.1f} %"
        else:
            change = f"x {self.achievable / self.requested:.3g}"
        return (
            f"{verb} {self.requirement} from {self.requested:.4g} to {self.achievable:.4g} {self.unit} "
            f"({change}){tail.get(self.confirmed, '')}"
        )

    def to_dict(self) -> dict:
        """The relaxation as plain JSON types."""
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
        """The closest achievable point as plain JSON types (without the muscle object)."""
        return {k: v for k, v in self.__dict__.items() if k != "muscle"}


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
            blocked = float(m.blocked_push(P))

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


def relax_request(request: Request, material: Material, catalogue: Catalogue):
    """(closest point or None, list of :class:`Relaxation`) for a request no design meets."""
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
