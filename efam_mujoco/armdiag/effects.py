"""The library of arm-level effects: what each one changes in the model, and its parameters.

Each :class:`ArmEffect` maps its parameter values onto :class:`~.replay.Knobs` (model edits or
the command map); ``per_muscle`` effects are tried once per muscle and name it. The first block
(:data:`REFIT`) is what the arm model already has and is re-fitted within tight bounds before
any effect is tried (the calibration a lab would redo anyway).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .replay import Knobs, with_values


@dataclass(frozen=True)
class Param:
    """One fitted parameter, SI, with bounds; ``log``: searched on a log scale; ``grid``: start
    values tried before the local search."""

    key: str
    lo: float
    hi: float
    log: bool = False
    start: float | None = None
    grid: tuple = ()

    def to_unit(self, v: float) -> float:
        """``v`` mapped onto [0, 1] (log or linear between the bounds)."""
        if self.log:
            return (math.log(v) - math.log(self.lo)) / (math.log(self.hi) - math.log(self.lo))
        return (v - self.lo) / (self.hi - self.lo)

    def from_unit(self, u: float) -> float:
        """The value at ``u`` in [0, 1] (clipped), inverse of :meth:`to_unit`."""
        u = min(1.0, max(0.0, u))
        if self.log:
            return math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        return self.lo + u * (self.hi - self.lo)


@dataclass(frozen=True)
class ArmEffect:
    """A named piece of physics the arm model can switch on."""

    name: str
    summary: str
    equation: str
    params: tuple[Param, ...]
    per_muscle: bool = False
    switch_on: str = ""
    per_pair: bool = False  # tried once per ordered (receiving, source) muscle pair of a section

    def knobs(self, base: Knobs, values: dict, muscle: int | None = None) -> Knobs:
        """``base`` with this effect at ``values`` (and on ``muscle`` for per-muscle effects, the
        (receiving, source) muscle pair for per-pair effects)."""
        v = values
        if self.name == "payload":
            return with_values(base, payload_kg=v["mass_kg"])
        if self.name == "mount_tilt":
            return with_values(base, tilt_rad=(math.radians(v["tilt_x_deg"]), math.radians(v["tilt_y_deg"])))
        if self.name == "damping":
            return with_values(
                base,
                damping_axial=base.damping_axial * v["axial_factor"],
                damping_bend=base.damping_bend * v["bend_factor"],
                medium_viscosity_Pa_s=v["medium_Pa_s"],
            )
        if self.name == "pressure_lag":
            lag = np.array(base.lag_s)
            if muscle is None:
                lag[:] = np.maximum(lag, v["tau_s"])
            else:
                lag[muscle] = max(lag[muscle], v["tau_s"])
            return with_values(base, lag_s=lag)
        if self.name == "weak_muscle":
            gain, offset = np.array(base.gain), np.array(base.offset_Pa)
            gain[muscle] = v["pressure_factor"]
            offset[muscle] += v["drop_Pa"]
            return with_values(base, gain=gain, offset_Pa=offset)
        if self.name == "muscle_friction":
            return with_values(base, friction_N=v["f0_N"])
        if self.name == "cross_talk":
            receiver, source = muscle
            return with_values(base, coupling=tuple(base.coupling) + ((receiver, source, v["coupling"]),))
        if self.name == "compliant_mount":
            return with_values(
                base,
                mount_stiffness_N_m_per_rad=v["stiffness_N_m_per_rad"],
                mount_damping_N_m_s_per_rad=v["damping_N_m_s_per_rad"],
            )
        raise KeyError(self.name)


LIBRARY: tuple[ArmEffect, ...] = (
    ArmEffect(
        "payload", "an unmodelled mass at the tip (gripper, sensor, cable, load)",
        "body 'payload' of mass m at the tip site", (Param("mass_kg", 0.003, 1.5, True, grid=(0.01, 0.05, 0.2)),),
        switch_on="MJCF: body 'payload' under the tip disk",
    ),
    ArmEffect(
        "mount_tilt", "the arm's base is turned from where the model puts it",
        "base quat = Ry(b) Rx(a) base quat", (Param("tilt_x_deg", -12.0, 12.0, start=0.0), Param("tilt_y_deg", -12.0, 12.0, start=0.0)),
        switch_on="MJCF: body 'base' quaternion",
    ),
    ArmEffect(
        "damping", "more (or less) damping than the model has: axial and bending separately, and a viscous medium",
        "c_slide *= a, c_hinge *= b; fluid viscosity mu (MuJoCo inertia-box drag on every body)",
        (Param("axial_factor", 0.1, 40.0, True, start=1.0), Param("bend_factor", 0.1, 40.0, True, start=1.0, grid=(0.3, 3.0, 10.0)),
         Param("medium_Pa_s", 1e-3, 100.0, True, start=1e-3, grid=(3.0,))),
        switch_on="MJCF: joint damping, option viscosity",
    ),
    ArmEffect(
        "pressure_lag", "a slower valve or tube on one muscle (or on the supply of all)",
        "dP/dt = (P_cmd - P) / tau (actuator dyntype filterexact, dynprm[0] = tau)",
        (Param("tau_s", 0.01, 2.0, True, grid=(0.1, 0.3, 0.8)),), per_muscle=True,
        switch_on="MJCF: actuator dynprm",
    ),
    ArmEffect(
        "weak_muscle", "one muscle acts with a lower pressure than commanded (a leak or a failing bladder)",
        "P_eff = k P_cmd - d on that muscle",
        (Param("pressure_factor", 0.2, 1.0, start=0.9, grid=(0.4, 0.7, 0.9)), Param("drop_Pa", 0.0, 80e3, start=0.0)),
        per_muscle=True, switch_on="command map (custom numeric efam_ctrl_gain)",
    ),
    ArmEffect(
        "muscle_friction", "friction in the muscles (the muscle-level friction term on every muscle)",
        "dry friction force f0 in every muscle; segmented arm: joint frictionloss = f0 sum_i |dL_i/dq| "
        "(n f0 per extension slide, f0 sum |y_i| per bend hinge); unsegmented: efam.muscle friction.f0_N",
        (Param("f0_N", 0.2, 60.0, True, grid=(1.0, 5.0, 20.0)),),
        switch_on="MJCF: joint frictionloss (segmented) or efam.muscle config keys (unsegmented)",
    ),
    ArmEffect(
        "cross_talk", "the pressure of one muscle leaks into a neighbour's supply (named: the receiving muscle, "
        "from the source muscle)",
        "P_i = P_cmd,i + c (P_cmd,j - P_cmd,i) (i receives from j, same section)",
        (Param("coupling", -0.2, 0.6, start=0.0, grid=(0.25,)),), per_muscle=True, per_pair=True,
        switch_on="command map (custom numeric efam_ctrl_coupling: i, j, c)",
    ),
    ArmEffect(
        "compliant_mount", "the base is not rigid: it rocks on a torsional spring",
        "two hinges at the base, stiffness k, damping c",
        (Param("stiffness_N_m_per_rad", 2.0, 3000.0, True, grid=(10.0, 60.0, 400.0)), Param("damping_N_m_s_per_rad", 0.005, 20.0, True, start=0.3)),
        switch_on="MJCF: hinges 'mount_x', 'mount_y' on body 'base'",
    ),
)  # fmt: skip

EFFECT_NAMES = tuple(e.name for e in LIBRARY)


def get(name: str) -> ArmEffect:
    """The library effect called ``name``."""
    for e in LIBRARY:
        if e.name == name:
            return e
    raise KeyError(f"unknown arm effect {name!r} (known: {', '.join(EFFECT_NAMES)})")


def refit_params(n_muscles: int) -> tuple[Param, ...]:
    """What the model already has, re-fitted within bounds a calibration would allow: a pressure
    gain per muscle (+-8 %), one pressure offset (+-10 kPa), damping and lag scale (x0.7..1.4)."""
    gains = tuple(Param(f"gain_{i}", 0.92, 1.08, start=1.0) for i in range(n_muscles))
    return gains + (
        Param("offset_Pa", -10e3, 10e3, start=0.0),
        Param("damping_scale", 0.7, 1.4, True, start=1.0),
        Param("lag_scale", 0.7, 1.4, True, start=1.0),
    )


def refit_knobs(nominal: Knobs, values: dict) -> Knobs:
    """The nominal knobs with a refit's values."""
    n = len(nominal.gain)
    return with_values(
        nominal,
        gain=[values[f"gain_{i}"] for i in range(n)],
        offset_Pa=[values["offset_Pa"]] * n,
        damping_axial=values["damping_scale"],
        damping_bend=values["damping_scale"],
        lag_s=np.asarray(nominal.lag_s) * values["lag_scale"],
    )
