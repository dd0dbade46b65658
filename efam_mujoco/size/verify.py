"""Every proposed design checked in the MuJoCo rig (efam_mujoco.rig), analytic beside simulated.

The rig runs the C plugin, an implementation independent of the Python reference the search
used: the stroke rig (displacement control) gives the force at the required stroke and the
blocked force; the free rig the free stroke; the loaded rig (a constant compressive load equal
to the required force) the stroke the muscle reaches while pushing it.
"""

from __future__ import annotations

from dataclasses import dataclass

from .. import rig
from ..muscle import Muscle
from . import constraints as con
from .request import Request


@dataclass(frozen=True)
class Pair:
    """One quantity, analytic (Eq. 2 / Eq. 9) and from MuJoCo."""

    analytic: float
    mujoco: float

    @property
    def relative_difference(self) -> float:
        """Relative difference: abs(MuJoCo - analytic) / abs(analytic)."""
        scale = max(abs(self.analytic), 1e-12)
        return abs(self.mujoco - self.analytic) / scale

    def to_dict(self) -> dict:
        """The pair as plain JSON types."""
        return {
            "analytic": self.analytic,
            "mujoco": self.mujoco,
            "relative_difference": self.relative_difference,
        }


@dataclass(frozen=True)
class Verification:
    """A design in the rig at the request's pressure (push positive; strokes as fractions)."""

    pressure_Pa: float
    force_at_stroke_N: Pair
    blocked_force_N: Pair
    free_stroke: Pair
    stroke_at_force: Pair
    meets_request: bool | None  # MuJoCo within 2 % of the request; None: the rig did not settle

    @property
    def max_relative_difference(self) -> float:
        """The largest relative analytic-vs-MuJoCo difference over all compared quantities."""
        return max(p.relative_difference for p in self.pairs().values())

    def pairs(self) -> dict[str, Pair]:
        """The compared quantities by name, each an analytic/MuJoCo pair."""
        return {
            "force_at_stroke_N": self.force_at_stroke_N,
            "blocked_force_N": self.blocked_force_N,
            "free_stroke": self.free_stroke,
            "stroke_at_force": self.stroke_at_force,
        }

    def to_dict(self) -> dict:
        """The verification as plain JSON types."""
        out = {k: v.to_dict() for k, v in self.pairs().items()}
        out["meets_request_in_mujoco"] = self.meets_request
        return out


#: how close MuJoCo must come to the request for a design to count as meeting it
TOLERANCE = 0.02


#: simulated time the free and loaded rigs get to come to rest (long, slender muscles ring slowly)
SETTLE_S = 60.0


def _settled_stroke(muscle: Muscle, pressure_Pa: float, load_N: float) -> float:
    """Stroke at rest on the free (load 0) or loaded rig; NaN if it does not come to rest."""
    try:
        length = rig.equilibrium_length(muscle, pressure_Pa, load_N=load_N, max_time_s=SETTLE_S)
    except RuntimeError:
        return float("nan")
    return length / muscle.rest_length_m - 1.0


def verify_design(muscle: Muscle, request: Request) -> Verification:
    """Run the rigs for one muscle at the request's pressure."""
    P = request.pressure_Pa
    rest = muscle.rest_length_m
    stroke_length = rest * (1 + request.stroke)
    blocked_mj, at_stroke_mj = rig.stroke_forces(muscle, P, [rest, stroke_length])
    free_length = float(muscle.free_length(P))
    free_mj = _settled_stroke(muscle, P, 0.0)
    F = request.muscle_force_N
    analytic_stroke = con.stroke_at_force(muscle, P, F, free_length)
    loaded_mj = _settled_stroke(muscle, P, F) if F > 0 else free_mj
    # None: the rig did not come to rest in SETTLE_S (a very long, soft muscle), so not checked
    meets = None
    if loaded_mj == loaded_mj:
        meets = bool((at_stroke_mj >= F * (1 - TOLERANCE) if F > 0 else True)
                     and loaded_mj >= request.stroke * (1 - TOLERANCE))  # fmt: skip
    return Verification(
        P,
        Pair(float(muscle.push(P, stroke_length)), float(at_stroke_mj)),
        Pair(float(muscle.blocked_push(P)), float(blocked_mj)),
        Pair(free_length / rest - 1.0, float(free_mj)),
        Pair(analytic_stroke, float(loaded_mj)),
        meets,
    )
