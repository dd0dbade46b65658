"""Everything the suite needs from the arm builder and its statics, in one place.

The suite acts on whatever arm :mod:`efam_mujoco.arm` builds. It relies on this much of it:

* ``arm.ArmSpec``, ``arm.SectionSpec``, ``arm.paper_section`` (the domains' arms), with the
  fields ``sections``, ``orientation``, ``pressure_tau_s``, ``max_pressure_Pa``, ``gravity``,
  ``timestep_s``, ``name`` and, per section, ``muscles``, ``radius_m``, ``angles_rad``;
* ``arm.build_spec(spec) -> mujoco.MjSpec`` whose model has a fixed body ``base`` (z along the
  first section), per section j the disk bodies ``s{j}d{k}`` (k = 1..D, the last is the section's
  end plate), a site ``tip`` with sensor ``tip_pos``, and one actuator and one tendon per muscle,
  named by ``arm.muscle_names(spec)``, ctrl = gauge pressure in Pa, ctrlrange [0, rated];
* the pressure convention of ``arm.muscle_pressures(model, data)`` (activation = pressure),
  ``arm.gravity_in_base(spec)``, ``arm.point_masses(spec)``, ``arm.ORIENTATIONS``;
* ``statics.solve_arm(sections, pressures, gravity_m_s2=, point_masses=, tip_force_N=,
  initial=)`` returning ``tip_position_m`` (base frame): the reference the controllers invert.

Nothing here reads a joint name or an equality constraint, so a different joint structure
inside the sections does not touch the suite. When the continuum reference replaces
``statics.solve_arm``, :func:`reference_tip` is the one function to point at it.
"""

from __future__ import annotations

import functools
from dataclasses import replace

import mujoco
import numpy as np

from .. import arm as arm_builder
from .. import plugin, statics

#: the paper's muscle preset every domain is built from
DOMAIN_MUSCLE = "FAM1"


def bundle_spec(**overrides) -> arm_builder.ArmSpec:
    """One section of three FAM1 muscles at 20 mm, upright (the ``bundle`` domain)."""
    options = {"orientation": "upright", "name": "efam_bundle"}
    options.update(overrides)
    return arm_builder.ArmSpec(sections=(arm_builder.paper_section(muscle=DOMAIN_MUSCLE),), **options)


def arm_spec(**overrides) -> arm_builder.ArmSpec:
    """Three sections of three FAM1 muscles, hanging (the ``arm`` domain; upright it buckles
    under its own weight at low pressure)."""
    options = {"orientation": "hanging", "name": "efam_arm"}
    options.update(overrides)
    section = arm_builder.paper_section(muscle=DOMAIN_MUSCLE)
    return arm_builder.ArmSpec(sections=(section,) * 3, **options)


def build_arm_spec(spec: arm_builder.ArmSpec) -> mujoco.MjSpec:
    """The builder's editable model of ``spec`` (plugin loaded), for the suite to add its scene."""
    plugin.load()
    return arm_builder.build_spec(replace(spec, payload_kg=0.0))


def muscle_names(spec: arm_builder.ArmSpec) -> list[str]:
    """Actuator (and tendon) names of all muscles, base section first."""
    return [name for section in arm_builder.muscle_names(spec) for name in section]


def muscle_pressures_Pa(act_adr, act, ctrl, rated_Pa) -> np.ndarray:
    """The pressure each muscle acts with, Pa, in actuator order: as
    ``arm.muscle_pressures(model, data)`` (the activation of an actuator with pressure
    dynamics, else its ctrl clamped to [0, rated]), vectorised for a per-step observation."""
    out = np.clip(ctrl, 0.0, rated_Pa)
    lagged = act_adr >= 0
    out[lagged] = act[act_adr[lagged]]
    return out


def base_quaternion(spec: arm_builder.ArmSpec) -> np.ndarray:
    """Orientation (w, x, y, z) of the arm's base frame in the world."""
    return np.asarray(arm_builder.ORIENTATIONS[spec.orientation], dtype=float)


def rest_length_m(spec: arm_builder.ArmSpec) -> float:
    """The arm's length at rest (sum of its sections' muscle rest lengths)."""
    return float(sum(section.rest_length_m for section in spec.sections))


def section_muscles(spec: arm_builder.ArmSpec):
    """Per section: (muscles, radii (M,), angles (M,) in rad)."""
    out = []
    for section in spec.sections:
        radii, angles = statics.muscle_layout(section)
        out.append((tuple(section.muscles), radii, angles))
    return out


# ---------------------------------------------------------------- the reference (statics)


def reference_tip(
    spec: arm_builder.ArmSpec,
    pressures_Pa,
    payload_kg: float = 0.0,
    tip_force_N=(0.0, 0.0, 0.0),
    initial=None,
):
    """Tip position (base frame, m) of the arm at rest under ``pressures_Pa`` (one per muscle,
    base section first) by the reference statics, with the arm's own weight, a payload at the
    tip and a tip force (base frame). Returns ``(tip, warm_start)``; pass ``warm_start`` back as
    ``initial`` to speed up a nearby solve."""
    pressures = np.asarray(pressures_Pa, dtype=float)
    counts = np.cumsum([len(s.muscles) for s in spec.sections])[:-1]
    masses = list(arm_builder.point_masses(spec))
    if payload_kg > 0:
        masses.append(statics.PointMass(len(spec.sections) - 1, 1.0, float(payload_kg)))
    state = statics.solve_arm(
        spec.sections,
        np.split(pressures, counts),
        tip_force_N=tip_force_N,
        gravity_m_s2=arm_builder.gravity_in_base(spec),
        point_masses=masses,
        initial=initial,
    )
    warm = np.concatenate([[sec.arc_length_m, *sec.curvature_xy_per_m] for sec in state.sections])
    return np.asarray(state.tip_position_m, dtype=float), warm


# ----------------------------------------------------- unloaded constant-curvature geometry


@functools.lru_cache(maxsize=32)
def _free_length_table(muscle, max_pressure_Pa: float):
    pressures = np.linspace(0.0, max_pressure_Pa, 513)
    lengths = np.array([muscle.free_length(p) for p in pressures])
    # below the muscle's dead band the free length stays at rest: keep the last such point
    first = int(np.searchsorted(lengths, lengths[0], side="right")) - 1
    pressures, lengths = pressures[first:], lengths[first:]
    if np.any(np.diff(lengths) <= 0):
        raise ValueError(f"muscle {muscle.name}: free length not increasing with pressure")
    return pressures, lengths


def free_length_m(muscle, pressure_Pa, max_pressure_Pa: float):
    """The muscle's free length at ``pressure_Pa`` (interpolated table; vectorised)."""
    pressures, lengths = _free_length_table(muscle, float(max_pressure_Pa))
    return np.interp(pressure_Pa, pressures, lengths)


def pressure_for_free_length(muscle, length_m, max_pressure_Pa: float):
    """Inverse of :func:`free_length_m`: the pressure at which the muscle's free length is
    ``length_m`` (clamped to [0, max_pressure_Pa])."""
    pressures, lengths = _free_length_table(muscle, float(max_pressure_Pa))
    return np.interp(length_m, lengths, pressures)


def cc_tip(sections_params, spec: arm_builder.ArmSpec) -> np.ndarray:
    """Tip (base frame) of an arm whose sections are the arcs ``(s, kx, ky)`` (no load)."""
    p, R = np.zeros(3), np.eye(3)
    for s, kx, ky in sections_params:
        dp, dR = statics.cc_frame(s, kx, ky)
        p, R = p + R @ dp, R @ dR
    return p
