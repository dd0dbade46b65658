"""``calibrate``: dead band, braid angle and every stress law from recordings, with held-out errors.

The procedure (paper Sec. 4.3-4.8, automated):

1. blocked forces at the resting length -> dead band (zero crossing, Sec. 4.3) and, from the
   slope and the resting diameter, the resting braid angle (Sec. 4.4); outliers rejected;
2. each stress law fitted with the geometry that braid angle gives (``fit.fit_law``);
3. held-out error: leave one pressure level out (for isobaric strokes; one recording out for
   other data), re-run 1-2 on the rest, predict the level left out; the RMS over all held-out
   samples;
4. best law: the smallest held-out RMS error (the smallest in-sample one if nothing was held out);
   within 1 % of it, the law with the fewest coefficients.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..muscle import Muscle, MuscleError
from ..musclefile import save_muscle
from ..recordings import MIN_SAMPLES, Recording, check_for_fit, refuse_copies
from ..stress import LAW_NAMES, LAWS, StressLaw
from .blocked import BlockedForceFit, blocked_points, fit_blocked
from .data import Samples, pool
from .fit import LawFit, Problem, fit_law

#: A placeholder law for the base muscle before any law is fitted (linear laws are always stable).
_PLACEHOLDER = StressLaw("linear", (1.0e6, 0.0))


@dataclass
class Calibration:
    """Everything ``calibrate`` found. ``muscle`` is the best law's muscle."""

    deadband_Pa: float
    theta_rest_deg: float
    blocked: BlockedForceFit
    fits: dict[str, LawFit]
    heldout_rms_N: dict[str, float | None]
    best_law: str
    seconds: float
    problem: Problem
    geometry_theta_rest_deg: float  # the muscle's braid angle before calibration

    @property
    def muscle(self) -> Muscle:
        """The calibrated muscle with the best law (lowest error)."""
        return self.fits[self.best_law].muscle

    def to_json(self) -> dict:
        """The summary: {"deadband_kPa" (the calibrated muscle's), "blocked_deadband_kPa" (the
        Sec. 4.3 estimate), "theta_rest_deg", "laws": {...}, "best_law"}."""
        return {
            "deadband_kPa": self.muscle.deadband_Pa / 1e3,
            "blocked_deadband_kPa": self.deadband_Pa / 1e3,
            "theta_rest_deg": self.theta_rest_deg,
            "laws": {
                law: {
                    "coefficients": fit.coefficients,
                    "eq14_error_pct": fit.eq14_error_pct,
                    "rms_N": fit.rms_N,
                    "heldout_rms_N": self.heldout_rms_N.get(law),
                    "stable": fit.stable,
                }
                for law, fit in self.fits.items()
            },
            "best_law": self.best_law,
        }

    def save_muscle(self, path, **extra):
        """A muscle file with every fitted law, the best one as default."""
        laws = {law: fit.stress for law, fit in self.fits.items()}
        summary = {
            "deadband_kPa": self.muscle.deadband_Pa / 1e3,
            "blocked_deadband_kPa": self.deadband_Pa / 1e3,
            "theta_rest_deg": self.theta_rest_deg,
            "theta_rest_deg_before": self.geometry_theta_rest_deg,
            "best_law": self.best_law,
            "rms_N": {law: fit.rms_N for law, fit in self.fits.items()},
            "heldout_rms_N": self.heldout_rms_N,
            "eq14_error_pct": {law: fit.eq14_error_pct for law, fit in self.fits.items()},
            "sources": [r.meta.get("source", "") for r in self.problem.recordings],
        }
        return save_muscle(path, self.muscle, laws, calibration=summary, **extra)


def resolve_laws(laws) -> tuple[str, ...]:
    """Law names from ``"all"``/None, one name or a list; an unknown name raises ``ValueError``."""
    if laws in (None, "all"):
        return LAW_NAMES
    names = (laws,) if isinstance(laws, str) else tuple(laws)
    if not names:  # min() over no fits said "arg is an empty sequence"
        raise ValueError(f"no stress law given: name at least one of {', '.join(LAW_NAMES)}, or 'all'")
    for name in names:
        if name not in LAW_NAMES:
            raise ValueError(f"unknown stress law '{name}' (known: {', '.join(LAW_NAMES)}, or 'all')")
    return names


def geometry_from_blocked(
    samples: Samples, muscle: Muscle, estimate_theta: bool = True
) -> tuple[BlockedForceFit, Muscle]:
    """Sec. 4.3-4.4 on pooled samples: the blocked-force fit and the muscle with its results."""
    P, F = blocked_points(samples, muscle.rest_length_m)
    blocked = fit_blocked(P, F, muscle.rest_diameter_m)
    theta = blocked.theta_rest_deg if estimate_theta else muscle.theta_rest_deg
    try:
        base = replace(muscle, theta_rest_deg=theta, deadband_Pa=blocked.deadband_Pa, stress=_PLACEHOLDER)
    except MuscleError as err:
        raise ValueError(
            f"the braid angle from the blocked forces ({theta:.3f} deg) gives an impossible muscle: {err}"
        ) from None
    return blocked, base


def calibrate(
    recordings: list[Recording],
    muscle: Muscle,
    laws="all",
    *,
    estimate_theta: bool = True,
    fit_deadband: bool = False,
    objective: str | None = None,
    heldout: bool = True,
    heldout_objective: str | None = None,
    n: int = 5,
    allow=(),
) -> Calibration:
    """Calibrate ``muscle`` (its geometry: rest length and diameter, bladder volume; its
    ``tension_only``) on recordings. ``estimate_theta=False`` keeps the muscle's braid angle
    (the paper's choice for its final fits); ``fit_deadband=True`` refits the dead band with each
    law instead of keeping the Sec. 4.3 estimate; ``objective`` as in :func:`fit.fit_law`.
    ``heldout_objective``: the criterion of the held-out refits; ``None`` (default) = the same as
    ``objective``, so the held-out error measures exactly the procedure that made the fits.
    The recordings pass the ``efam calibrate`` plausibility checks first
    (``recordings.check_for_fit``): a failed check not named in ``allow`` (or ``allow="all"``)
    raises ``PlausibilityError``.
    """
    t0 = time.perf_counter()
    names = resolve_laws(laws)
    if not isinstance(muscle, Muscle):
        raise TypeError(f"calibrate: muscle must be a Muscle (load_muscle), got {type(muscle).__name__}")
    # n: the Eq. 14 comparison points per pressure level (Delta L = k/n Delta L_max); n = 0 gave
    # a fit at the bounds and an Eq. 14 error of NaN without a word
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(
            f"calibrate: n (comparison points per pressure level) must be a whole number >= 1, got {n!r}"
        )
    recordings = [recordings] if isinstance(recordings, Recording) else list(recordings)
    for r in recordings:
        if not isinstance(r, Recording):  # a file name's length was counted as its samples
            raise TypeError(
                f"calibrate: recordings must be Recording objects (read_csv), got {type(r).__name__}"
            )
    refuse_copies(recordings)
    total = sum(len(r) for r in recordings)
    if total < MIN_SAMPLES:
        # three rows gave a muscle file without a word
        raise ValueError(f"too few samples to calibrate: {total} in all (at least {MIN_SAMPLES})")
    forces = np.concatenate([r.force_N for r in recordings])
    if np.ptp(forces) == 0.0:
        # a dead load cell let through with --allow force-dead: a fit has nothing to follow (it
        # ended in scipy's "c must not contain values inf, nan, or None")
        raise ValueError(
            f"the force is {forces[0]:g} N in every sample: a stress law cannot be calibrated "
            "against a constant force (a dead or disconnected load cell?)"
        )
    check_for_fit(recordings, muscle, allow, "calibrate")
    samples = pool(recordings)
    blocked, base = geometry_from_blocked(samples, muscle, estimate_theta)
    problem = Problem(base, recordings, n=n, samples=samples)
    fits = {law: fit_law(base, problem, law, fit_deadband, objective=objective) for law in names}
    fold_objective = objective if heldout_objective is None else heldout_objective
    held = (
        _heldout(recordings, samples, muscle, names, estimate_theta, fit_deadband, fold_objective, n)
        if heldout
        else {}
    )
    scores = {law: held.get(law) for law in names}
    best = best_law(names, scores, fits)
    return Calibration(
        deadband_Pa=blocked.deadband_Pa, theta_rest_deg=base.theta_rest_deg, blocked=blocked, fits=fits,
        heldout_rms_N=scores, best_law=best, seconds=time.perf_counter() - t0, problem=problem,
        geometry_theta_rest_deg=muscle.theta_rest_deg,
    )  # fmt: skip


#: Laws whose held-out errors are within this fraction of the best are a tie.
TIE_FRACTION = 0.01


def best_law(names, heldout: dict, fits: dict[str, LawFit]) -> str:
    """Smallest held-out RMS (in-sample RMS when nothing was held out); among laws within 1 % of
    it, the one with the fewest coefficients (the linear law before a four-coefficient law)."""
    scores = heldout if heldout and all(v is not None and math.isfinite(v) for v in heldout.values()) else {
        law: fits[law].rms_N for law in names
    }  # fmt: skip
    lowest = min(scores[law] for law in names)
    tied = [law for law in names if scores[law] <= lowest * (1 + TIE_FRACTION)]
    return min(tied, key=lambda law: (len(LAWS[law].params), scores[law]))


def folds(samples: Samples) -> list[np.ndarray]:
    """Held-out groups: one per pressure level (isobaric data), else one per recording."""
    if samples.isobaric:
        return [samples.level == j for j in range(len(samples.levels_Pa))]
    recs = np.unique(samples.recording)
    return [samples.recording == r for r in recs] if len(recs) > 1 else []


def _heldout(recordings, samples, muscle, names, estimate_theta, fit_deadband, objective, n) -> dict:
    """Pooled RMS over each fold's held-out samples, the model refitted without them."""
    sq = {law: 0.0 for law in names}
    count = 0
    for out in folds(samples):
        train = _split(recordings, samples, ~out)
        test = _split(recordings, samples, out)
        train_samples = pool(train)
        try:
            _, base = geometry_from_blocked(train_samples, muscle, estimate_theta)
        except ValueError:
            return {}  # too few pressures left to estimate the dead band: no held-out error
        problem = Problem(base, train, n=n, samples=train_samples)
        fold_objective = objective if problem.points is not None else "lsq"
        test_samples = pool(test)
        count += len(test_samples)
        for law in names:
            fit = fit_law(base, problem, law, fit_deadband, objective=fold_objective)
            predicted = fit.muscle.tension(test_samples.pressure_Pa, test_samples.length_m)
            sq[law] += float(np.sum((predicted - test_samples.tension_N) ** 2))
    if count == 0:
        return {}
    return {law: math.sqrt(sq[law] / count) for law in names}


def _split(recordings: list[Recording], samples: Samples, mask: np.ndarray) -> list[Recording]:
    """The recordings restricted to the pooled samples in ``mask`` (empty ones dropped)."""
    out = []
    start = 0
    for r in recordings:
        part = mask[start : start + len(r)]
        start += len(r)
        if part.any():
            out.append(r.subset(part))
    return out
