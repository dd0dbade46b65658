"""Continuum arms of parallel-bundled EFAMs in MuJoCo (OctArm-style; paper Sec. 1.2).

An arm is S sections stacked base to tip. A section is M >= 3 muscles in parallel between two
plates, muscle i at radius r and angle alpha_i about the section's axis; equal pressures extend
it, unequal pressures bend it towards the lower-pressure muscle (an EFAM pushes).

The MuJoCo model (:func:`build_spec`):

* bodies: a fixed ``base`` plate, then per section D disks ``s{j}d{k}`` (k = 1..D, the last one
  is the section's end plate); each disk is a child of the previous one.
* joints, per disk: slide ``ext_a`` along the previous disk's axis, the bending hinges
  ``bend_x1``, ``bend_y``, ``bend_x2`` (anchored midway between the disks), slide ``ext_b``
  along the new axis. With equal x hinges Rx(a) Ry(b) Rx(a) is a pure bend (axis in the disk
  plane): no twist. With equal slides the disks sit at the tangent points of the arc: no shear.
* constant curvature: equality constraints make every link of a section take the same
  extension and bend as its first link, so a section is a circular arc (the muscles slide
  through the disks and carry one force along their whole length, and without this coupling the
  disk spacing would be undetermined). The disks discretise the arc that the muscle tendons
  follow: the tendon chords are shorter than the arc by sin(t/2)/(t/2) at a bend t per link.
* muscles: a spatial tendon ``s{j}m{i}`` through a site on every disk of its section (its
  length is the path length), driven by an ``efam.muscle`` plugin actuator (ctrl = gauge
  pressure in Pa; with ``pressure_tau_s`` > 0 a first-order pressure lag, ``dyntype=
  filterexact``, and the plugin uses the filtered pressure, the actuator's activation).
* masses from the muscles' parts (paper Table 1, see :func:`muscle_part_masses`): end fittings
  and swage tubes on the plates, latex bladder and Kevlar sleeve spread over the disks.
* passive damping on the joints, given per section (axial and bending) and spread over the links.
* sensors: ``tip_pos``/``tip_quat`` (framepos/framequat of site ``tip``), ``len_s{j}m{i}``
  (tendonpos), ``force_s{j}m{i}`` (actuatorfrc, push positive), and ``pressures_<instance>``:
  the efam.muscle plugin's own sensor, the pressure state (activation, or ctrl without a lag) of
  every actuator of that plugin instance in actuator order, read at the position stage (before
  the step integrates it; :func:`muscle_pressures` reads the same after a step).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from . import plugin
from .files import write_json_atomic, write_text_atomic
from .muscle import Muscle
from .musclefile import load_muscle
from .statics import PointMass

PSI = 6894.757293168361
#: the paper's test pressures (15..75 psi), Pa
PAPER_PRESSURES_PA = tuple(p * PSI for p in (15, 30, 45, 60, 75))
#: highest pressure the paper characterised the muscles at (75 psi), Pa
MAX_TESTED_PRESSURE_PA = 75 * PSI

#: largest bend of one link (between two disks)
HINGE_LIMIT_RAD = math.radians(60.0)
#: equality data of q1 = q2 (polycoef 0 1 0 0 0; slot 10 as the MJCF parser fills it)
JOINT_COUPLING_DATA = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
#: the constant-curvature couplings carry the gravity moments along a section: stiff and hard
CC_SOLREF = (0.004, 1.0)
CC_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)

ORIENTATIONS = {
    # quaternion (w, x, y, z) turning the base frame's z (the arm axis) to the named direction
    "upright": (1.0, 0.0, 0.0, 0.0),
    "hanging": (0.0, 1.0, 0.0, 0.0),
    "horizontal": (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0),
}

# ------------------------------------------------------------------------ masses (Table 1)

DENSITY_KG_M3 = {
    "aluminium": 2700.0,
    "latex": 930.0,  # natural rubber latex
    "aramid": 1440.0,  # Kevlar 49 fibre
}
#: braided sleeve: fraction of the envelope (diameter x thickness x length) that is fibre. Not in
#: the paper; a biaxial braid of multi-filament yarns is about half fibre by volume.
SLEEVE_FIBRE_FRACTION = 0.5
SLEEVE_THICKNESS_M = 0.279e-3  # paper Sec. 2


@dataclass(frozen=True)
class MuscleParts:
    """The parts of one muscle (paper Table 1), SI. Defaults are the paper's FAM1/FAM2 parts."""

    fitting_length_m: float = 0.0254
    fitting_diameter_m: float = 0.02133
    swage_length_m: float = 0.0254
    swage_inner_diameter_m: float = 0.884 * 0.0254
    swage_outer_diameter_m: float = 0.0254
    bladder_length_m: float = 0.1778
    bladder_inner_diameter_m: float = 0.019
    bladder_outer_diameter_m: float = 0.0222
    sleeve_length_m: float = 0.508  # at 45 deg
    sleeve_diameter_m: float = 0.0222  # at 45 deg
    sleeve_thickness_m: float = SLEEVE_THICKNESS_M
    sleeve_fibre_fraction: float = SLEEVE_FIBRE_FRACTION


def _annulus_volume(length, inner_d, outer_d):
    return math.pi / 4 * (outer_d**2 - inner_d**2) * length


def muscle_part_masses(parts: MuscleParts = MuscleParts()) -> tuple[float, float]:
    """(mass at each end: end fitting + swage tube, mass along the muscle: bladder + sleeve), kg.

    End fittings are taken as solid aluminium cylinders (their fluid channel is not given), swage
    tubes as aluminium tubes, the bladder as a latex tube, the sleeve as an aramid tube of the
    sleeve's thickness holding ``sleeve_fibre_fraction`` fibre. The working fluid (air) is
    neglected.
    """
    al, latex, aramid = (DENSITY_KG_M3[k] for k in ("aluminium", "latex", "aramid"))
    fitting = al * math.pi / 4 * parts.fitting_diameter_m**2 * parts.fitting_length_m
    swage = al * _annulus_volume(
        parts.swage_length_m, parts.swage_inner_diameter_m, parts.swage_outer_diameter_m
    )
    bladder = latex * _annulus_volume(
        parts.bladder_length_m, parts.bladder_inner_diameter_m, parts.bladder_outer_diameter_m
    )
    sleeve = (
        aramid
        * parts.sleeve_fibre_fraction
        * math.pi
        * parts.sleeve_diameter_m
        * parts.sleeve_thickness_m
        * parts.sleeve_length_m
    )
    return fitting + swage, bladder + sleeve


# ------------------------------------------------------------------------------ the specs


@dataclass(frozen=True)
class SectionSpec:
    """One bundle of M >= 3 muscles in parallel.

    ``angles_deg`` default: evenly spaced from 0 deg (the base frame's x axis). ``end_mass_kg``
    (per muscle end) and ``body_mass_kg`` (per muscle, spread along it) default to the Table 1
    estimate of :func:`muscle_part_masses`; ``plate_mass_kg`` is extra structure at the section's
    end plate (none in the paper).
    """

    muscles: tuple[Muscle, ...]
    radius_m: float = 0.02
    angles_deg: tuple[float, ...] | None = None
    disks: int = 4
    end_mass_kg: float | None = None
    body_mass_kg: float | None = None
    plate_mass_kg: float = 0.0

    def __post_init__(self):
        muscles = tuple(self.muscles)
        object.__setattr__(self, "muscles", muscles)
        if len(muscles) < 3 or not all(isinstance(m, Muscle) for m in muscles):
            raise ValueError(f"section: needs at least 3 Muscle objects, got {len(muscles)}")
        if self.angles_deg is None:
            object.__setattr__(
                self, "angles_deg", tuple(360.0 * i / len(muscles) for i in range(len(muscles)))
            )
        angles = tuple(float(a) for a in self.angles_deg)
        object.__setattr__(self, "angles_deg", angles)
        if len(angles) != len(muscles):
            raise ValueError(f"section: {len(muscles)} muscles but {len(angles)} angles_deg")
        if not (math.isfinite(self.radius_m) and self.radius_m > 0):
            raise ValueError(f"section: radius_m must be positive, got {self.radius_m}")
        if int(self.disks) != self.disks or self.disks < 1:
            raise ValueError(f"section: disks must be a positive integer, got {self.disks}")
        for key in ("end_mass_kg", "body_mass_kg", "plate_mass_kg"):
            value = getattr(self, key)
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"section: {key} must be >= 0, got {value}")
        self._check_no_overlap()

    def _check_no_overlap(self):
        xy = self.radius_m * np.column_stack([np.cos(self.angles_rad), np.sin(self.angles_rad)])
        for a in range(len(self.muscles)):
            for b in range(a + 1, len(self.muscles)):
                gap = np.linalg.norm(xy[a] - xy[b])
                touch = self.muscles[a].rest_outer_radius_m + self.muscles[b].rest_outer_radius_m
                if gap < touch * (1 - 1e-9):
                    raise ValueError(
                        f"section: muscles {a} and {b} overlap at rest (centres {gap * 1e3:.1f} mm apart, "
                        f"need {touch * 1e3:.1f} mm): raise radius_m or spread angles_deg"
                    )

    @property
    def angles_rad(self) -> tuple[float, ...]:
        return tuple(math.radians(a) for a in self.angles_deg)

    @property
    def rest_length_m(self) -> float:
        """Disk spacing at qpos0 times D: the muscles' mean resting length."""
        return float(np.mean([m.rest_length_m for m in self.muscles]))

    def muscle_masses(self) -> tuple[float, float]:
        end, body = muscle_part_masses()
        return (
            end if self.end_mass_kg is None else self.end_mass_kg,
            body if self.body_mass_kg is None else self.body_mass_kg,
        )


@dataclass(frozen=True)
class ArmSpec:
    """A whole arm. Damping is per section: N s/m of section extension rate and N m s/rad of
    section bend rate (spread over the section's joints so that the section sees these values)."""

    sections: tuple[SectionSpec, ...]
    orientation: str = "upright"
    pressure_tau_s: float = 0.05
    max_pressure_Pa: float = MAX_TESTED_PRESSURE_PA
    payload_kg: float = 0.0
    gravity: bool = True
    timestep_s: float = 1e-3
    axial_damping_N_s_per_m: float = 40.0
    bend_damping_N_m_s_per_rad: float = 0.3
    hold_tip: bool = False  # weld the tip plate where it is at rest (blocked-force checks)
    name: str = "efam_arm"

    def __post_init__(self):
        object.__setattr__(self, "sections", tuple(self.sections))
        if not self.sections:
            raise ValueError("arm: needs at least one section")
        if self.orientation not in ORIENTATIONS:
            raise ValueError(
                f"arm: orientation must be one of {', '.join(ORIENTATIONS)}, got {self.orientation!r}"
            )
        checks = {
            "pressure_tau_s": self.pressure_tau_s >= 0,
            "max_pressure_Pa": self.max_pressure_Pa > 0,
            "payload_kg": self.payload_kg >= 0,
            "timestep_s": self.timestep_s > 0,
            "axial_damping_N_s_per_m": self.axial_damping_N_s_per_m >= 0,
            "bend_damping_N_m_s_per_rad": self.bend_damping_N_m_s_per_rad >= 0,
        }
        for key, ok in checks.items():
            if not (math.isfinite(getattr(self, key)) and ok):
                raise ValueError(f"arm: {key} is invalid: {getattr(self, key)!r}")


# --------------------------------------------------------------------------- mass model


@dataclass
class _Inertia:
    """Accumulates point-like parts (mass, position, inertia about their own centre)."""

    parts: list = field(default_factory=list)

    def add(self, mass, pos, own):
        if mass > 0:
            self.parts.append((float(mass), np.asarray(pos, dtype=float), np.asarray(own, dtype=float)))

    @property
    def mass(self) -> float:
        return sum(m for m, _, _ in self.parts)

    def com_and_tensor(self):
        total = self.mass
        com = sum(m * p for m, p, _ in self.parts) / total
        tensor = np.zeros((3, 3))
        for m, p, own in self.parts:
            d = p - com
            tensor += own + m * (d @ d * np.eye(3) - np.outer(d, d))
        return com, tensor


def _tube(mass, radius, length):
    """Inertia of a thin-walled tube along z about its centre."""
    transverse = mass * (radius**2 / 2 + length**2 / 12)
    return np.diag([transverse, transverse, mass * radius**2])


def _rod(mass, radius, length):
    """Inertia of a solid cylinder along z about its centre."""
    transverse = mass * (radius**2 / 4 + length**2 / 12)
    return np.diag([transverse, transverse, mass * radius**2 / 2])


def _disk_inertias(arm: ArmSpec) -> list[list[_Inertia]]:
    """Per section, per disk k = 0..D (k = 0 is the section's base plate), the parts it carries."""
    parts = MuscleParts()
    out = []
    for section in arm.sections:
        D = section.disks
        disks = [_Inertia() for _ in range(D + 1)]
        end, body = section.muscle_masses()
        link = section.rest_length_m / D
        for muscle, angle in zip(section.muscles, section.angles_rad):
            xy = section.radius_m * np.array([math.cos(angle), math.sin(angle), 0.0])
            fitting = _rod(end, parts.fitting_diameter_m / 2, parts.fitting_length_m)
            disks[0].add(end, xy, fitting)
            disks[D].add(end, xy, fitting)
            for k in range(D + 1):
                share = body / D * (0.5 if k in (0, D) else 1.0)
                disks[k].add(share, xy, _tube(share, muscle.rest_outer_radius_m, link))
        plate_radius = section.radius_m + max(m.rest_outer_radius_m for m in section.muscles)
        disks[D].add(section.plate_mass_kg, np.zeros(3), _rod(section.plate_mass_kg, plate_radius, 0.005))
        out.append(disks)
    return out


def point_masses(arm: ArmSpec) -> list[PointMass]:
    """The arm's moving masses lumped on the backbone (for :func:`statics.solve_arm` with gravity):
    each disk's mass at its fraction of its section, the payload at the tip."""
    out = []
    for j, (section, disks) in enumerate(zip(arm.sections, _disk_inertias(arm))):
        for k, disk in enumerate(disks):
            if k == 0 and j == 0:
                continue  # the base plate does not move
            if k == 0:
                out.append(PointMass(j - 1, 1.0, disk.mass))  # the previous section's end plate
            else:
                out.append(PointMass(j, k / section.disks, disk.mass))
    if arm.payload_kg > 0:
        out.append(PointMass(len(arm.sections) - 1, 1.0, arm.payload_kg))
    return out


# ------------------------------------------------------------------------------ the builder

_MUSCLE_RGBA = ((0.85, 0.33, 0.1, 1), (0.1, 0.45, 0.75, 1), (0.2, 0.6, 0.25, 1), (0.55, 0.3, 0.65, 1))


def build_spec(arm: ArmSpec, muscles: str = "plugin") -> mujoco.MjSpec:
    """The arm as an :class:`mujoco.MjSpec` (compile with ``spec.compile()`` after
    ``efam_mujoco.plugin.load()``; :func:`build_model` does both).

    ``muscles="affine"`` drives the tendons with MuJoCo's built-in affine actuators instead: the
    muscle model linearised about its free length at half the pressure range. Same arm, same
    pressure lag; a speed reference for the plugin, not a muscle model.
    """
    if muscles not in ("plugin", "affine"):
        raise ValueError(f"muscles must be 'plugin' or 'affine', got {muscles!r}")
    spec = mujoco.MjSpec()
    spec.modelname = arm.name
    spec.compiler.degree = False  # every angle below is in radians
    spec.option.timestep = arm.timestep_s
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = [0.0, 0.0, -9.81 if arm.gravity else 0.0]
    spec.option.disableflags = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)  # the arm has no contacts
    spec.visual.global_.offwidth, spec.visual.global_.offheight = 960, 720
    spec.activate_plugin(plugin.PLUGIN_NAME)

    world = spec.worldbody
    world.add_light(pos=[0.4, -0.4, 1.2], dir=[-0.3, 0.3, -1.0], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    total = sum(s.rest_length_m for s in arm.sections)
    # a side view centred on the arm at about 1.5x its resting length
    axis = np.zeros(9)
    mujoco.mju_quat2Mat(axis, np.array(ORIENTATIONS[arm.orientation]))
    centre = axis.reshape(3, 3)[:, 2] * 0.75 * total
    world.add_camera(
        name="side",
        pos=(centre + [0.0, -4.0 * total, 0.0]).tolist(),
        xyaxes=[1, 0, 0, 0, 0, 1],
        mode=mujoco.mjtCamLight.mjCAMLIGHT_FIXED,
    )
    base = world.add_body(name="base", quat=list(ORIENTATIONS[arm.orientation]))
    inertias = _disk_inertias(arm)
    first = arm.sections[0]
    _add_plate_geom(base, first, thickness=0.006, rgba=(0.5, 0.5, 0.5, 1))

    parent, parent_name = base, "base"
    for j, section in enumerate(arm.sections, start=1):
        disks = [parent_name]
        link = section.rest_length_m / section.disks
        for k in range(1, section.disks + 1):
            body = parent.add_body(name=f"s{j}d{k}", pos=[0.0, 0.0, link])
            mass = _set_inertia(
                body,
                inertias[j - 1][k],
                inertias[j][0] if k == section.disks and j < len(arm.sections) else None,
            )
            _add_link_joints(body, f"s{j}d{k}", link, arm, section, *mass)
            end_plate = k == section.disks
            _add_plate_geom(
                body,
                section,
                0.004 if end_plate else 0.0015,
                (0.6, 0.6, 0.65, 1) if end_plate else (0.75, 0.75, 0.75, 0.6),
            )
            parent, parent_name = body, body.name
            disks.append(body.name)
        _add_muscles(spec, j, section, disks, arm, muscles == "affine")
        _add_cc_equalities(spec, j, section)
    parent.add_site(name="tip", size=[0.006, 0, 0], rgba=[0.9, 0.1, 0.1, 1])
    if arm.payload_kg > 0:
        radius = (3 * arm.payload_kg / (4 * math.pi * 7800.0)) ** (1 / 3)  # a steel ball
        payload = parent.add_body(name="payload", pos=[0, 0, radius + 0.005])
        payload.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[radius, 0, 0],
            mass=arm.payload_kg,
            rgba=[0.3, 0.3, 0.3, 1],
        )
    if arm.hold_tip:
        spec.add_equality(
            type=mujoco.mjtEq.mjEQ_WELD,
            name1=parent.name,
            name2="base",
            objtype=mujoco.mjtObj.mjOBJ_BODY,
            name="hold_tip",
            data=[0.0] * 10 + [1.0, 0.0],  # anchor at the tip, pose of qpos0 (zero quaternion)
            solref=list(CC_SOLREF),
            solimp=[0.9999, 0.9999, 0.001, 0.5, 2.0],  # a test fixture: as rigid as MuJoCo allows
        )
    _add_sensors(spec, arm)
    return spec


def _add_plate_geom(body, section, thickness, rgba):
    radius = section.radius_m + max(m.rest_outer_radius_m for m in section.muscles)
    body.add_geom(
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[radius, thickness / 2, 0],
        rgba=list(rgba),
        contype=0,
        conaffinity=0,
        group=1,
        mass=0,
    )


def _set_inertia(body, disk: _Inertia, next_base: _Inertia | None):
    """Explicit inertia from the parts a disk carries (an end plate also carries the next
    section's base-end parts)."""
    acc = _Inertia(list(disk.parts) + (list(next_base.parts) if next_base is not None else []))
    if acc.mass <= 0:
        raise ValueError(f"body {body.name}: no mass (set end_mass_kg/body_mass_kg above zero)")
    com, tensor = acc.com_and_tensor()
    body.explicitinertial = True
    body.mass = acc.mass
    body.ipos = com.tolist()
    body.fullinertia = [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]
    return acc.mass, float(tensor[0, 0])


def _add_link_joints(body, name, link, arm, section, disk_mass, disk_inertia_xx):
    """slide ``ext_a``; hinges ``bend_x1``, ``bend_y``, ``bend_x2`` anchored mid-link; slide
    ``ext_b``. With bend_x1 = bend_x2 the rotation Rx(a) Ry(b) Rx(a) is a pure bend (its axis
    lies in the disk plane for any a, b), so the disks stay on a circular arc without twist."""
    D = section.disks
    # spread the section's damping so that the section sees the given values: 2D slides share
    # the extension, 2D x hinges and D y hinges share the bend about x and y
    slide_damping = 2 * D * arm.axial_damping_N_s_per_m
    hinge_damping = {"x1": 2 * D * arm.bend_damping_N_m_s_per_rad, "y": D * arm.bend_damping_N_m_s_per_rad}
    hinge_damping["x2"] = hinge_damping["x1"]
    slide_range = [-0.4 * link, 2.0 * link]  # link length from 0.2 to 5 rest spacings
    hinge_limit = {"x1": HINGE_LIMIT_RAD / 2, "y": HINGE_LIMIT_RAD, "x2": HINGE_LIMIT_RAD / 2}
    # a straight link's two slides (and, unbent about y, its two x hinges) move the disk the same
    # way: the mass matrix is singular there without a little armature (1 % of the disk's mass and
    # of its inertia about the hinge, negligible against the arm's inertia)
    slide_armature = 0.01 * disk_mass
    hinge_armature = 0.01 * (disk_inertia_xx + disk_mass * (link / 2) ** 2)

    def slide(suffix):
        body.add_joint(
            name=f"{name}_{suffix}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1],
            damping=slide_damping, limited=mujoco.mjtLimited.mjLIMITED_TRUE, range=slide_range,
            armature=slide_armature,
        )  # fmt: skip

    def hinge(suffix, axis):
        body.add_joint(
            name=f"{name}_bend_{suffix}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
            pos=[0, 0, -link / 2], damping=hinge_damping[suffix], limited=mujoco.mjtLimited.mjLIMITED_TRUE,
            range=[-hinge_limit[suffix], hinge_limit[suffix]], armature=hinge_armature if suffix != "y" else 0.0,
        )  # fmt: skip

    slide("ext_a")
    hinge("x1", [1, 0, 0])
    hinge("y", [0, 1, 0])
    hinge("x2", [1, 0, 0])
    slide("ext_b")


def _add_cc_equalities(spec, j, section):
    """Every link of section j extends and bends like its first link (constant curvature), the
    two slides of a link are equal (no shear), and so are its two x hinges (no twist)."""
    first = f"s{j}d1"
    pairs = []
    for k in range(1, section.disks + 1):
        disk = f"s{j}d{k}"
        if k > 1:
            pairs += [(f"{disk}_{q}", f"{first}_{q}") for q in ("ext_a", "bend_x1", "bend_y")]
        pairs += [(f"{disk}_ext_b", f"{first}_ext_a"), (f"{disk}_bend_x2", f"{first}_bend_x1")]
    for follower, leader in pairs:
        spec.add_equality(
            type=mujoco.mjtEq.mjEQ_JOINT, name1=follower, name2=leader, objtype=mujoco.mjtObj.mjOBJ_JOINT,
            data=JOINT_COUPLING_DATA, solref=list(CC_SOLREF), solimp=list(CC_SOLIMP),
        )  # fmt: skip


def _add_muscles(spec, j, section, disks, arm, affine=False):
    for i, (muscle, angle) in enumerate(zip(section.muscles, section.angles_rad)):
        name = f"s{j}m{i + 1}"
        xy = [section.radius_m * math.cos(angle), section.radius_m * math.sin(angle), 0.0]
        tendon = spec.add_tendon(name=name, width=muscle.rest_outer_radius_m, rgba=list(_MUSCLE_RGBA[i % 4]))
        for k, disk in enumerate(disks):
            site = f"{name}_k{k}"
            spec.body(disk).add_site(name=site, pos=xy, size=[0.002, 0, 0], group=3)
            tendon.wrap_site(site)
        actuator = spec.add_actuator(
            name=name, trntype=mujoco.mjtTrn.mjTRN_TENDON, target=name,
            ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE, ctrlrange=[0.0, arm.max_pressure_Pa],
        )  # fmt: skip
        if arm.pressure_tau_s > 0:
            actuator.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
            actuator.dynprm[0] = arm.pressure_tau_s
            actuator.actdim = 1
        if affine:
            _make_affine(actuator, muscle, arm.max_pressure_Pa / 2)
        else:
            actuator.plugin = _shared_instance(spec, muscle)


def _shared_instance(spec: mujoco.MjSpec, muscle: Muscle):
    """The plugin instance for ``muscle``'s constants, made once per distinct muscle: an instance
    evaluates all its actuators as one vectorised batch, and MuJoCo visits every instance each
    step whatever it computes (bench/bench_plugin.py: shared 0.99x affine, one each 0.90x)."""
    config = plugin.plugin_config(muscle)
    for existing in spec.plugins:
        if existing.plugin_name == plugin.PLUGIN_NAME and dict(existing.config) == config:
            return existing
    instance = spec.add_plugin(
        name=f"muscle{len(spec.plugins) + 1}", plugin_name=plugin.PLUGIN_NAME, active=True
    )
    instance.config = config
    return instance


def _make_affine(actuator, muscle: Muscle, pressure_Pa: float):
    """force = gain p + b0 + b1 L: the tangent of push(P, L) at (pressure_Pa, free length)."""
    length = muscle.free_length(pressure_Pa)
    dp, dl = 1e-3 * pressure_Pa, 1e-6
    gain = (muscle.push(pressure_Pa + dp, length) - muscle.push(pressure_Pa - dp, length)) / (2 * dp)
    slope = (muscle.push(pressure_Pa, length + dl) - muscle.push(pressure_Pa, length - dl)) / (2 * dl)
    actuator.gaintype = mujoco.mjtGain.mjGAIN_AFFINE
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.gainprm[0] = gain
    actuator.biasprm[0] = -gain * pressure_Pa - slope * length
    actuator.biasprm[1] = slope


def _add_sensors(spec, arm):
    site = mujoco.mjtObj.mjOBJ_SITE
    spec.add_sensor(name="tip_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=site, objname="tip")
    spec.add_sensor(name="tip_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=site, objname="tip")
    for j, section in enumerate(arm.sections, start=1):
        for i in range(len(section.muscles)):
            spec.add_sensor(
                name=f"len_s{j}m{i + 1}", type=mujoco.mjtSensor.mjSENS_TENDONPOS,
                objtype=mujoco.mjtObj.mjOBJ_TENDON, objname=f"s{j}m{i + 1}",
            )  # fmt: skip
    for j, section in enumerate(arm.sections, start=1):
        for i in range(len(section.muscles)):
            spec.add_sensor(
                name=f"force_s{j}m{i + 1}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"s{j}m{i + 1}",
            )  # fmt: skip
    # the plugin's pressure sensor: per instance, the pressure state of each of its actuators
    for instance in spec.plugins:
        if instance.plugin_name == plugin.PLUGIN_NAME:
            sensor = spec.add_sensor(name=f"pressures_{instance.name}", type=mujoco.mjtSensor.mjSENS_PLUGIN)
            sensor.plugin = instance


def build_model(arm: ArmSpec, muscles: str = "plugin") -> mujoco.MjModel:
    plugin.load()
    return build_spec(arm, muscles).compile()


def arm_xml(arm: ArmSpec) -> str:
    plugin.load()
    spec = build_spec(arm)
    spec.compile()  # to_xml needs a compiled spec
    return spec.to_xml()


# ------------------------------------------------------------------------ reading a model


def muscle_names(arm: ArmSpec) -> list[list[str]]:
    return [[f"s{j}m{i + 1}" for i in range(len(s.muscles))] for j, s in enumerate(arm.sections, start=1)]


def muscle_pressures(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Pressure each muscle acts with, Pa: the activation (filtered pressure) of an actuator with
    pressure dynamics, else its ctrl (clamped to ctrlrange, as MuJoCo applies it)."""
    out = np.empty(model.nu)
    for a in range(model.nu):
        adr = model.actuator_actadr[a]
        if adr >= 0:
            out[a] = data.act[adr]
        else:
            lo, hi = model.actuator_ctrlrange[a]
            out[a] = np.clip(data.ctrl[a], lo, hi) if model.actuator_ctrllimited[a] else data.ctrl[a]
    return out


def base_frame_position(model: mujoco.MjModel, data: mujoco.MjData, world_pos) -> np.ndarray:
    """A world position expressed in the arm's base frame (z along the first section)."""
    b = model.body("base").id
    return data.xmat[b].reshape(3, 3).T @ (np.asarray(world_pos) - data.xpos[b])


# ------------------------------------------------------------------------------ the models


def paper_section(disks: int = 4, law: str | None = None, muscle: str = "FAM1", **kw) -> SectionSpec:
    """Three of the paper's muscles, evenly spaced at 20 mm."""
    m = load_muscle(muscle, law)
    return SectionSpec(muscles=(m, m, m), disks=disks, **kw)


def arm_1x3(**kw) -> ArmSpec:
    """One section of three FAM1 muscles, upright."""
    return ArmSpec(sections=(paper_section(),), name="arm_1x3", **kw)


def arm_3x3(**kw) -> ArmSpec:
    """Three sections of three FAM1 muscles, hanging (upright it buckles under its own weight at
    low pressure)."""
    kw.setdefault("orientation", "hanging")
    return ArmSpec(sections=(paper_section(),) * 3, name="arm_3x3", **kw)


MODELS = {"arm_1x3": arm_1x3, "arm_3x3": arm_3x3}
MODELS_DIR = Path(__file__).resolve().parent.parent / "models"


def write_models(directory: Path = MODELS_DIR) -> list[Path]:
    """Write models/arm_*.xml from the builder (atomically)."""
    written = []
    for name, make in MODELS.items():
        written.append(write_text_atomic(Path(directory) / f"{name}.xml", arm_xml(make())))
    return written


# ----------------------------------------------------------------- equilibrium, MuJoCo vs CC


def settle(
    model: mujoco.MjModel, data: mujoco.MjData, pressures_Pa, t_max_s: float = 6.0, vel_tol: float = 1e-6
):
    """Hold the pressures and step until the arm is still (or ``t_max_s`` of simulated time);
    returns whether it settled. Raises if the state stops being finite."""
    data.ctrl[:] = np.ravel(pressures_Pa)
    while data.time < t_max_s:
        for _ in range(100):
            mujoco.mj_step(model, data)
        if not np.all(np.isfinite(data.qpos)):
            raise FloatingPointError(f"arm state not finite at t = {data.time:.3f} s")
        if np.abs(data.qvel).max() < vel_tol:
            return True
    return False


def tip_in_base(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Tip site position in the arm's base frame."""
    return base_frame_position(model, data, data.site("tip").xpos)


def gravity_in_base(arm: ArmSpec) -> np.ndarray:
    """Gravity (m/s^2) expressed in the base frame, for :func:`statics.solve_arm`."""
    if not arm.gravity:
        return np.zeros(3)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(ORIENTATIONS[arm.orientation]))
    return rotation.reshape(3, 3).T @ np.array([0.0, 0.0, -9.81])


def equilibrium(arm: ArmSpec, pressures_Pa: Sequence[Sequence[float]]) -> dict:
    """Tip position at rest under constant pressures: the MuJoCo arm and the constant-curvature
    statics (with the arm's own weight and payload when gravity is on), in the base frame."""
    from .statics import solve_arm

    model = build_model(arm)
    data = mujoco.MjData(model)
    settled = settle(model, data, [p for section in pressures_Pa for p in section], t_max_s=15.0)
    simulated = tip_in_base(model, data)
    state = solve_arm(
        arm.sections,
        pressures_Pa,
        gravity_m_s2=gravity_in_base(arm),
        point_masses=point_masses(arm),
    )
    predicted = state.tip_position_m
    arm_length = sum(s.rest_length_m for s in arm.sections)
    return {
        "settled": bool(settled),
        "tip_mujoco_m": simulated.tolist(),
        "tip_statics_m": np.asarray(predicted).tolist(),
        "difference_pct_of_rest_length": float(100 * np.linalg.norm(simulated - predicted) / arm_length),
        "section_bend_deg": [math.degrees(sec.bend_angle_rad) for sec in state.sections],
    }


# ------------------------------------------------------------------------------------- CLI


def _add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--write-models", action="store_true", help="regenerate models/arm_*.xml from the builder"
    )
    parser.add_argument("--models-dir", type=Path, default=MODELS_DIR, help="where --write-models writes")
    parser.add_argument(
        "--muscle",
        nargs="+",
        default=["FAM1"],
        help="preset or muscle file per muscle (one value: the same muscle everywhere)",
    )
    parser.add_argument("--stress", help="stress law (default: each file's default law)")
    parser.add_argument("--sections", type=int, default=1, help="number of sections (default 1)")
    parser.add_argument("--muscles-per-section", type=int, default=3, help="muscles per section (>= 3)")
    parser.add_argument("--radius-mm", type=float, default=20.0, help="muscle placement radius, mm")
    parser.add_argument("--disks", type=int, default=4, help="discretisation disks per section")
    parser.add_argument("--orientation", choices=sorted(ORIENTATIONS), default="upright")
    parser.add_argument("--payload-kg", type=float, default=0.0, help="tip payload, kg")
    parser.add_argument("--no-gravity", action="store_true", help="switch gravity off")
    parser.add_argument(
        "--pressure-lag-s", type=float, default=0.05, help="valve/tube time constant, s (0: none)"
    )
    parser.add_argument("--xml", type=Path, help="write the arm's MJCF to this file")
    parser.add_argument(
        "--pressures-kPa",
        type=float,
        nargs="+",
        help="one pressure per muscle, base section first: print the tip at rest, MuJoCo vs statics",
    )
    parser.add_argument("--json", type=Path, help="write the equilibrium as JSON to this file")


def arm_from_args(args) -> ArmSpec:
    count = args.sections * args.muscles_per_section
    if args.sections < 1 or args.muscles_per_section < 3:
        raise ValueError("--sections must be >= 1 and --muscles-per-section >= 3")
    if len(args.muscle) not in (1, count):
        raise ValueError(f"--muscle: give 1 muscle or one per muscle ({count}), got {len(args.muscle)}")
    names = args.muscle * count if len(args.muscle) == 1 else args.muscle
    loaded = {name: load_muscle(name, args.stress) for name in set(names)}
    m = args.muscles_per_section
    sections = tuple(
        SectionSpec(
            muscles=tuple(loaded[n] for n in names[j * m : (j + 1) * m]),
            radius_m=args.radius_mm / 1e3,
            disks=args.disks,
        )
        for j in range(args.sections)
    )
    return ArmSpec(
        sections=sections,
        orientation=args.orientation,
        pressure_tau_s=args.pressure_lag_s,
        payload_kg=args.payload_kg,
        gravity=not args.no_gravity,
        name=f"arm_{args.sections}x{m}",
    )


def _run(args) -> int:
    if args.write_models:
        for path in write_models(args.models_dir):
            print(path)
        return 0
    spec = arm_from_args(args)
    if args.xml:
        write_text_atomic(args.xml, arm_xml(spec))
        print(f"wrote {args.xml}")
    if args.pressures_kPa:
        count = sum(len(s.muscles) for s in spec.sections)
        pressures = np.asarray(args.pressures_kPa) * 1e3
        if pressures.size != count or not np.all(np.isfinite(pressures)) or np.any(pressures < 0):
            raise ValueError(f"--pressures-kPa: need {count} finite pressures >= 0, got {args.pressures_kPa}")
        per_section = np.split(pressures, len(spec.sections))
        result = equilibrium(spec, per_section)
        print(
            f"tip at rest, base frame (mm): MuJoCo {np.round(1e3 * np.array(result['tip_mujoco_m']), 2)}, "
            f"constant-curvature statics {np.round(1e3 * np.array(result['tip_statics_m']), 2)}; "
            f"difference {result['difference_pct_of_rest_length']:.2f} % of the arm's rest length"
        )
        if not result["settled"]:
            print("warning: the arm had not come to rest after 15 s of simulated time", file=sys.stderr)
        if args.json:
            write_json_atomic(args.json, result)
    if not (args.xml or args.pressures_kPa):
        print("nothing to do: pass --xml FILE, --pressures-kPa ..., or --write-models", file=sys.stderr)
        return 2
    return 0


def register_cli(subparsers) -> None:
    """``efam arm --write-models`` (for efam_mujoco.cli.COMMAND_MODULES)."""
    parser = subparsers.add_parser(
        "arm",
        help="build a continuum arm; its tip at rest under pressures, MuJoCo vs statics",
        description=__doc__.splitlines()[0],
    )
    _add_arguments(parser)
    parser.set_defaults(run=_run)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m efam_mujoco.arm", description=__doc__.splitlines()[0])
    _add_arguments(parser)
    return _run(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
