"""What a user asks the sizing for (SI inside; the CLI converts kPa and mm)."""

from __future__ import annotations

import math
from dataclasses import dataclass

#: the largest stroke accepted (the paper's muscles reach about 1; MTS stroke 0.98 of rest)
MAX_STROKE = 5.0


class RequestError(ValueError):
    """A request that cannot be physical; the message names the parameter and its unit."""


@dataclass(frozen=True)
class Request:
    """A sizing request.

    ``stroke``: extension as a fraction of the resting length (0.98 = 98 %, the paper's free
    extension at 517.1 kPa). ``force_N``: the push the muscle (or, with ``bundle``, the whole
    section) must still deliver when extended by ``stroke`` at ``pressure_Pa``; 0 asks for a free
    stroke. ``blocked_force_N``: an optional push at the resting length. ``length_m``: the
    resting length (default: the shortest the rules allow). ``max_diameter_m``: the largest
    resting diameter. ``bundle``: M muscles in parallel (a section) sharing the forces.
    ``payload_kg``: a tip payload for the bundle's deflection. ``unguided``: the muscle pushes
    without a guide tube, so Euler buckling limits it.
    """

    stroke: float
    force_N: float
    pressure_Pa: float
    length_m: float | None = None
    max_diameter_m: float | None = None
    blocked_force_N: float | None = None
    bundle: int | None = None
    payload_kg: float = 0.0
    unguided: bool = False

    def __post_init__(self):
        def bad(name, value, why):
            raise RequestError(f"{name}: {why}, got {value!r}")

        def finite(name, value):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                bad(name, value, "must be a finite number")

        finite("stroke", self.stroke)
        if not 0 < self.stroke <= MAX_STROKE:
            hint = " (a fraction: 0.98 means 98 %)" if self.stroke > MAX_STROKE else ""
            bad(
                "stroke",
                self.stroke,
                f"must be a fraction of the resting length in (0, {MAX_STROKE:g}]{hint}",
            )
        finite("force_N", self.force_N)
        if self.force_N < 0:
            bad("force_N", self.force_N, "must be >= 0 N (0 asks for a free stroke)")
        finite("pressure_Pa", self.pressure_Pa)
        if not self.pressure_Pa > 0:
            bad("pressure_Pa", self.pressure_Pa, "must be a positive gauge pressure in Pa")
        for name in ("length_m", "max_diameter_m", "blocked_force_N"):
            value = getattr(self, name)
            if value is not None:
                finite(name, value)
                if not value > 0:
                    bad(name, value, "must be positive")
        if self.length_m is not None and not 0.005 <= self.length_m <= 5.0:
            bad("length_m", self.length_m, "must be a resting length in metres, 0.005-5 m")
        if self.bundle is not None and (isinstance(self.bundle, bool) or int(self.bundle) != self.bundle
                                        or self.bundle < 3):  # fmt: skip
            bad("bundle", self.bundle, "must be a whole number of muscles >= 3")
        finite("payload_kg", self.payload_kg)
        if not isinstance(self.unguided, bool):  # "no" or "false" would be truthy: guided taken for unguided
            bad("unguided", self.unguided, "must be True or False")
        if self.payload_kg < 0:
            bad("payload_kg", self.payload_kg, "must be >= 0 kg")
        if self.payload_kg and self.bundle is None:
            bad(
                "payload_kg",
                self.payload_kg,
                "applies to a bundle (bundle=M); for one muscle add its weight to force_N",
            )

    @property
    def muscles(self) -> int:
        """Muscles sharing the load: the bundle size, or 1 for a single muscle."""
        return self.bundle or 1

    @property
    def muscle_force_N(self) -> float:
        """What one muscle must push at the stroke (a bundle's muscles share the force)."""
        return self.force_N / self.muscles

    @property
    def muscle_blocked_force_N(self) -> float | None:
        """Blocked force each muscle must give (N), or None when no blocked force is asked."""
        return None if self.blocked_force_N is None else self.blocked_force_N / self.muscles
