"""The reachable workspace of an EFAM arm, and the targets the tasks draw from it.

A section reaches a shape when its muscles can be pressurised into it. Unloaded, a section of
muscles that are each at their own free length is in equilibrium (no muscle pushes), and under
constant curvature muscle i of a section with arc length s, curvature kappa and bend direction
phi has the length ``L_i = s (1 - r_i kappa cos(phi - alpha_i))``. So a shape is reachable when
every ``L_i`` lies between the muscle's free lengths at the lowest and the highest admissible
pressure, and the pressures are the inverse of the free length at ``L_i``.

The workspace is sampled in that shape space (arc length uniform between the free lengths of
the pressure range, bend uniform over the disk of bends up to ``max_bend_deg``, direction
uniform), the pressures follow, and the suite's statics (the arm's own weight, a payload)
gives the tip where the arm comes to rest under them. Every sample is therefore a target the
arm reaches at rest with admissible pressures, by the reference; the bend cap keeps targets
away from the folded-over shapes where the muscles would touch each other and where the
reference is least trustworthy.

Pressures are fractions of each muscle's rated pressure (the suite's action scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import arm_glue

#: pressure fractions the workspace uses: above the muscles' dead band (the free length barely
#: moves below ~0.1 of rated) and short of the rated pressure
DEFAULT_PRESSURE_RANGE = (0.15, 0.9)


@dataclass(frozen=True)
class WorkspaceLimits:
    """The part of the arm's shape space the tasks use."""

    pressure_range: tuple[float, float] = DEFAULT_PRESSURE_RANGE
    max_bend_deg: float = 90.0  # per section

    def __post_init__(self):
        lo, hi = self.pressure_range
        if not (0.0 <= lo < hi <= 1.0):
            raise ValueError(
                f"workspace: pressure_range must satisfy 0 <= lo < hi <= 1, got {self.pressure_range}"
            )
        if not (0.0 <= self.max_bend_deg <= 180.0):
            raise ValueError(f"workspace: max_bend_deg must be in [0, 180], got {self.max_bend_deg}")


def sample_section_shape(
    section, max_pressure_Pa: float, limits: WorkspaceLimits, random, max_tries: int = 10_000
):
    """One reachable unloaded shape of a section: ``(s, kx, ky)`` and its muscles' pressures
    as fractions of ``max_pressure_Pa`` (rejection sampling in shape space)."""
    muscles, radii, angles = section
    lo, hi = limits.pressure_range
    short = np.array([arm_glue.free_length_m(m, lo * max_pressure_Pa, max_pressure_Pa) for m in muscles])
    long_ = np.array([arm_glue.free_length_m(m, hi * max_pressure_Pa, max_pressure_Pa) for m in muscles])
    s_lo, s_hi = short.max(), long_.min()
    if s_lo >= s_hi:
        raise ValueError("workspace: the muscles' free-length ranges do not overlap in pressure_range")
    max_bend = math.radians(limits.max_bend_deg)
    for _ in range(max_tries):
        s = random.uniform(s_lo, s_hi)
        bend = max_bend * math.sqrt(random.uniform())
        phi = random.uniform(-math.pi, math.pi)
        kappa = bend / s
        lengths = s * (1.0 - radii * kappa * np.cos(phi - angles))
        if np.all(lengths >= short) and np.all(lengths <= long_):
            fractions = np.array(
                [
                    arm_glue.pressure_for_free_length(m, L, max_pressure_Pa) / max_pressure_Pa
                    for m, L in zip(muscles, lengths)
                ]
            )
            return (s, kappa * math.cos(phi), kappa * math.sin(phi)), fractions
    raise ValueError(f"workspace: no reachable shape found in {max_tries} tries (limits {limits})")


def sample_pressures(spec, random, limits: WorkspaceLimits = WorkspaceLimits()):
    """Pressure fractions (one per muscle, base section first) of a random reachable shape."""
    fractions = [
        sample_section_shape(section, spec.max_pressure_Pa, limits, random)[1]
        for section in arm_glue.section_muscles(spec)
    ]
    return np.concatenate(fractions)


def sample_target(spec, random, limits: WorkspaceLimits = WorkspaceLimits(), payload_kg: float = 0.0):
    """A reachable tip position (base frame, m) and the pressure fractions that reach it by the
    reference statics (with the arm's weight and ``payload_kg`` at the tip)."""
    fractions = sample_pressures(spec, random, limits)
    tip, _ = arm_glue.reference_tip(spec, fractions * spec.max_pressure_Pa, payload_kg=payload_kg)
    return tip, fractions


@dataclass(frozen=True)
class Workspace:
    """Sampled reachable tip positions (base frame, m) and the pressure fractions behind them."""

    tips_m: np.ndarray  # (N, 3)
    pressure_fractions: np.ndarray  # (N, muscles)
    limits: WorkspaceLimits

    @property
    def extent_m(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners of the samples' bounding box."""
        return self.tips_m.min(axis=0), self.tips_m.max(axis=0)

    @property
    def radial_reach_m(self) -> float:
        """Largest distance of a sample from the arm's axis."""
        return float(np.hypot(self.tips_m[:, 0], self.tips_m[:, 1]).max())


def compute_workspace(spec, samples: int = 200, seed: int = 0, limits: WorkspaceLimits = WorkspaceLimits()):
    """Sample the reachable workspace of ``spec`` (the suite's statics with gravity)."""
    if samples < 1:
        raise ValueError(f"workspace: samples must be >= 1, got {samples}")
    random = np.random.RandomState(seed)
    tips, fractions = [], []
    for _ in range(samples):
        tip, u = sample_target(spec, random, limits)
        tips.append(tip)
        fractions.append(u)
    return Workspace(np.array(tips), np.array(fractions), limits)
