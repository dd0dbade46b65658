"""Continuum arms of parallel-bundled EFAMs in MuJoCo (OctArm-style; paper Sec. 1.2).

An arm is S sections stacked base to tip. A section is M >= 3 muscles in parallel between two
plates, muscle i at radius r and angle alpha_i about the section's axis, clamped by D spacer
disks; equal pressures extend it, unequal pressures bend it towards the lower-pressure muscle
(an EFAM pushes). The shape comes from the muscles alone: every muscle is cut into segments
between consecutive disks, each with its own length and force, all at the muscle's one
pressure; the joints between disks allow extension and bending and nothing else.

* :mod:`.spec`: :class:`SectionSpec`, :class:`ArmSpec`, the shipped arms;
* :mod:`.masses`: the mass table (paper Table 1);
* :mod:`.builder`: the MuJoCo model and helpers to read it;
* :mod:`.timestep`: the time step and integrator, derived from the arm's physics;
* :mod:`.continuum`: the continuum (Kirchhoff rod) reference, independent of MuJoCo;
* :mod:`.pcc`: the piecewise-constant-curvature mode;
* :mod:`.cli`: ``efam arm``.
"""

from .builder import (
    MODELS,
    MODELS_DIR,
    SegmentLengths,
    arm_xml,
    base_frame_position,
    bend_in_base,
    build_model,
    build_spec,
    gravity_in_base,
    muscle_names,
    muscle_pressures,
    muscle_segment_lengths,
    node_inertias,
    segment_tendons,
    settle,
    static_equilibrium,
    tip_in_base,
    write_models,
)
from .cli import arm_from_args, equilibrium, main, register_cli
from .continuum import PointMass, solve_arm_spec
from .masses import DENSITY_KG_M3, MuscleParts, muscle_part_masses
from .spec import (
    DEFAULT_DISKS,
    MAX_TESTED_PRESSURE_PA,
    ORIENTATIONS,
    PAPER_PRESSURES_PA,
    ArmSpec,
    SectionSpec,
    arm_1x3,
    arm_3x3,
    default_radius,
    paper_section,
)

__all__ = [
    "DEFAULT_DISKS",
    "DENSITY_KG_M3",
    "MAX_TESTED_PRESSURE_PA",
    "MODELS",
    "MODELS_DIR",
    "ORIENTATIONS",
    "PAPER_PRESSURES_PA",
    "ArmSpec",
    "MuscleParts",
    "SectionSpec",
    "SegmentLengths",
    "arm_1x3",
    "arm_3x3",
    "arm_xml",
    "base_frame_position",
    "build_model",
    "build_spec",
    "default_radius",
    "gravity_in_base",
    "muscle_names",
    "muscle_part_masses",
    "muscle_pressures",
    "muscle_segment_lengths",
    "node_inertias",
    "paper_section",
    "segment_tendons",
    "settle",
    "bend_in_base",
    "tip_in_base",
    "write_models",
    "arm_from_args",
    "equilibrium",
    "main",
    "register_cli",
    "static_equilibrium",
    "PointMass",
    "solve_arm_spec",
    "point_masses",
]


def point_masses(arm: ArmSpec) -> list:
    """The arm's point masses for the continuum reference (end fittings, plates, payload; the
    muscles' spread mass is a line density: see :func:`.continuum.arm_loads`)."""
    from .continuum import arm_loads

    return arm_loads(arm)["point_masses"]
