"""Synthetic bench recordings from a known muscle model (for recovery tests and the bench).

The paper's test (Sec. 3): isobaric strokes at 15, 30, 45, 60 and 75 psi, from the resting length
out to the end of the machine's stroke (198 % of the resting length) at 5.1 mm/s and back, with
Gaussian noise on the force. ``synthesize`` reproduces that protocol with any muscle model, with
a short hold at the resting length first (the blocked-force reading taken while the pressure
settles; ``hold_s=0`` for none) and a sample rate the paper does not state (20 Hz by default).
"""

from __future__ import annotations

import numpy as np

from ..muscle import Muscle
from ..recordings import Recording
from ..units import PRESSURE

#: The paper's five test pressures: 15 ... 75 psi, in Pa.
PAPER_PRESSURES_PA = tuple(psi * PRESSURE["psi"] for psi in (15, 30, 45, 60, 75))
#: The paper's stroke limit: 198 % of the resting length (Sec. 3).
PAPER_STROKE_RATIO = 1.98
PAPER_SPEED_M_PER_S = 5.1e-3


def stroke_end(muscle: Muscle, ratio: float = PAPER_STROKE_RATIO) -> float:
    """Where the stroke ends: ``ratio`` x rest length, kept inside the model's admissible range."""
    span = muscle.max_length_m - muscle.min_length_m
    if ratio >= 1:
        return min(ratio * muscle.rest_length_m, muscle.max_length_m - 0.01 * span)
    return max(ratio * muscle.rest_length_m, muscle.min_length_m + 0.01 * span)


def synthesize(
    muscle: Muscle,
    pressures_Pa=PAPER_PRESSURES_PA,
    *,
    stroke_ratio: float = PAPER_STROKE_RATIO,
    speed_m_per_s: float = PAPER_SPEED_M_PER_S,
    rate_Hz: float = 20.0,
    noise_N: float = 0.5,
    hold_s: float = 2.0,
    seed: int = 0,
) -> list[Recording]:
    """One recording per pressure: a hold at rest, loading to the stroke end, unloading back.

    ``force_N`` is the model's push (MuJoCo sign) plus N(0, noise_N^2) noise.
    """
    rng = np.random.default_rng(seed)
    end = stroke_end(muscle, stroke_ratio)
    steps = max(int(abs(end - muscle.rest_length_m) / speed_m_per_s * rate_Hz), 10)
    out = np.linspace(muscle.rest_length_m, end, steps + 1)
    hold = np.full(int(round(hold_s * rate_Hz)), muscle.rest_length_m)
    lengths = np.concatenate([hold, out, out[-2::-1]])
    time = np.arange(len(lengths)) / rate_Hz
    recordings = []
    for p in pressures_Pa:
        force = muscle.push(p, lengths) + rng.normal(0.0, noise_N, len(lengths))
        meta = {"source": f"synthetic {muscle.name} {muscle.stress.name} {p / 1e3:.1f} kPa",
                "rest_length_m": muscle.rest_length_m}  # fmt: skip
        recordings.append(Recording(time, lengths, np.full(len(lengths), float(p)), force, meta))
    return recordings


def recovery_error(fitted: Muscle, truth: Muscle, pressures_Pa=PAPER_PRESSURES_PA, *,
                   stroke_ratio: float = PAPER_STROKE_RATIO, points: int = 200) -> float:  # fmt: skip
    """Largest force error over the tested range, relative to the force range at that pressure.

    For each test pressure p: max over the stroke of abs(F_fit - F_true) / (max F_true - min F_true),
    the range taken over the same stroke; the result is the largest over pressures. (A plain
    relative error is meaningless where the force crosses zero, which every EFAM stroke does.)
    """
    lengths = np.linspace(truth.rest_length_m, stroke_end(truth, stroke_ratio), points)
    worst = 0.0
    for p in pressures_Pa:
        true = truth.tension(p, lengths)
        span = float(np.ptp(true))
        worst = max(worst, float(np.max(np.abs(fitted.tension(p, lengths) - true))) / span)
    return worst
