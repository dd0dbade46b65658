"""Bench recordings of a muscle: time, length, pressure and force, SI inside.

A :class:`Recording` is what every consumer (calibration, diagnosis, the rig replay) takes. CSV
reading and writing with unit-suffixed headers lives here too (see ``read_csv``).

Force sign: ``force_N`` is positive when the muscle pushes its ends apart (the package's MuJoCo
convention); a ``tension_N`` column (positive = pulls, the paper's Eq. 2 sign) is negated on read.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Recording:
    """One bench test. Arrays share one length; ``meta`` keeps provenance (file, rest length...)."""

    time_s: np.ndarray
    length_m: np.ndarray
    pressure_Pa: np.ndarray
    force_N: np.ndarray  # positive = pushes the ends apart
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("time_s", "length_m", "pressure_Pa", "force_N"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float))
        n = {len(self.time_s), len(self.length_m), len(self.pressure_Pa), len(self.force_N)}
        if len(n) != 1:
            raise ValueError("recording arrays must all have the same length")

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def tension_N(self) -> np.ndarray:
        """Paper sign (Eq. 2): positive when the muscle pulls."""
        return -self.force_N
