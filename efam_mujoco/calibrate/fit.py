"""Stress-law coefficients from recordings: variable projection, then an Eq. 14 polish.

Why it is fast and needs no initial guess. Eq. 2 is

    F = max(P - P_db, 0) g(L) + sigma(eps_z, P) a_z(L) - sigma(eps_c, P) a_c(L)

with g = (3L^2 - B^2)/(4 pi N^2), a_z = V_B/L, a_c = t_B L^2/(2 pi R_o N^2), all fixed by the
geometry. Every law is a sum ``sum_j c_j b_j(eps, P)`` in which most coefficients enter linearly
(E1, E2 always; E3 of the polynomial, exponential-decay, sigmoid and arccot laws; E4 of the
polynomial) and at most two (E4; the exponent law's E3 and E4) enter non-linearly. So:

1. the per-sample geometry is computed once;
2. for given non-linear coefficients, the linear ones (and, with ``fit_deadband``, the dead band,
   whose term ``-P_db g(L)`` is linear too while the set of samples above it is fixed) come from
   one bounded linear least-squares solve on a k x k problem (k <= 5) -- exact, no start needed;
3. the non-linear coefficients (0, 1 or 2 of them) are searched over their whole search box
   (``stress.LAWS[law].search``): a grid, then a bounded local refinement from the best points.

Bounds: the linear coefficients stay in the law's search box (bounded-variable least squares).
Drucker stability: every law but the polynomial one is stable inside its bounds (stress.py); the
polynomial law's slope ``E1 + 2 E3 eps + 3 E4 eps^2`` is linear in the coefficients at each
strain, so stability over the muscle's whole strain range is a set of linear inequalities, imposed
exactly in the linear solve (cutting planes at the slope's minimum until it is positive).

A slack tension-only muscle (``muscle.tension_only``) carries ``max(F, 0)``: samples the model
calls slack are left out of the linear solve unless the data there is clearly taut (above 5 % of
the largest force), the rest kept (an active set iterated to a fixed point), and the reported
error uses the clipped model.

``objective="eq14"`` (default when the data are isobaric strokes) then minimises the paper's
Eq. 14 error itself, by the same variable projection: Eq. 14 is a weighted L1 norm, so for given
non-linear coefficients a linear programme gives the exact optimum of the linear ones
(``_eq14_search``). For a tension-only muscle (max(F, 0) is not linear) Nelder-Mead over all
coefficients, started from the best of the least-squares optimum and a grid, is used instead.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import linprog, lsq_linear, minimize, minimize_scalar

from ..muscle import Muscle
from ..recordings import Recording
from ..stress import LAW_NAMES, LAWS, StressLaw, StressLawError
from .data import ComparisonPoints, Samples, comparison_points, pool

#: Coefficients that enter the law non-linearly (searched); the others are solved linearly.
NONLINEAR = {
    "linear": (),
    "polynomial": (),
    "exponential_decay": ("E4",),
    "exponent": ("E3", "E4"),
    "sigmoid": ("E4",),
    "arccot": ("E4",),
}
#: Smallest d sigma/d eps accepted for the polynomial law, Pa (a strictly positive margin).
STABILITY_MARGIN_PA = 1e3
#: Samples kept per recording for fitting (consecutive samples averaged beyond this).
MAX_SAMPLES_PER_RECORDING = 300
OBJECTIVES = ("eq14", "lsq")


def _signed_power(e, p):
    return np.sign(e) * np.abs(e) ** p


def stress_basis(law: str, nonlinear: dict[str, float], eps, P) -> list[np.ndarray]:
    """sigma = sum_j c_j basis_j over the law's linearly-entering coefficients (params order)."""
    e = np.asarray(eps, dtype=float)
    linear = [e, P * e]
    if law == "linear":
        return linear
    if law == "polynomial":
        return linear + [e * e, e * e * e]
    if law == "exponent":
        return [e + _signed_power(e, nonlinear["E3"]) + _signed_power(e, nonlinear["E4"]), P * e]
    k = nonlinear["E4"]
    if law == "exponential_decay":
        return linear + [1.0 - np.exp(-k * e)]
    if law == "sigmoid":
        return linear + [np.tanh(k * e)]
    if law == "arccot":
        return linear + [(2.0 / np.pi) * np.arctan(k * e)]
    raise StressLawError(f"unknown stress law '{law}' (known: {', '.join(LAW_NAMES)})")


def linear_params(law: str) -> tuple[str, ...]:
    """The coefficients of ``law`` that enter Eq. 2 linearly (solved exactly, not searched)."""
    return tuple(p for p in LAWS[law].params if p not in NONLINEAR[law])


class Design:
    """Per-sample geometry of Eq. 2 for a set of samples (each may belong to its own muscle)."""

    def __init__(self, muscles: list[Muscle], recording: np.ndarray, P, L, tension, deadband_Pa: float):
        self.P = np.asarray(P, dtype=float)
        self.tension = np.asarray(tension, dtype=float)
        self.deadband_Pa = float(deadband_Pa)
        n = len(self.P)
        self.g, self.az, self.ac, self.ez, self.ec, self.lock = (np.empty(n) for _ in range(6))
        L = np.asarray(L, dtype=float)
        for i, m in enumerate(muscles):
            rows = recording == i
            if not rows.any():
                continue
            Lr = L[rows]
            Lc = np.clip(Lr, m.min_length_m, m.max_length_m)
            r_out = m.outer_radius(Lc)
            t = m.wall_thickness(Lc)
            ez, ec = m.strains(Lc)
            self.g[rows] = (3 * Lc * Lc - m.thread_length_m**2) / (4 * math.pi * m.turns**2)
            self.az[rows] = m.bladder_volume_m3 / Lc
            self.ac[rows] = t * Lc * Lc / (2 * math.pi * r_out * m.turns**2)
            self.ez[rows], self.ec[rows] = ez, ec
            self.lock[rows] = m.lock_stiffness_N_per_m * (Lr - Lc)
        self.tension_only = muscles[0].tension_only

    def __len__(self) -> int:
        return len(self.P)

    def columns(self, law: str, nonlinear: dict[str, float]) -> np.ndarray:
        """The design matrix of ``law``'s linear coefficients (one column each) at fixed non-linear ones:
        Eq. 2's stress terms, sigma_z a_z - sigma_c a_c, per sample."""
        bz = stress_basis(law, nonlinear, self.ez, self.P)
        bc = stress_basis(law, nonlinear, self.ec, self.P)
        return np.column_stack([z * self.az - c * self.ac for z, c in zip(bz, bc)])

    def predict(self, stress: StressLaw, deadband_Pa: float | None = None) -> np.ndarray:
        """Eq. 2 tension, exactly as Muscle.tension computes it."""
        d = self.deadband_Pa if deadband_Pa is None else deadband_Pa
        gauge = np.maximum(np.maximum(self.P, 0.0) - d, 0.0)
        P = np.maximum(self.P, 0.0)
        force = gauge * self.g + stress(self.ez, P) * self.az - stress(self.ec, P) * self.ac + self.lock
        return np.maximum(force, 0.0) if self.tension_only else force


@dataclass
class LawFit:
    """One law fitted to recordings. ``muscle`` carries the fitted law and dead band."""

    law: str
    muscle: Muscle
    coefficients: dict[str, float]
    rms_N: float
    eq14_error_pct: float | None
    stable: bool
    seconds: float
    deadband_Pa: float = 0.0
    eq14_by_k: dict[str, float] = field(default_factory=dict)  # Table 3 rows
    objective: str = "lsq"
    evaluations: int = 0
    method: str = "variable projection"

    @property
    def stress(self) -> StressLaw:
        """The fitted stress law (the muscle's)."""
        return self.muscle.stress


# --------------------------------------------------------------------------------- problem
class Problem:
    """Recordings prepared for fitting one or more laws to one muscle geometry."""

    def __init__(
        self,
        muscle: Muscle,
        recordings: list[Recording],
        *,
        muscle_for: Callable[[Recording], Muscle] | None = None,
        n: int = 5,
        max_samples_per_recording: int = MAX_SAMPLES_PER_RECORDING,
        samples: Samples | None = None,
    ):
        self.muscle = muscle
        self.recordings = recordings
        self.muscles = [muscle_for(r) if muscle_for else muscle for r in recordings]
        self.samples = pool(recordings) if samples is None else samples
        self.n = n
        self.reduced = _reduce(self.samples, max_samples_per_recording)
        self.points = comparison_points(self.samples, [m.rest_length_m for m in self.muscles], n)
        lo, hi = zip(*(m.strain_range() for m in self.muscles))
        self.strain_range = (min(lo), max(hi))

    def subset(self, mask) -> Problem:
        """The same problem on a subset of the samples (held-out validation)."""
        clone = object.__new__(Problem)
        clone.__dict__.update(self.__dict__)
        clone.samples = self.samples.take(mask)
        clone.reduced = _reduce(clone.samples, MAX_SAMPLES_PER_RECORDING)
        clone.points = comparison_points(clone.samples, [m.rest_length_m for m in self.muscles], self.n)
        return clone

    def design(self, which: str, deadband_Pa: float) -> Design:
        """The per-sample geometry of ``which`` samples: ``"fit"`` (reduced), ``"all"`` or ``"points"``
        (the Eq. 14 comparison points), with the dead band ``deadband_Pa``."""
        s = self.reduced if which == "fit" else self.samples
        if which == "points":
            pts = self.points
            return Design(self.muscles, pts.recording, pts.pressure_Pa, pts.length_m,
                          pts.tension_N, deadband_Pa)  # fmt: skip
        return Design(self.muscles, s.recording, s.pressure_Pa, s.length_m, s.tension_N, deadband_Pa)


def _reduce(samples: Samples, max_per_recording: int) -> Samples:
    """Average consecutive samples (never across recordings or levels) to bound the fit size."""
    keys = []
    for rec in np.unique(samples.recording):
        idx = np.nonzero(samples.recording == rec)[0]
        idx = idx[np.argsort(samples.time_s[idx], kind="stable")]
        chunk = max(1, math.ceil(len(idx) / max_per_recording))
        level = samples.level[idx]
        start = (np.arange(len(idx)) % chunk == 0) | np.r_[True, level[1:] != level[:-1]]
        keys.append((idx, np.nonzero(start)[0]))
    if all(len(starts) == len(idx) for idx, starts in keys):
        return samples
    cols = {name: [] for name in ("time_s", "length_m", "pressure_Pa", "tension_N", "recording", "level")}
    for idx, starts in keys:
        counts = np.diff(np.r_[starts, len(idx)])
        for name in ("time_s", "length_m", "pressure_Pa", "tension_N"):
            cols[name].append(np.add.reduceat(getattr(samples, name)[idx], starts) / counts)
        cols["recording"].append(samples.recording[idx][starts])
        cols["level"].append(samples.level[idx][starts])
    return Samples(**{k: np.concatenate(v) for k, v in cols.items()}, levels_Pa=samples.levels_Pa)


# ---------------------------------------------------------------------------- linear solve
@dataclass
class _Solution:
    linear: np.ndarray
    deadband_Pa: float
    cost: float


class _LinearSolver:
    """min ||A c - y|| over the linear coefficients (and the dead band) for fixed non-linear ones."""

    def __init__(
        self, design: Design, law: str, fit_deadband: bool, deadband_hi: float, strain_range, weights=None
    ):
        self.d = design
        self.w = np.ones(len(design)) if weights is None else np.asarray(weights, dtype=float)
        self.law = law
        self.fit_deadband = fit_deadband
        names = linear_params(law)
        box = dict(zip(LAWS[law].params, LAWS[law].search))
        self.lo = np.array([box[p][0] for p in names] + ([0.0] if fit_deadband else []))
        self.hi = np.array([box[p][1] for p in names] + ([deadband_hi] if fit_deadband else []))
        self.k = len(names)
        self.strain_range = strain_range
        self.evaluations = 0

    def solve(self, nonlinear: dict[str, float]) -> _Solution:
        self.evaluations += 1
        d = self.d
        A_stress = d.columns(self.law, nonlinear)
        deadband = d.deadband_Pa
        rows = np.ones(len(d), dtype=bool)
        P = np.maximum(d.P, 0.0)
        # A sample the model calls slack only pulls the model up when the data is clearly taut (5 % of
        # the largest force), so noise around zero in a slack stretch does not bias the fit.
        taut = 0.05 * float(np.max(np.abs(d.tension), initial=0.0))
        solution = None
        for _ in range(12):
            above = P > deadband
            if self.fit_deadband:
                A = np.column_stack([A_stress, -d.g * above])
                y = d.tension - d.lock - P * above * d.g
            else:
                A = A_stress
                y = d.tension - d.lock - np.maximum(P - deadband, 0.0) * d.g
            coef = self._bounded_lsq(A[rows] * self.w[rows, None], y[rows] * self.w[rows])
            new_deadband = float(coef[-1]) if self.fit_deadband else deadband
            model = A @ coef - y + d.tension  # y = tension - (pressure term + lock)
            new_rows = (model > 0) | (d.tension > taut) if d.tension_only else rows
            new_above = P > new_deadband
            solution = _Solution(coef[: self.k], new_deadband, 0.0)
            if np.array_equal(new_rows, rows) and np.array_equal(new_above, above):
                break
            rows, deadband = new_rows, new_deadband
        model = A @ coef - y + d.tension
        if d.tension_only:
            model = np.maximum(model, 0.0)
        r = (model - d.tension) * self.w
        solution.cost = float(r @ r)
        return solution

    def _bounded_lsq(self, A: np.ndarray, y: np.ndarray) -> np.ndarray:
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        As = A / scale
        Q, R = np.linalg.qr(As)
        z = Q.T @ y
        lo, hi = self.lo * scale, self.hi * scale
        try:
            x = np.linalg.solve(R, z)
        except np.linalg.LinAlgError:
            x = np.full(len(z), np.nan)
        if not (np.all(np.isfinite(x)) and np.all(x >= lo) and np.all(x <= hi)):
            x = lsq_linear(R, z, bounds=(lo, hi), method="bvls").x
        # the solver meets its bounds to rounding (-6e-10 Pa on a bound of 0 with 3 samples)
        coef = np.clip(x / scale, self.lo, self.hi)
        unstable = (
            self.law == "polynomial" and _quad_min(*coef[[0, 2, 3]], self.strain_range) < STABILITY_MARGIN_PA
        )
        if unstable:
            coef = _stable_polynomial(R, z, scale, lo, hi, self.strain_range)
        return coef


def _quad_min(E1, E3, E4, strain_range) -> float:
    lo, hi = strain_range
    candidates = [lo, hi]
    if E4 != 0:
        vertex = -E3 / (3 * E4)
        if lo < vertex < hi:
            candidates.append(vertex)
    return min(E1 + 2 * E3 * e + 3 * E4 * e * e for e in candidates)


def _stable_polynomial(R, z, scale, lo, hi, strain_range) -> np.ndarray:
    """min ||R x - z|| in bounds with E1 + 2 E3 e + 3 E4 e^2 >= margin over the strain range."""
    grid = list(np.linspace(*strain_range, 41))
    k = R.shape[1]  # the coefficients (fewer samples than coefficients give fewer rows in R)

    def rows_for(strains):
        G = np.zeros((len(strains), k))
        for i, e in enumerate(strains):
            G[i, 0], G[i, 2], G[i, 3] = 1.0, 2 * e, 3 * e * e
        return G / scale  # constraints act on coef = x / scale

    x = np.clip(np.linalg.lstsq(R, z, rcond=None)[0], lo, hi)
    for _ in range(8):
        G = rows_for(grid)
        constraint = {
            "type": "ineq",
            "fun": lambda v, G=G: G @ v - 2 * STABILITY_MARGIN_PA,
            "jac": lambda v, G=G: G,
        }
        result = minimize(
            lambda v: 0.5 * float((R @ v - z) @ (R @ v - z)),
            x,
            jac=lambda v: R.T @ (R @ v - z),
            bounds=list(zip(lo, hi)),
            constraints=[constraint],
            method="SLSQP",
            options={"maxiter": 200, "ftol": 1e-12},
        )
        x = result.x
        coef = np.clip(x / scale, lo / scale, hi / scale)
        if _quad_min(coef[0], coef[2], coef[3], strain_range) >= STABILITY_MARGIN_PA:
            return coef
        grid.append(-coef[2] / (3 * coef[3]))  # cut at the slope's minimum and solve again
    return coef


# ----------------------------------------------------------------------------- outer search
class _Space:
    """The non-linear coefficients as a unit cube: E4 of the 1-D laws on a log scale (it spans
    0.5-200), the exponent law's E3 and E4 on a linear one."""

    def __init__(self, law: str):
        self.names = NONLINEAR[law]
        box = dict(zip(LAWS[law].params, LAWS[law].search))
        self.boxes = [box[n] for n in self.names]
        self.log = len(self.names) == 1

    def values(self, u) -> dict[str, float]:
        if self.log:
            (lo, hi), x = self.boxes[0], float(u[0])
            return {self.names[0]: math.exp(math.log(lo) + x * (math.log(hi) - math.log(lo)))}
        return {n: b[0] + float(x) * (b[1] - b[0]) for n, b, x in zip(self.names, self.boxes, u)}

    def unit(self, nonlinear: dict[str, float]) -> np.ndarray:
        """Inverse of :meth:`values`."""
        if self.log:
            (lo, hi), v = self.boxes[0], nonlinear[self.names[0]]
            return np.array([(math.log(v) - math.log(lo)) / (math.log(hi) - math.log(lo))])
        return np.array([(nonlinear[n] - b[0]) / (b[1] - b[0]) for n, b in zip(self.names, self.boxes)])

    def grid(self, points: int | None = None) -> list[np.ndarray]:
        """A regular grid over the box (25 points in 1-D, 9 x 9 in 2-D by default)."""
        if not self.names:
            return [np.zeros(0)]
        if self.log:
            return [np.array([x]) for x in np.linspace(0.0, 1.0, points or 25)]
        axis = np.linspace(0.0, 1.0, points or 9)
        return [np.array([a, b]) for a in axis for b in axis]


#: Costs within this relative distance are a tie: the tie goes to the first grid point (in grid
#: order), and a local refinement must beat the grid by more than this to be taken. Where the data
#: cannot tell coefficients apart (e.g. isometric recordings probe a law at a few strains only, so
#: its cost is flat along a valley to the last bits), the answer is then the same on every machine
#: and numpy/scipy version instead of wherever rounding noise stopped the optimiser.
TIE_REL = 1e-9


def _first_best(costs: np.ndarray) -> int:
    """Index of the first cost within :data:`TIE_REL` of the smallest."""
    return int(np.nonzero(costs <= costs.min() * (1 + TIE_REL))[0][0])


def _golden(cost, a: float, b: float, xtol: float = 1e-5) -> tuple[float, float]:
    """Golden-section minimum of ``cost`` on [a, b]; a near-tie (:data:`TIE_REL`) keeps the left
    part, so rounding noise on a flat stretch never decides the path."""
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - ratio * (b - a), a + ratio * (b - a)
    fc, fd = cost(c), cost(d)
    while b - a > xtol:
        if fc <= fd * (1 + TIE_REL):
            b, d, fd = d, c, fc
            c = b - ratio * (b - a)
            fc = cost(c)
        else:
            a, c, fc = c, d, fd
            d = a + ratio * (b - a)
            fd = cost(d)
    return (c, fc) if fc <= fd * (1 + TIE_REL) else (d, fd)


def _compass(cost, start: np.ndarray, f0: float, step: float, xtol: float = 1e-5) -> tuple[np.ndarray, float]:
    """Compass search in the unit square from ``start``: try +-step along each axis in a fixed order,
    move on an improvement beyond :data:`TIE_REL`, else halve the step. Deterministic."""
    u, best = np.array(start, dtype=float), float(f0)
    while step >= xtol:
        moved = False
        for axis in range(len(u)):
            for sign in (-1.0, 1.0):
                trial = u.copy()
                trial[axis] = min(max(trial[axis] + sign * step, 0.0), 1.0)
                if np.array_equal(trial, u):
                    continue
                value = cost(trial)
                if value < best * (1 - TIE_REL):
                    u, best, moved = trial, value, True
                    break
        if not moved:
            step /= 2.0
    return u, best


def _search(solver: _LinearSolver, law: str) -> tuple[dict[str, float], _Solution]:
    """Least squares over the whole box: a grid of the non-linear coefficients, then a local
    refinement that ties go against (golden section in 1-D, compass search in 2-D; both make
    their decisions with :data:`TIE_REL`, so the result does not depend on rounding noise)."""
    space = _Space(law)
    if not space.names:
        return {}, solver.solve({})
    grid = space.grid()
    cost = lambda u: solver.solve(space.values(u)).cost  # noqa: E731
    costs = np.array([cost(u) for u in grid])
    i = _first_best(costs)
    if len(space.names) == 1:
        a, b = grid[max(i - 1, 0)][0], grid[min(i + 1, len(grid) - 1)][0]
        x, value = _golden(lambda x: cost([x]), a, b)
        u = np.array([x]) if value < costs[i] * (1 - TIE_REL) else grid[i]
    else:
        spacing = 1.0 / (round(math.sqrt(len(grid))) - 1)
        u, _ = _compass(cost, grid[i], float(costs[i]), spacing / 2)
    nonlinear = space.values(u)
    return nonlinear, solver.solve(nonlinear)


def _eq14_starts(problem: Problem, law: str, eq14: Eq14, deadband_Pa: float, count: int = 2) -> list:
    """Starts for the Eq. 14 polish that do not come from least squares on all samples: over the
    same grid, the linear coefficients that fit the comparison points in relative terms (weighted
    least squares, Eq. 14's weights), ranked by their Eq. 14 error."""
    solver = _LinearSolver(problem.design("points", deadband_Pa), law, False, deadband_Pa,
                           problem.strain_range, weights=eq14.weight)  # fmt: skip
    space = _Space(law)
    scored = []
    for u in space.grid():
        nonlinear = space.values(u)
        coefficients = _assemble(law, nonlinear, solver.solve(nonlinear).linear)
        scored.append((eq14(coefficients), coefficients))
    scored.sort(key=lambda item: item[0])
    return [c for _, c in scored[:count]]


def _assemble(law: str, nonlinear: dict[str, float], linear: np.ndarray) -> tuple[float, ...]:
    values = dict(zip(linear_params(law), linear))
    values.update(nonlinear)
    return tuple(float(values[p]) for p in LAWS[law].params)


# ------------------------------------------------------------------------------ Eq. 14
def eq14_table(points: ComparisonPoints, model_tension: np.ndarray) -> dict[str, float]:
    """Table 3 rows: mean relative error (%) over pressures at each comparison length.

    ``blocked`` is the paper's near-blocked row (eps = 5e-4), ``k/n`` the Eq. 14 points and
    ``eq14`` Eq. 14 itself: the mean over pressures of the mean over k = 1..n.
    """
    # a comparison point at exactly zero tension (a slack muscle) has no relative error: it is
    # inf here, and eq14_value drops non-finite levels (no warning: it is expected, not a fault)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(points.tension_N - model_tension) / np.abs(points.tension_N) * 100.0
    table: dict[str, float] = {}
    for k in range(0, points.n + 1):
        at = points.k == k
        if at.any():
            table["blocked" if k == 0 else f"{k}/{points.n}"] = float(np.mean(rel[at]))
    table["eq14"] = eq14_value(points, rel)
    return table


def eq14_value(points: ComparisonPoints, rel_pct: np.ndarray) -> float:
    """Eq. 14 from per-point relative errors (%): the mean over levels of each level's mean (k > 0)."""
    # a level with no point above the blocked one (k = 0) has no mean and is left out
    at_levels = [(points.level == j) & (points.k > 0) for j in np.unique(points.level)]
    per_level = [v for v in (np.mean(rel_pct[at]) for at in at_levels if at.any()) if np.isfinite(v)]
    return float(np.mean(per_level)) if per_level else math.nan


class Eq14:
    """Eq. 14 error of a coefficient vector (a large penalty outside bounds or when unstable).

    Evaluated thousands of times by Nelder-Mead, so it avoids building objects: the bounds are
    checked against ``LAWS[law].bounds`` and the model is the law's basis times its coefficients.
    """

    PENALTY = 1e6

    def __init__(self, problem: Problem, law: str, deadband_Pa: float):
        pts = problem.points
        self.points = pts
        self.design = problem.design("points", deadband_Pa)
        self.law = law
        self.strain_range = problem.strain_range
        self.evaluations = 0
        self.bounds = LAWS[law].bounds
        self.params = LAWS[law].params
        self.linear_index = [self.params.index(p) for p in linear_params(law)]
        d = self.design
        P = np.maximum(d.P, 0.0)
        self.fixed = np.maximum(P - deadband_Pa, 0.0) * d.g + d.lock
        # Eq. 14 = sum_i weight_i |F_i - model_i| / |F_i|: the mean over levels of the mean over k
        weight = np.zeros(len(pts.k))
        used = [j for j in np.unique(pts.level) if np.any((pts.level == j) & (pts.k > 0))]
        for j in used:
            at = (pts.level == j) & (pts.k > 0)
            weight[at] = 1.0 / (len(used) * np.count_nonzero(at))
        self.weight = 100.0 * weight / np.abs(pts.tension_N)

    def admissible(self, c) -> bool:
        """Whether coefficients ``c`` are inside the law's bounds (and, for the polynomial, stable)."""
        for value, (lo, hi, lo_open, hi_open) in zip(c, self.bounds):
            if not math.isfinite(value) or value < lo or value > hi:
                return False
            if (lo_open and value == lo) or (hi_open and value == hi):
                return False
        if self.law == "polynomial":
            return _quad_min(c[0], c[2], c[3], self.strain_range) > 0
        return True

    def model(self, c) -> np.ndarray:
        """Eq. 2 tension at the comparison points for coefficients ``c``."""
        d = self.design
        nonlinear = {p: c[i] for i, p in enumerate(self.params) if p in NONLINEAR[self.law]}
        P = np.maximum(d.P, 0.0)
        bz = stress_basis(self.law, nonlinear, d.ez, P)
        bc = stress_basis(self.law, nonlinear, d.ec, P)
        force = self.fixed.copy()
        for i, z, w in zip(self.linear_index, bz, bc):
            force += c[i] * (z * d.az - w * d.ac)
        return np.maximum(force, 0.0) if d.tension_only else force

    def __call__(self, coefficients) -> float:
        self.evaluations += 1
        c = tuple(float(v) for v in coefficients)
        if not self.admissible(c):
            return self.PENALTY
        value = float(self.weight @ np.abs(self.points.tension_N - self.model(c)))
        return value if math.isfinite(value) else self.PENALTY


def _eq14_search(
    eq14: Eq14, problem: Problem, law: str, deadband_Pa: float, ls_nonlinear: dict[str, float]
) -> tuple[float, ...]:
    """Variable projection on Eq. 14.

    Eq. 14 is a weighted L1 norm of relative errors, convex in the linear coefficients: for given
    non-linear ones a linear programme gives their exact optimum (``_eq14_linear_programme``; for
    the linear and polynomial laws that is the global optimum). Its landscape in the non-linear
    coefficients has narrow curved valleys (the exponent law), so the search over them is:

    1. a fine grid scored cheaply -- linear coefficients by weighted least squares on the
       comparison points (Eq. 14's weights), then the true Eq. 14 of the result;
    2. the two best local minima of that grid, and the least-squares optimum on all
       samples, refined with the exact linear programme inside (Brent in 1-D, Nelder-Mead in 2-D).
    """
    space = _Space(law)
    cache: dict[tuple, tuple[float, tuple[float, ...] | None]] = {}

    def exact(u) -> float:
        key = tuple(np.round(np.asarray(u, dtype=float), 12))
        if key not in cache:
            coefficients = _eq14_linear_programme(eq14, law, space.values(u))
            cache[key] = (eq14(coefficients) if coefficients else Eq14.PENALTY, coefficients)
        return cache[key][0]

    if not space.names:
        exact(np.zeros(0))
        return min(cache.values(), key=lambda item: item[0])[1]
    surrogate = _LinearSolver(problem.design("points", deadband_Pa), law, False, deadband_Pa,
                              problem.strain_range, weights=eq14.weight)  # fmt: skip
    one_d = len(space.names) == 1
    fine = space.grid(49 if one_d else 15)
    scores = np.array([eq14(_assemble(law, space.values(u), surrogate.solve(space.values(u)).linear))
                       for u in fine])  # fmt: skip
    starts = [fine[i] for i in _local_minima(scores, one_d)[:2]] + [space.unit(ls_nonlinear)]
    step = 1.0 / 48 if one_d else 1.0 / 14
    for u in starts:
        if one_d:
            a, b = max(u[0] - step, 0.0), min(u[0] + step, 1.0)
            minimize_scalar(lambda v: exact([v]), bounds=(a, b), method="bounded", options={"xatol": 2e-4})
        else:
            simplex = [u, np.clip(u + [step, 0], 0, 1), np.clip(u + [0, step], 0, 1)]
            minimize(exact, u, method="Nelder-Mead", bounds=[(0.0, 1.0)] * 2,
                     options={"xatol": 1e-5, "fatol": 1e-7, "maxfev": 30, "initial_simplex": simplex})  # fmt: skip
    return min(cache.values(), key=lambda item: item[0])[1]


def _local_minima(scores: np.ndarray, one_d: bool) -> list[int]:
    """Indices of the grid's local minima (4-neighbourhood in 2-D), best first."""
    if one_d:
        padded = np.r_[np.inf, scores, np.inf]
        mask = (scores <= padded[:-2]) & (scores <= padded[2:])
    else:
        side = int(round(math.sqrt(len(scores))))
        z = np.pad(scores.reshape(side, side), 1, constant_values=np.inf)
        c = z[1:-1, 1:-1]
        mask = ((c <= z[:-2, 1:-1]) & (c <= z[2:, 1:-1]) & (c <= z[1:-1, :-2]) & (c <= z[1:-1, 2:])).ravel()
    idx = np.nonzero(mask)[0]
    return [int(i) for i in idx[np.argsort(scores[idx])]]


def _eq14_linear_programme(eq14: Eq14, law: str, nonlinear: dict[str, float]) -> tuple[float, ...] | None:
    """The linear coefficients minimising Eq. 14 exactly, the non-linear ones held.

    min sum_i w_i t_i  s.t.  -t_i <= y_i - A_i c <= t_i, c in the search box, and for the
    polynomial law E1 + 2 E3 e + 3 E4 e^2 >= margin on a strain grid (plus cuts at the slope's
    minimum until it holds exactly). None when the model is not linear in c (tension-only).
    """
    if eq14.design.tension_only:
        return None
    params = LAWS[law].params
    A = eq14.design.columns(law, nonlinear)
    y = eq14.points.tension_N - eq14.fixed
    used = eq14.weight > 0
    A, y, w = A[used], y[used], eq14.weight[used]
    m, k = A.shape
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    As = A / scale
    box = dict(zip(params, LAWS[law].search))
    bounds = [(box[p][0] * s, box[p][1] * s) for p, s in zip(linear_params(law), scale)] + [(0, None)] * m
    objective = np.r_[np.zeros(k), w]
    A_ub = np.block([[As, -np.eye(m)], [-As, -np.eye(m)]])
    b_ub = np.r_[y, -y]
    strains = list(np.linspace(*eq14.strain_range, 41)) if law == "polynomial" else []
    for _ in range(8):
        rows, rhs = A_ub, b_ub
        if strains:  # -(E1 + 2 E3 e + 3 E4 e^2) <= -2 margin, on coef = x / scale
            G = np.array([[1.0, 0.0, 2 * e, 3 * e * e] for e in strains]) / scale
            rows = np.vstack([A_ub, np.hstack([-G, np.zeros((len(strains), m))])])
            rhs = np.r_[b_ub, np.full(len(strains), -2 * STABILITY_MARGIN_PA)]
        result = linprog(objective, A_ub=rows, b_ub=rhs, bounds=bounds, method="highs")
        if result.status != 0:
            return None
        linear = result.x[:k] / scale
        if law != "polynomial" or _quad_min(*linear[[0, 2, 3]], eq14.strain_range) >= STABILITY_MARGIN_PA:
            return _assemble(law, nonlinear, linear)
        strains.append(-linear[2] / (3 * linear[3]))
    return None


def _polish_eq14(eq14: Eq14, start: tuple[float, ...], law: str) -> tuple[tuple[float, ...], float]:
    """Nelder-Mead on Eq. 14 in coordinates scaled by the start, within the search box; restarted
    from its own result while that still improves (a collapsed simplex is a common NM stall)."""
    box = np.array(LAWS[law].search, dtype=float)
    width = box[:, 1] - box[:, 0]
    scale = np.where(np.abs(start) > 1e-9 * width, np.abs(start), 1e-3 * width)
    best_x, best_f = np.array(start) / scale, eq14(start)
    for _ in range(3):
        result = minimize(
            lambda x: eq14(x * scale), best_x, method="Nelder-Mead",
            bounds=list(zip(box[:, 0] / scale, box[:, 1] / scale)),
            options={"xatol": 1e-6, "fatol": 1e-6, "maxfev": 300 * len(start), "adaptive": True},
        )  # fmt: skip
        if not result.fun < best_f - 1e-6:
            if result.fun < best_f:
                best_x, best_f = result.x, float(result.fun)
            break
        best_x, best_f = result.x, float(result.fun)
    return tuple(float(v) for v in best_x * scale), best_f


# ------------------------------------------------------------------------------- fit_law
def fit_law(
    muscle: Muscle,
    recordings: list[Recording] | Problem,
    law: str,
    fit_deadband: bool = True,
    *,
    objective: str | None = None,
    muscle_for: Callable[[Recording], Muscle] | None = None,
    n: int = 5,
) -> LawFit:
    """Fit ``law``'s coefficients (and, with ``fit_deadband``, the dead band) to recordings.

    ``muscle`` gives the geometry (rest length and diameter, braid angle, bladder volume), the
    dead band (the start, or the value kept when ``fit_deadband`` is False) and ``tension_only``;
    its stress law is ignored. ``objective``: ``"lsq"`` (least squares in N over all samples) or
    ``"eq14"`` (the paper's Eq. 14 error, searched as described in the module docstring); default
    ``"eq14"`` for isobaric strokes and ``"lsq"`` otherwise. ``muscle_for(recording)`` gives a
    recording its own muscle (e.g. the same tube cut to another length); the returned fit's
    ``muscle`` is ``muscle`` with the fitted law and dead band.
    """
    start = time.perf_counter()
    if law not in LAWS:
        raise StressLawError(f"unknown stress law '{law}' (known: {', '.join(LAW_NAMES)})")
    problem = recordings if isinstance(recordings, Problem) else Problem(
        muscle, list(recordings), muscle_for=muscle_for, n=n
    )  # fmt: skip
    if objective is None:
        objective = "eq14" if problem.points is not None else "lsq"
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    if objective == "eq14" and problem.points is None:
        raise ValueError("objective 'eq14' needs isobaric strokes (Eq. 14 compares along a stroke)")
    deadband_hi = _deadband_limit(problem.samples)
    solver = _LinearSolver(
        # a dead band kept from Sec. 4.3 stays as estimated, even above a tested level (a level
        # below the dead band carries no pressure force: the estimate lowered to it under the
        # lowest level misfit every level, 7 N RMS on a 0.5 N noise); a fitted one starts inside
        # its bound
        problem.design("fit", min(muscle.deadband_Pa, deadband_hi) if fit_deadband else muscle.deadband_Pa),
        law, fit_deadband, deadband_hi,
        problem.strain_range,
    )  # fmt: skip
    nonlinear, solution = _search(solver, law)
    coefficients = _assemble(law, nonlinear, solution.linear)
    deadband = solution.deadband_Pa
    evaluations = solver.evaluations
    if objective == "eq14":
        eq14 = Eq14(problem, law, deadband)
        if eq14.design.tension_only:  # max(F, 0) is not linear in the coefficients: no LP
            starts = [coefficients] + _eq14_starts(problem, law, eq14, deadband)
            coefficients, _ = _polish_eq14(eq14, min(starts, key=eq14), law)
        else:
            found = _eq14_search(eq14, problem, law, deadband, nonlinear)
            if eq14(found) <= eq14(coefficients):
                coefficients = found
        evaluations += eq14.evaluations
    return finish_fit(problem, law, coefficients, deadband, objective, start, evaluations)


def _deadband_limit(samples: Samples) -> float:
    """The dead band stays below the lowest tested level (isobaric) or half the top pressure."""
    positive = samples.levels_Pa[samples.levels_Pa > 0] if samples.isobaric else np.array([])
    if len(positive):
        return 0.95 * float(positive.min())
    return 0.5 * float(np.max(samples.pressure_Pa))


def finish_fit(
    problem: Problem, law: str, coefficients, deadband_Pa: float, objective: str, start: float,
    evaluations: int, method: str = "variable projection",
) -> LawFit:  # fmt: skip
    """Score coefficients on all samples and package them as a :class:`LawFit`."""
    stress = StressLaw(law, tuple(coefficients))
    try:
        stress.check_stable(*problem.strain_range)
        stable = True
    except StressLawError:
        stable = False
    fitted = replace(problem.muscle, stress=stress, deadband_Pa=float(deadband_Pa))
    model = problem.design("all", deadband_Pa).predict(stress)
    rms = float(np.sqrt(np.mean((model - problem.samples.tension_N) ** 2)))
    table: dict[str, float] = {}
    if problem.points is not None:
        table = eq14_table(problem.points, problem.design("points", deadband_Pa).predict(stress))
    return LawFit(
        law=law, muscle=fitted, coefficients=stress.to_dict(), rms_N=rms,
        eq14_error_pct=table.get("eq14"), stable=stable, seconds=time.perf_counter() - start,
        deadband_Pa=float(deadband_Pa), eq14_by_k=table, objective=objective, evaluations=evaluations,
        method=method,
    )  # fmt: skip
