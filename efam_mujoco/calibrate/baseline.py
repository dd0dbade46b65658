"""The paper's procedure, as the baseline: Nelder-Mead (MATLAB's fminsearch) on Eq. 14.

Sec. 4.6: the linear law is fitted first from one start; its E1 and E2 are then the start of every
other law, whose remaining coefficients start from fixed, reasonable values. fminsearch's defaults
are kept: an initial simplex of +5 % of each non-zero start value (0.00025 for a zero one),
TolX = TolFun = 1e-4, at most 200 x (number of coefficients) iterations and function
evaluations. Bounds and Drucker stability are a penalty (Eq. 14 = 1e6 outside), as a user of the
unconstrained fminsearch would add them.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import minimize

from ..muscle import Muscle
from ..recordings import Recording
from .fit import Eq14, LawFit, Problem, finish_fit

#: The fixed start of the linear law: E1 in the paper's expected 1-5 MPa, a moderate E2.
LINEAR_START = {"E1_Pa": 2.0e6, "E2": 1.0}
#: Starts of the non-linear coefficients (E1, E2 come from the linear fit).
NONLINEAR_START = {
    "polynomial": {"E3_Pa": 1.0e5, "E4_Pa": 1.0e5},
    "exponential_decay": {"E3_Pa": 1.0e5, "E4": 10.0},
    "exponent": {"E3": 0.5, "E4": 1.5},
    "sigmoid": {"E3_Pa": 1.0e5, "E4": 10.0},
    "arccot": {"E3_Pa": 1.0e5, "E4": 10.0},
}


def fminsearch(function, x0, max_factor: int = 200):
    """scipy's Nelder-Mead configured as MATLAB's fminsearch defaults."""
    x0 = np.asarray(x0, dtype=float)
    n = len(x0)
    simplex = [x0]
    for i in range(n):
        x = x0.copy()
        x[i] = 1.05 * x[i] if x[i] != 0 else 0.00025
        simplex.append(x)
    return minimize(
        function, x0, method="Nelder-Mead",
        options={"initial_simplex": np.array(simplex), "xatol": 1e-4, "fatol": 1e-4,
                 "maxiter": max_factor * n, "maxfev": max_factor * n},
    )  # fmt: skip


def fit_law_nelder_mead(
    muscle: Muscle, recordings: list[Recording] | Problem, law: str, start: dict[str, float]
) -> LawFit:
    """Nelder-Mead on Eq. 14 from ``start`` (dead band fixed at the muscle's)."""
    t0 = time.perf_counter()
    problem = recordings if isinstance(recordings, Problem) else Problem(muscle, list(recordings))
    if problem.points is None:
        raise ValueError("the Nelder-Mead baseline minimises Eq. 14, which needs isobaric strokes")
    from ..stress import LAWS

    eq14 = Eq14(problem, law, muscle.deadband_Pa)
    x0 = [start[p] for p in LAWS[law].params]
    result = fminsearch(lambda x: eq14(tuple(x)), x0)
    best = result.x if result.fun <= eq14(tuple(x0)) else np.array(x0)
    return finish_fit(
        problem, law, tuple(best), muscle.deadband_Pa, "eq14", t0, eq14.evaluations, method="Nelder-Mead"
    )


def paper_baseline(muscle: Muscle, recordings: list[Recording] | Problem, laws) -> dict[str, LawFit]:
    """The paper's sequence: linear from LINEAR_START, then each law from the linear result."""
    problem = recordings if isinstance(recordings, Problem) else Problem(muscle, list(recordings))
    fits = {"linear": fit_law_nelder_mead(muscle, problem, "linear", LINEAR_START)}
    for law in laws:
        if law == "linear":
            continue
        start = {**fits["linear"].coefficients, **NONLINEAR_START[law]}
        fits[law] = fit_law_nelder_mead(muscle, problem, law, start)
    return {law: fits[law] for law in laws}
