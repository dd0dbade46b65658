"""Recordings pooled for fitting: pressure levels, stroke branches, the paper's comparison points.

A bench file may hold several pressures and loading and unloading. Fitting needs to know

* which samples belong to one isobaric stroke (a *pressure level*): samples are clustered by
  pressure; a cluster narrower than the tolerance with enough samples is a level;
* along a stroke, which samples move away from the resting length (*loading*) and which move back
  (*unloading*);
* the paper's Eq. 14 comparison points: at each level the force at ``Delta L = k/n Delta L_max``
  (k = 1..n), where ``Delta L_max`` is the largest length change reached at that level.

Force at a comparison length (stated in docs/calibration.md): on each branch a local quadratic
(``local_value``) is fitted to the samples within 8 % of ``Delta L_max`` of that length, and the
experimental force is the MEAN of the loading and unloading values (the model has no hysteresis,
so it is compared with the middle of the loop); a level with one branch uses that branch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..recordings import Recording

#: Half-width of the window around a comparison length, as a fraction of Delta L_max.
WINDOW_FRACTION = 0.08
#: Strain of the paper's "blocked force" comparison row (Table 3 footnote: eps = +-5e-4).
BLOCKED_STRAIN = 5e-4


@dataclass
class Samples:
    """All samples of a set of recordings, SI, tension in the paper sign (positive = pulls)."""

    time_s: np.ndarray
    length_m: np.ndarray
    pressure_Pa: np.ndarray
    tension_N: np.ndarray
    recording: np.ndarray  # index into the recordings list
    level: np.ndarray  # index into levels_Pa, -1 = between levels (a pressure ramp)
    levels_Pa: np.ndarray

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def isobaric(self) -> bool:
        """True when most samples sit on a few constant pressures (isobaric strokes)."""
        return len(self.levels_Pa) >= 2 and np.mean(self.level >= 0) >= 0.9

    def take(self, mask) -> Samples:
        """The samples where ``mask`` holds (a boolean or index array); the levels stay."""
        return Samples(
            self.time_s[mask], self.length_m[mask], self.pressure_Pa[mask], self.tension_N[mask],
            self.recording[mask], self.level[mask], self.levels_Pa,
        )  # fmt: skip


def pressure_tolerance(pressures_Pa: np.ndarray) -> float:
    """Pressures closer than this are one level: 3 kPa or 2 % of the largest pressure."""
    return max(3e3, 0.02 * float(np.max(np.abs(pressures_Pa), initial=0.0)))


def pool(recordings: list[Recording], tol_Pa: float | None = None) -> Samples:
    """Concatenate recordings and cluster their pressures into levels."""
    if not recordings:
        raise ValueError("no recordings to fit")
    for r in recordings:
        if len(r) == 0:
            raise ValueError(f"{r.meta.get('source', 'recording')}: no samples")
    P = np.concatenate([r.pressure_Pa for r in recordings])
    tol = pressure_tolerance(P) if tol_Pa is None else tol_Pa
    source = np.concatenate([np.full(len(r), i) for i, r in enumerate(recordings)])
    levels, level = _levels(P, tol, source, np.array([len(r) for r in recordings]))
    return Samples(
        time_s=np.concatenate([r.time_s for r in recordings]),
        length_m=np.concatenate([r.length_m for r in recordings]),
        pressure_Pa=P,
        tension_N=np.concatenate([r.tension_N for r in recordings]),
        recording=source,
        level=level,
        levels_Pa=levels,
    )


#: A pressure level holds at least this many samples, and at least this fraction of the pooled
#: samples or of its own recording's (so one long file pooled with short ones does not push the
#: short files' levels under the threshold and turn isobaric strokes into "ramps").
MIN_LEVEL_SAMPLES = 20
MIN_LEVEL_FRACTION = 0.01


def _levels(P: np.ndarray, tol: float, source=None, lengths=None) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(P)
    sorted_p = P[order]
    breaks = np.nonzero(np.diff(sorted_p) > tol)[0] + 1
    min_count = max(MIN_LEVEL_SAMPLES, int(MIN_LEVEL_FRACTION * len(P)))
    levels: list[float] = []
    level = np.full(len(P), -1)
    for chunk in np.split(np.arange(len(P)), breaks):
        values = sorted_p[chunk]
        width = np.percentile(values, 95) - np.percentile(values, 5)
        if width <= tol and (len(chunk) >= min_count or _holds_own_level(order[chunk], source, lengths)):
            level[order[chunk]] = len(levels)
            levels.append(float(np.median(values)))
    return np.array(levels), level


def _holds_own_level(members: np.ndarray, source, lengths) -> bool:
    """A cluster that is a level of one of its recordings: at least MIN_LEVEL_FRACTION of that
    recording's samples (and MIN_LEVEL_SAMPLES)."""
    if source is None or len(members) < MIN_LEVEL_SAMPLES:
        return False
    counts = np.bincount(source[members], minlength=len(lengths))
    return bool(np.any(counts >= np.maximum(MIN_LEVEL_SAMPLES, MIN_LEVEL_FRACTION * lengths)))


def branches(length_m: np.ndarray, direction: float) -> np.ndarray:
    """+1 where the length moves away from rest (loading), -1 back (unloading), 0 held.

    ``length_m`` is one stroke in time order; ``direction`` is +1 for a stroke that lengthens the
    muscle, -1 for one that shortens it. The velocity is a centred difference over a few samples
    so that length-sensor noise does not flip the branch.
    """
    n = len(length_m)
    if n < 3:
        return np.zeros(n, dtype=int)
    w = max(1, n // 400)
    padded = np.concatenate([np.full(w, length_m[0]), length_m, np.full(w, length_m[-1])])
    velocity = padded[2 * w :] - padded[: -2 * w]
    span = max(float(np.ptp(length_m)), 1e-12)
    moving = np.abs(velocity) > 1e-6 * span
    return np.where(moving, np.sign(velocity) * np.sign(direction), 0).astype(int)


def local_value(x: np.ndarray, y: np.ndarray, at: float, half_width: float) -> float:
    """Local polynomial fit of y(x) over abs(x - at) <= half_width, evaluated at ``at``.

    A quadratic with 6 or more samples (a stroke's start or end is one-sided, where a straight
    line would be biased by the curvature), a straight line with 3-5, NaN with fewer.
    """
    near = np.abs(x - at) <= half_width
    count = np.count_nonzero(near)
    if count < 3:
        return float("nan")
    xs, ys = (x[near] - at) / half_width, y[near]
    if np.ptp(xs) <= 0:
        return float(np.mean(ys))
    degree = 2 if count >= 6 and len(np.unique(np.round(xs, 9))) >= 3 else 1
    return float(np.polyfit(xs, ys, degree)[-1])


@dataclass
class ComparisonPoints:
    """The experimental forces Eq. 14 compares with, one row per (level, k)."""

    pressure_Pa: np.ndarray
    length_m: np.ndarray
    tension_N: np.ndarray
    level: np.ndarray  # index into Samples.levels_Pa
    k: np.ndarray  # 1..n: Delta L = k/n Delta L_max; 0: the blocked-force row (eps = 5e-4)
    recording: np.ndarray  # the recording (so the muscle) each point comes from
    n: int

    def take(self, mask) -> ComparisonPoints:
        """The points where ``mask`` holds (a boolean or index array)."""
        return ComparisonPoints(
            self.pressure_Pa[mask], self.length_m[mask], self.tension_N[mask], self.level[mask],
            self.k[mask], self.recording[mask], self.n,
        )  # fmt: skip


def comparison_points(samples: Samples, rest_length_m, n: int = 5) -> ComparisonPoints | None:
    """Eq. 14's points for isobaric data (None for other data, e.g. isometric pressure ramps).

    ``rest_length_m`` is one length or an array (one per recording, for several muscles).
    """
    if not samples.isobaric:
        return None
    rest_of = np.broadcast_to(np.asarray(rest_length_m, dtype=float), (int(samples.recording.max()) + 1,))
    rows = []
    for j, p_level in enumerate(samples.levels_Pa):
        at_level = samples.level == j
        for rec in np.unique(samples.recording[at_level]):
            seg = at_level & (samples.recording == rec)
            points = _level_points(samples.take(seg), float(rest_of[rec]), p_level, j, n)
            rows += [point + (rec,) for point in points]
    if not rows:
        return None
    data = np.array(rows)
    keep = np.isfinite(data[:, 2])
    data = data[keep]
    ints = data[:, 3:].astype(int)
    return ComparisonPoints(data[:, 0], data[:, 1], data[:, 2], ints[:, 0], ints[:, 1], ints[:, 2], n)


def _level_points(seg: Samples, rest: float, p_level: float, j: int, n: int) -> list[tuple]:
    order = np.argsort(seg.time_s)
    L, F = seg.length_m[order], seg.tension_N[order]
    dL = L - rest
    far = float(dL[np.argmax(np.abs(dL))])
    if abs(far) < 1e-6 * rest:
        return []  # an isometric hold at rest length: no stroke to compare along
    branch = branches(L, np.sign(far))
    half = max(WINDOW_FRACTION * abs(far), 1e-9)
    out = []
    targets = [(0, BLOCKED_STRAIN * rest * np.sign(far))] + [(k, k / n * far) for k in range(1, n + 1)]
    for k, delta in targets:
        values = [local_value(dL[branch == b], F[branch == b], delta, half) for b in (1, -1)]
        values = [v for v in values if np.isfinite(v)]
        if not values:  # no moving samples near: use all samples there
            values = [local_value(dL, F, delta, half)]
        out.append((p_level, rest + delta, float(np.mean(values)), j, k))
    return out
