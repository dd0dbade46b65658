"""Dead band (paper Sec. 4.3) and resting braid angle (Sec. 4.4) from blocked forces.

At the resting length the stress terms of Eq. 2 vanish and it reduces to Gaylord's Eq. 9:

    F_BF = (P - P_db) pi D_rest^2 / (4 cos^2 theta) (3 sin^2 theta - 1)
         = (P - P_db) (pi D_rest^2 / 4) (2 tan^2 theta - 1)

so the blocked force is a straight line in pressure: its zero crossing is the dead band and, with
the resting diameter known, its slope gives the braid angle. Below the dead band the muscle
carries no force, so the fitted model is the hinge ``a max(P - P_db, 0)``; with isobaric data
above the dead band (the paper's five pressures) that is exactly the paper's linear fit and zero
crossing.

Outliers (the paper drops FAM2's 413.7 kPa point by eye): with few points, a point is rejected
when its residual from the line fitted to the OTHER points exceeds 4 times their residual standard
deviation and 1 % of the largest blocked force (the worst first, one at a time); with many points
(a pressure ramp), residuals beyond 4 robust standard deviations (1.4826 x the median absolute
deviation) and 1 % are dropped. At most a third of the points are ever rejected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .data import Samples, local_value

OUTLIER_SIGMAS = 4.0
OUTLIER_FLOOR = 0.01  # of the largest |blocked force|


@dataclass
class BlockedForceFit:
    """Blocked-force line: tension (paper sign) = slope * max(P - deadband, 0)."""

    deadband_Pa: float
    slope_N_per_Pa: float
    pressure_Pa: np.ndarray
    tension_N: np.ndarray
    inlier: np.ndarray
    rms_N: float
    theta_rest_deg: float | None = None  # from the slope, given the resting diameter
    rest_diameter_m: float | None = None

    def predict(self, pressure_Pa):
        """The hinge line's blocked tension (N) at ``pressure_Pa``: slope x max(P - dead band, 0)."""
        return self.slope_N_per_Pa * np.maximum(np.asarray(pressure_Pa, dtype=float) - self.deadband_Pa, 0.0)


def blocked_points(samples: Samples, rest_length_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(pressure, tension) pairs at the resting length.

    Isobaric strokes, at each level: the mean force of the samples held at the resting length
    (within 0.01 % of it) when there are 10 or more (a blocked-force hold before the stroke);
    otherwise the value at Delta L = 0 of a local quadratic over the samples within 2 % of the
    level's largest length change (a stroke starting at rest). Other data (isometric pressure
    ramps): every sample held within 0.1 % of the resting length.
    """
    if samples.isobaric:
        P, F = [], []
        for j, p in enumerate(samples.levels_Pa):
            seg = samples.take(samples.level == j)
            dL = seg.length_m - rest_length_m
            held = np.abs(dL) <= 1e-4 * rest_length_m
            if np.count_nonzero(held) >= 10:
                value = float(np.mean(seg.tension_N[held]))
            else:
                half = max(0.02 * float(np.max(np.abs(dL))), 1e-4 * rest_length_m)
                value = local_value(dL, seg.tension_N, 0.0, half)
            if np.isfinite(value):
                P.append(p)
                F.append(value)
        return np.array(P), np.array(F)
    near = np.abs(samples.length_m - rest_length_m) <= 1e-3 * rest_length_m
    return samples.pressure_Pa[near], samples.tension_N[near]


#: the points kept must span at least this share of the largest pressure (one level gives no line)
MIN_PRESSURE_SPAN = 0.1


def fit_blocked(pressure_Pa, tension_N, rest_diameter_m: float | None = None) -> BlockedForceFit:
    """Hinge fit with residual-based outlier rejection; braid angle from the slope if D is given."""
    P = np.asarray(pressure_Pa, dtype=float)
    F = np.asarray(tension_N, dtype=float)
    if len(P) < 2 or np.ptp(P) <= 0:
        raise ValueError(
            "blocked force: need the force at the resting length at two or more pressures "
            f"(got {len(P)} point(s)); record a stroke that starts at the resting length"
        )
    inlier = _reject_outliers(P, F)
    kept = P[inlier]
    if np.ptp(kept) < MIN_PRESSURE_SPAN * float(np.max(np.abs(P))):
        rejected = ", ".join(f"{p / 1e3:.4g}" for p in P[~inlier]) or "none"
        raise ValueError(
            f"blocked force: the {len(kept)} point(s) kept lie at {np.min(kept) / 1e3:.4g} .. "
            f"{np.max(kept) / 1e3:.4g} kPa (rejected as outliers: {rejected} kPa), one pressure level: "
            "a dead band and a slope need the force at the resting length at two or more clearly "
            "different pressures"
        )
    deadband, slope = _hinge(kept, F[inlier])
    residual = F - slope * np.maximum(P - deadband, 0.0)
    fit = BlockedForceFit(
        deadband_Pa=deadband, slope_N_per_Pa=slope, pressure_Pa=P, tension_N=F, inlier=inlier,
        rms_N=float(np.sqrt(np.mean(residual[inlier] ** 2))),
    )  # fmt: skip
    if rest_diameter_m is not None:
        fit.rest_diameter_m = rest_diameter_m
        fit.theta_rest_deg = braid_angle_from_slope(slope, rest_diameter_m)
    return fit


def _reject_outliers(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Inlier mask. Few points (the paper's five pressures): a point is judged by its residual
    from the line fitted WITHOUT it (so it cannot pull the line towards itself) against the
    scatter of the others; many points (a pressure ramp): residuals against 1.4826 x their median
    absolute deviation. Either way the residual must also exceed 1 % of the largest force."""
    inlier = np.ones(len(P), dtype=bool)
    floor = OUTLIER_FLOOR * float(np.max(np.abs(F)))
    for _ in range(len(P) // 3):
        idx = np.nonzero(inlier)[0]
        if len(idx) < 4:
            break
        if len(idx) <= 50:
            scores = []
            for i in idx:
                others = idx[idx != i]
                d, a = _hinge(P[others], F[others])
                r_others = F[others] - a * np.maximum(P[others] - d, 0.0)
                scale = math.sqrt(float(r_others @ r_others) / max(len(others) - 2, 1))
                r_i = abs(F[i] - a * max(P[i] - d, 0.0))
                scores.append((r_i / max(scale, 1e-12), r_i, scale, i))
            score, r_i, scale, worst = max(scores)
            reject = r_i > max(OUTLIER_SIGMAS * scale, floor)
        else:
            d, a = _hinge(P[idx], F[idx])
            residual = F - a * np.maximum(P - d, 0.0)
            sigma = 1.4826 * float(np.median(np.abs(residual[idx] - np.median(residual[idx]))))
            limit = max(OUTLIER_SIGMAS * sigma, floor)
            bad = idx[np.abs(residual[idx]) > limit]
            if len(bad) == 0 or len(bad) > len(P) // 3:
                break
            inlier[bad] = False
            continue
        if not reject:
            break
        inlier[worst] = False
    return inlier


def braid_angle_from_slope(slope_N_per_Pa: float, rest_diameter_m: float) -> float:
    """Eq. 9 solved for theta: tan^2 theta = (slope / (pi D^2 / 4) + 1) / 2."""
    area = math.pi * rest_diameter_m**2 / 4
    tan_sq = (slope_N_per_Pa / area + 1.0) / 2.0
    if tan_sq <= 0:
        raise ValueError(
            f"blocked force: the muscle pushes {-slope_N_per_Pa / area:.3g} x harder than a piston of "
            f"its resting diameter ({rest_diameter_m * 1e3:.4g} mm); Eq. 9 has no braid angle for that "
            "(is the resting diameter right?)"
        )
    return math.degrees(math.atan(math.sqrt(tan_sq)))


def _hinge(P: np.ndarray, F: np.ndarray) -> tuple[float, float]:
    """Least-squares a, d of F = a max(P - d, 0), d in [0, 0.9 max P]."""

    def slope_at(d):
        h = np.maximum(P - d, 0.0)
        hh = float(h @ h)
        return (float(h @ F) / hh if hh > 0 else 0.0), h

    def cost(d):
        a, h = slope_at(d)
        r = F - a * h
        return float(r @ r)

    hi = 0.9 * float(np.max(P))
    if hi <= 0:
        return 0.0, 0.0
    # The line fit's zero crossing is the answer when every point is above it (the paper's case).
    a, b = np.polyfit(P, F, 1)
    if a != 0 and 0 <= -b / a < float(np.min(P)):
        return float(-b / a), float(a)
    grid = np.linspace(0.0, hi, 181)
    costs = [cost(d) for d in grid]
    i = int(np.argmin(costs))
    lo_d, hi_d = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    best = minimize_scalar(cost, bounds=(lo_d, hi_d), method="bounded", options={"xatol": 1e-6 * hi})
    d = float(best.x) if best.fun <= costs[i] else float(grid[i])
    return d, slope_at(d)[0]
