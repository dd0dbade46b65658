"""A bundle of the sized muscle: one section of M muscles in parallel, what it does, from the
continuum reference and verified in MuJoCo (``efam size --bundle M``).

This is the only module of ``efam size`` that knows the arm API (``arm.SectionSpec``,
``arm.ArmSpec``, ``arm.build_model``, ``arm.settle``, ``arm.tip_in_base``, and
``arm.continuum.solve_arm_spec``, the Kirchhoff-rod continuum reference with the section's own
weight and the payload).

Quantities (all at the request's pressure P; gravity off unless stated)::

    ``tip_force_N``       the section held at its resting length (``hold_tip``): the sum of the
                          muscles' pushes, M x Eq. 9 (reference) beside MuJoCo's actuator forces.
    ``stroke``            all muscles at P: the section's extension as a fraction of its resting length.
    ``bend_range_deg``    reference only: muscle 1 vented (0 Pa), the others at P: the angle the tip
                          turns through, the largest single-muscle bend the pressure budget gives (with
                          three muscles each sits at its own free length, so it is geometric and can
                          exceed what the disks allow; MuJoCo's links stop at 60 deg each).
    ``bend_deg``          verified bend: muscle 1 at the pressure ``bend_check_Pa`` at which the
                          reference turns 90 deg (or vented, when the full range is below 90 deg),
                          reference beside MuJoCo.
    ``tip_deflection_m``  the section horizontal, all muscles at P, gravity on with the payload at the
                          tip: how far the tip sits from where it would be without gravity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import brentq

from .. import arm
from ..arm.builder import MAX_SETTLE_STEPS
from ..arm.continuum import solve_arm_spec
from ..muscle import Muscle
from ..statics import StaticsError
from .request import Request
from .verify import Pair

#: muscles sit this much further apart than touching (a clearance for the disks' holes)
CLEARANCE = 1.05
DISKS = 8  # the tendon chords shorten the bent arc: 4 disks err by ~8 deg at 90 deg on thin bundles
SETTLE_S = 40.0  # soft sections creep slowly to rest under the default damping
#: the bend verified in MuJoCo (within the 4 x 60 deg the model's links allow)
CHECK_BEND_DEG = 90.0


@dataclass(frozen=True)
class BundleReport:
    muscles: int
    radius_m: float
    pressure_Pa: float
    payload_kg: float
    tip_force_N: Pair
    stroke: Pair
    bend_range_deg: float
    bend_check_Pa: float
    bend_deg: Pair
    tip_deflection_m: Pair
    settled: bool
    notes: tuple = ()

    def to_dict(self) -> dict:
        """The report as plain JSON types (SI units, keys with units)."""
        return {
            "muscles": self.muscles,
            "radius_m": self.radius_m,
            "pressure_kPa": self.pressure_Pa / 1e3,
            "payload_kg": self.payload_kg,
            "tip_force_N": self.tip_force_N.to_dict(),
            "stroke": self.stroke.to_dict(),
            "bend_range_deg": self.bend_range_deg,
            "bend_check_kPa": self.bend_check_Pa / 1e3,
            "bend_deg": self.bend_deg.to_dict(),
            "tip_deflection_m": self.tip_deflection_m.to_dict(),
            "settled": self.settled,
            "notes": list(self.notes),
        }


def section_for(muscle: Muscle, count: int) -> arm.SectionSpec:
    """M copies of the muscle evenly spaced, just clear of touching."""
    radius = CLEARANCE * muscle.rest_diameter_m / (2 * math.sin(math.pi / count))
    return arm.SectionSpec(muscles=(muscle,) * count, radius_m=radius, disks=DISKS)


def _reference(spec: arm.ArmSpec, pressures) -> tuple[np.ndarray, float, float]:
    """Continuum reference: (tip position in the base frame, bend angle in rad, arc length)."""
    state = solve_arm_spec(spec, [pressures])
    section = state.sections[0]
    return np.asarray(state.tip_position_m), section.bend_angle_rad, section.arc_length_m


def _simulate(spec: arm.ArmSpec, pressures) -> tuple[np.ndarray, float, mujoco.MjModel, mujoco.MjData, bool]:
    """MuJoCo at rest: (tip in the base frame, bend angle in rad, model, data, settled)."""
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    settled = arm.settle(model, data, pressures, t_max_s=SETTLE_S)
    return arm.tip_in_base(model, data), arm.bend_in_base(model, data), model, data, bool(settled)


def bundle_report(muscle: Muscle, request: Request) -> BundleReport:
    """The section's tip force, stroke, bend and payload deflection, reference beside MuJoCo."""
    M, P = request.muscles, request.pressure_Pa
    section = section_for(muscle, M)
    rest = section.rest_length_m
    notes, settled = [], True
    equal = [P] * M
    common = dict(sections=(section,), pressure_tau_s=0.0, max_pressure_Pa=max(P, 1.0))

    held = arm.ArmSpec(**common, gravity=False, hold_tip=True)
    model = arm.build_model(held)
    data = mujoco.MjData(model)
    settled &= arm.settle(model, data, equal, t_max_s=2.0)
    forces = [data.sensor(f"force_s1m{i + 1}").data[0] for i in range(M)]
    tip_force = Pair(float(M * muscle.push(P, rest)), float(np.sum(forces)))

    free = arm.ArmSpec(**common, gravity=False)
    ref_tip, _, arc = _reference(free, equal)
    sim_tip, _, _, _, ok = _simulate(free, equal)
    settled &= ok
    stroke = Pair(arc / rest - 1.0, float(sim_tip[2]) / rest - 1.0)

    def reference_bend(p1):
        return math.degrees(_reference(free, [p1] + [P] * (M - 1))[1])

    try:
        full = reference_bend(0.0)
        check = 0.0
        if full > CHECK_BEND_DEG:
            check = brentq(lambda p1: reference_bend(p1) - CHECK_BEND_DEG, 0.0, P, xtol=10.0)
        ref_bend = reference_bend(check)
    except (StaticsError, ValueError) as err:
        full = check = ref_bend = math.nan
        notes.append(f"bend: no continuum equilibrium ({err})")
    if math.isfinite(check):
        _, sim_bend, _, _, ok = _simulate(free, [check] + [P] * (M - 1))
        settled &= ok
    else:
        sim_bend = math.nan
    bend = Pair(ref_bend, math.degrees(sim_bend))

    loaded = arm.ArmSpec(**common, orientation="horizontal", payload_kg=request.payload_kg)
    straight = np.array([0.0, 0.0, arc])
    try:
        ref_deflection = float(np.linalg.norm(_reference(loaded, equal)[0] - straight))
    except StaticsError as err:
        ref_deflection = math.nan
        notes.append(f"payload: no continuum equilibrium ({err})")
    try:
        sim_loaded, _, _, _, ok = _simulate(loaded, equal)
        settled &= ok
        sim_deflection = float(np.linalg.norm(sim_loaded - straight))
    except FloatingPointError as err:
        sim_deflection = math.nan
        notes.append(f"payload: MuJoCo diverged ({err})")
    deflection = Pair(ref_deflection, sim_deflection)
    if not settled:
        notes.append(
            f"MuJoCo had not come to rest in every case (within {SETTLE_S:g} s of simulated time, or "
            f"{MAX_SETTLE_STEPS} steps for a section whose time step is tiny): its figures are not at rest"
        )
    return BundleReport(
        M,
        section.radius_m,
        P,
        request.payload_kg,
        tip_force,
        stroke,
        full,
        check,
        bend,
        deflection,
        bool(settled),
        tuple(notes),
    )
