"""The MuJoCo arm (:func:`build_spec`): bodies, joints, segmented muscles, masses, sensors.

Per section j, D links. Link k runs from disk ``s{j}d{k-1}`` (``s{j}d0`` is the previous
section's end plate, or ``base``) to disk ``s{j}d{k}``, through a hinge node ``s{j}h{k}`` at its
middle. The joints of link k, and all the joints there are:

* slide ``s{j}d{k}_ext_a`` along the previous disk's axis (the node, a half-link away); its value
  is that half-link's length (``ref`` = its resting length);
* hinges ``s{j}d{k}_bend_x`` and ``s{j}d{k}_bend_y`` at the node (a universal joint: bending about
  two axes, no twist to first order; their order alternates from link to link so that the
  second-order twist of one link is undone by the next);
* slide ``s{j}d{k}_ext_b`` along the node's new axis to the next disk.

So a straight link is two half-links end to end and a bent one the two tangents of an arc that
meet at the node: extension and bending only, no shear, no constraint. Each muscle has one
segment per half-link, a fixed tendon whose length is exactly the length of the muscle's arc at
its offset y in that half (l = ext - y . theta / 2, with theta the link's bend): linear in the
joints, so the muscle forces are exact functions of the strains and conservative.
"""

from __future__ import annotations

import math
import numbers
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from .. import plugin
from ..files import write_text_atomic
from ..muscle import Muscle
from ..units import as_float, check_pressure_Pa
from .masses import FITTING_LENGTH_M, FITTING_RADIUS_M
from .spec import ORIENTATIONS, ArmSpec, SectionSpec, arm_1x3, arm_3x3
from .timestep import ROUND_TIMESTEPS_S, apply_timestep, default_integrator, force_jacobian, generalized_force

_MUSCLE_RGBA = ((0.85, 0.33, 0.1, 1), (0.1, 0.45, 0.75, 1), (0.2, 0.6, 0.25, 1), (0.55, 0.3, 0.65, 1))


# --------------------------------------------------------------------------- lumped masses


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


def node_inertias(section: SectionSpec) -> tuple[_Inertia, list[_Inertia], list[_Inertia]]:
    """(the section's base plate, its D hinge nodes, its D disks (the last is the end plate)):
    the parts each carries. The muscles' spread mass is lumped by the trapezoidal rule over the
    2D half-links (a quarter of a link's share on each end of each half-link); end fittings on
    the plates."""
    D = section.disks
    end, body = section.muscle_masses()
    half = section.rest_length_m / (2 * D)
    base, nodes, disks = _Inertia(), [_Inertia() for _ in range(D)], [_Inertia() for _ in range(D)]
    for muscle, (x, y) in zip(section.muscles, section.offsets_m()):
        pos = [x, y, 0.0]
        piece = body / (4 * D)  # a quarter of one link's share
        fitting = _rod(end, FITTING_RADIUS_M, FITTING_LENGTH_M)
        base.add(end, pos, fitting)
        base.add(piece, pos, _tube(piece, muscle.rest_outer_radius_m, half))
        for k in range(D):
            nodes[k].add(2 * piece, pos, _tube(2 * piece, muscle.rest_outer_radius_m, half))
            disks[k].add(
                piece if k == D - 1 else 2 * piece, pos, _tube(2 * piece, muscle.rest_outer_radius_m, half)
            )
        disks[D - 1].add(end, pos, fitting)
    plate_radius = section.radius_m + max(m.rest_outer_radius_m for m in section.muscles)
    disks[D - 1].add(section.plate_mass_kg, np.zeros(3), _rod(section.plate_mass_kg, plate_radius, 0.005))
    for k in range(D - 1):
        disks[k].add(section.disk_mass_kg, np.zeros(3), _rod(section.disk_mass_kg, plate_radius, 0.003))
    return base, nodes, disks


# ------------------------------------------------------------------------------ the builder


def build_spec(arm: ArmSpec, muscles: str = "plugin") -> mujoco.MjSpec:
    """The arm as an :class:`mujoco.MjSpec` (compile with ``spec.compile()`` after
    ``efam_mujoco.plugin.load()``; :func:`build_model` does both).

    ``muscles="affine"`` drives every muscle segment with MuJoCo's built-in affine actuator
    instead (the muscle model linearised about its free length at half the pressure range; one
    actuator per segment, so ``ctrl`` has one entry per segment): the benchmark's speed
    reference, not a muscle model.
    """
    if muscles not in ("plugin", "affine"):
        raise ValueError(f"muscles must be 'plugin' or 'affine', got {muscles!r}")
    spec = _new_spec(arm)
    base = _add_base(spec, arm)
    parent, parent_parts = base, None
    for j, section in enumerate(arm.sections, start=1):
        parent, parent_parts = _add_section(spec, arm, j, section, parent, parent_parts)
        _add_muscles(spec, arm, j, section, muscles == "affine", segmented=arm.mode == "segmented")
        if arm.mode == "pcc":
            _add_pcc_coupling(spec, arm, j, section)
    _finish(spec, arm, parent)
    plugin.load()
    apply_timestep(spec, arm.max_pressure_Pa, arm.timestep_s)
    return spec


def _new_spec(arm: ArmSpec) -> mujoco.MjSpec:
    spec = mujoco.MjSpec()
    spec.modelname = arm.name
    spec.compiler.degree = False  # every angle below is in radians
    spec.option.timestep = ROUND_TIMESTEPS_S[-1]  # set by apply_timestep from the built arm
    spec.option.integrator = default_integrator(arm.axial_viscosity_N_s > 0 or arm.bend_viscosity_N_m2_s > 0)
    spec.option.gravity = [0.0, 0.0, -9.81 if arm.gravity else 0.0]
    spec.option.disableflags = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)  # the arm has no contacts
    spec.visual.global_.offwidth, spec.visual.global_.offheight = 960, 720
    spec.activate_plugin(plugin.PLUGIN_NAME)
    world = spec.worldbody
    world.add_light(pos=[0.4, -0.4, 1.2], dir=[-0.3, 0.3, -1.0], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    total = arm.rest_length_m
    axis = np.zeros(9)
    mujoco.mju_quat2Mat(axis, np.array(ORIENTATIONS[arm.orientation]))
    centre = axis.reshape(3, 3)[:, 2] * 0.75 * total
    world.add_camera(
        name="side",
        pos=(centre + [0.0, -4.0 * total, 0.0]).tolist(),
        xyaxes=[1, 0, 0, 0, 0, 1],
        mode=mujoco.mjtCamLight.mjCAMLIGHT_FIXED,
    )
    return spec


def _add_base(spec, arm):
    base = spec.worldbody.add_body(name="base", quat=list(ORIENTATIONS[arm.orientation]))
    _add_plate_geom(base, arm.sections[0], 0.006, (0.5, 0.5, 0.5, 1))
    return base


def _set_inertia(body, acc: _Inertia):
    if acc.mass <= 0:
        raise ValueError(f"body {body.name}: no mass (set end_mass_kg/body_mass_kg above zero)")
    com, tensor = acc.com_and_tensor()
    body.explicitinertial = True
    body.mass = acc.mass
    body.ipos = com.tolist()
    body.fullinertia = [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]


def _add_section(spec, arm: ArmSpec, j: int, section: SectionSpec, parent, parent_parts):
    """Links k = 1..D of section j on ``parent`` (the previous end plate with its parts, or the
    base); returns the section's end plate and its parts."""
    D = section.disks
    half = section.rest_length_m / (2 * D)
    base_parts, nodes, disks = node_inertias(section)
    if parent_parts is not None:  # this section's base-end parts ride on the previous end plate
        _set_inertia(parent, _Inertia(parent_parts + base_parts.parts))
    # damping of a half-link's extension and of a link's bend, from the material viscosities
    slide_damping = arm.axial_viscosity_N_s / half
    hinge_damping = arm.bend_viscosity_N_m2_s / (2 * half)
    for k in range(1, D + 1):
        node = parent.add_body(name=f"s{j}h{k}", pos=[0.0, 0.0, half])
        _set_inertia(node, nodes[k - 1])
        _slide(node, f"s{j}d{k}_ext_a", half, slide_damping)
        axes = (("x", [1, 0, 0]), ("y", [0, 1, 0]))
        for suffix, axis in axes if k % 2 else axes[::-1]:
            node.add_joint(
                name=f"s{j}d{k}_bend_{suffix}",
                type=mujoco.mjtJoint.mjJNT_HINGE,
                axis=axis,
                damping=hinge_damping,
            )
        disk = node.add_body(name=f"s{j}d{k}", pos=[0.0, 0.0, half])
        _slide(disk, f"s{j}d{k}_ext_b", half, slide_damping)
        _set_inertia(disk, disks[k - 1])
        end = k == D
        _add_plate_geom(
            disk, section, 0.004 if end else 0.0015, (0.6, 0.6, 0.65, 1) if end else (0.75, 0.75, 0.75, 0.6)
        )
        parent = disk
    return parent, list(disks[D - 1].parts)


def _slide(body, name, half, damping):
    body.add_joint(
        name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1], ref=half, damping=damping
    )  # fmt: skip


def segment_coefficients(section: SectionSpec, j: int, k: int, i: int) -> dict[str, float]:
    """Joint coefficients of muscle i's two segments in link k: each half-link's slide plus half
    the link's bend at the muscle's offset (x, y): l = ext - (x theta_y - y theta_x) / 2."""
    x, y = section.offsets_m()[i]
    return {f"s{j}d{k}_bend_x": y / 2, f"s{j}d{k}_bend_y": -x / 2}


def _add_muscles(spec, arm: ArmSpec, j: int, section: SectionSpec, affine: bool, segmented: bool = True):
    D = section.disks
    for i, muscle in enumerate(section.muscles):
        name = f"s{j}m{i + 1}"
        whole = spec.add_tendon(name=name, rgba=list(_MUSCLE_RGBA[i % 4]))
        segments = []
        for k in range(1, D + 1):
            bends = segment_coefficients(section, j, k, i)
            for ext in ("a", "b"):
                segments.append((f"{name}_k{k}{ext}", {f"s{j}d{k}_ext_{ext}": 1.0, **bends}))
        totals: dict[str, float] = {}
        for _, coefs in segments:
            for joint, c in coefs.items():
                totals[joint] = totals.get(joint, 0.0) + c
        for joint, c in totals.items():
            whole.wrap_joint(joint, c)
        if not segmented:  # PCC: one force along the whole muscle
            actuator = _add_actuator(spec, arm, name, name)
            if affine:
                _make_affine(actuator, muscle, arm.max_pressure_Pa / 2)
            else:
                actuator.plugin = _shared_instance(spec, muscle, 1)
            continue
        for seg_name, coefs in segments:
            tendon = spec.add_tendon(name=seg_name)
            for joint, c in coefs.items():
                tendon.wrap_joint(joint, c)
        if affine:
            for seg_name, _ in segments:
                actuator = _add_actuator(spec, arm, seg_name, seg_name)
                _make_affine(actuator, muscle, arm.max_pressure_Pa / 2, len(segments))
        else:
            actuator = _add_actuator(spec, arm, name, name)
            actuator.plugin = _shared_instance(spec, muscle, len(segments))


#: PCC mode: a section's departures from constant curvature are this many times stiffer than
#: the muscles make them (measured in docs/arms.md: the tip's distance from the exact
#: constant-curvature equilibrium falls as 1 / ratio; the fastest mode grows as sqrt(ratio))
PCC_STIFFNESS_RATIO = 30.0


def _add_pcc_coupling(spec, arm: ArmSpec, j: int, section: SectionSpec):
    """PCC: every half-link of the section extends like the section's mean and every link bends
    like the mean, held by conservative springs on the departures q_k - mean(q), a penalty (no
    constraint: nothing numerical decides the rest pose). Their energy (1/2) k sum (q_k - mean)^2
    makes every departure from constant curvature, smooth or zig-zag, ``PCC_STIFFNESS_RATIO``
    times stiffer than the muscles make a single joint (springs between neighbours would resist
    the smooth departures gravity causes only (pi / D)^2 as much). It is built as
    (1/2) k sum (q_k - q_rest)^2 (joint springs) minus (1/2) k N (mean - q_rest)^2 (a fixed
    tendon over the N joints with negative stiffness): N + 1 terms instead of N tendons of N
    joints. The dampers, the same way, are ``PCC_STIFFNESS_RATIO`` times the bundle's viscous
    damping of the same joints (the coupling relaxes like the bundle, vanishes with the
    viscosities, and its damping counts in the damping work)."""
    D = section.disks
    k_muscles = sum(-(m.push(0.0, m.rest_length_m * 1.000001) - m.push(0.0, m.rest_length_m * 0.999999))
                    / (2e-6 * m.rest_length_m) for m in section.muscles)  # fmt: skip
    half = section.rest_length_m / (2 * D)
    offsets = section.offsets_m()
    mean_k = k_muscles / len(section.muscles)
    groups = [  # name, joints, rest value, a joint's stiffness from the muscles, its viscous damping
        ("ext", [f"s{j}d{k}_ext_{e}" for k in range(1, D + 1) for e in ("a", "b")], half, 2 * D * k_muscles,
         arm.axial_viscosity_N_s / half),
        ("bend_x", [f"s{j}d{k}_bend_x" for k in range(1, D + 1)], 0.0,
         D * mean_k * float(np.sum(offsets[:, 1] ** 2)), arm.bend_viscosity_N_m2_s / (2 * half)),
        ("bend_y", [f"s{j}d{k}_bend_y" for k in range(1, D + 1)], 0.0,
         D * mean_k * float(np.sum(offsets[:, 0] ** 2)), arm.bend_viscosity_N_m2_s / (2 * half)),
    ]  # fmt: skip
    for name, joints, rest, stiffness, damping in groups:
        k, c = PCC_STIFFNESS_RATIO * stiffness, PCC_STIFFNESS_RATIO * damping
        for joint in joints:
            element = spec.joint(joint)
            element.stiffness = [k, *element.stiffness[1:]]  # (linear, polynomial terms)
            element.springref = rest
            element.damping = [element.damping[0] + c, *element.damping[1:]]
        count = len(joints)
        mean = spec.add_tendon(
            name=f"pcc_s{j}_{name}", stiffness=-k * count, damping=-c * count, springlength=[rest, rest]
        )
        for joint in joints:
            mean.wrap_joint(joint, 1.0 / count)


def _add_actuator(spec, arm, name, tendon):
    actuator = spec.add_actuator(
        name=name, trntype=mujoco.mjtTrn.mjTRN_TENDON, target=tendon,
        ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE, ctrlrange=[0.0, arm.max_pressure_Pa],
    )  # fmt: skip
    if arm.pressure_tau_s > 0:
        actuator.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
        actuator.dynprm[0] = arm.pressure_tau_s
        actuator.actdim = 1
    return actuator


def _shared_instance(spec: mujoco.MjSpec, muscle: Muscle, segments: int):
    """The plugin instance for ``muscle``'s constants, made once per distinct muscle: an instance
    evaluates all its actuators (and their segments) as one vectorised batch, and MuJoCo visits
    every instance each step whatever it computes."""
    config = plugin.plugin_config(muscle, segments=segments, arc_geometry=segments > 1)
    for existing in spec.plugins:
        if existing.plugin_name == plugin.PLUGIN_NAME and dict(existing.config) == config:
            return existing
    instance = spec.add_plugin(
        name=f"muscle{len(spec.plugins) + 1}", plugin_name=plugin.PLUGIN_NAME, active=True
    )
    instance.config = config
    return instance


def _make_affine(actuator, muscle: Muscle, pressure_Pa: float, segments: int = 1):
    """force = gain p + b0 + b1 l: the tangent of push(P, N l) at (pressure_Pa, free length / N)."""
    length = muscle.free_length(pressure_Pa)
    dp, dl = 1e-3 * pressure_Pa, 1e-6
    gain = (muscle.push(pressure_Pa + dp, length) - muscle.push(pressure_Pa - dp, length)) / (2 * dp)
    slope = (muscle.push(pressure_Pa, length + dl) - muscle.push(pressure_Pa, length - dl)) / (2 * dl)
    actuator.gaintype = mujoco.mjtGain.mjGAIN_AFFINE
    actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
    actuator.gainprm[0] = gain
    actuator.biasprm[0] = -gain * pressure_Pa - slope * length
    actuator.biasprm[1] = slope * segments


def _add_plate_geom(body, section, thickness, rgba):
    radius = section.radius_m + max(m.rest_outer_radius_m for m in section.muscles)
    body.add_geom(
        type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[radius, thickness / 2, 0], rgba=list(rgba),
        contype=0, conaffinity=0, group=1, mass=0,
    )  # fmt: skip


def _finish(spec, arm: ArmSpec, tip_body):
    tip_body.add_site(name="tip", size=[0.006, 0, 0], rgba=[0.9, 0.1, 0.1, 1])
    if arm.payload_kg > 0:
        radius = (3 * arm.payload_kg / (4 * math.pi * 7800.0)) ** (1 / 3)  # a steel ball
        # the payload's mass acts at the tip (a point load, as in the continuum reference); the
        # ball is drawn beyond the tip plate
        payload = tip_body.add_body(name="payload", pos=[0, 0, 0])
        payload.explicitinertial = True
        payload.mass = arm.payload_kg
        payload.ipos = [0.0, 0.0, 0.0]
        payload.inertia = [1e-9 * arm.payload_kg] * 3
        payload.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], pos=[0, 0, radius + 0.005], mass=0,
            rgba=[0.3, 0.3, 0.3, 1], contype=0, conaffinity=0,
        )  # fmt: skip
    if arm.hold_tip:
        spec.add_equality(
            type=mujoco.mjtEq.mjEQ_WELD, name1=tip_body.name, name2="base", objtype=mujoco.mjtObj.mjOBJ_BODY,
            name="hold_tip", data=[0.0] * 10 + [1.0, 0.0], solref=[0.004, 1.0],
            solimp=[0.9999, 0.9999, 0.001, 0.5, 2.0],  # a test fixture: as rigid as MuJoCo allows
        )  # fmt: skip
    _add_sensors(spec, arm)


def _add_sensors(spec, arm):
    site = mujoco.mjtObj.mjOBJ_SITE
    spec.add_sensor(name="tip_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=site, objname="tip")
    spec.add_sensor(name="tip_quat", type=mujoco.mjtSensor.mjSENS_FRAMEQUAT, objtype=site, objname="tip")
    names = [n for section in muscle_names(arm) for n in section]
    for name in names:
        spec.add_sensor(
            name=f"len_{name}", type=mujoco.mjtSensor.mjSENS_TENDONPOS, objtype=mujoco.mjtObj.mjOBJ_TENDON, objname=name
        )  # fmt: skip
    for name in names:
        if spec.actuator(name) is None:
            continue
        spec.add_sensor(
            name=f"force_{name}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
            objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=name,
        )  # fmt: skip
    for instance in spec.plugins:
        if instance.plugin_name == plugin.PLUGIN_NAME:
            sensor = spec.add_sensor(name=f"pressures_{instance.name}", type=mujoco.mjtSensor.mjSENS_PLUGIN)
            sensor.plugin = instance


def build_model(arm: ArmSpec, muscles: str = "plugin") -> mujoco.MjModel:
    """Compile the arm (loads the plugin first)."""
    plugin.load()
    return build_spec(arm, muscles).compile()


def arm_xml(arm: ArmSpec) -> str:
    """The arm's MJCF."""
    plugin.load()
    spec = build_spec(arm)
    spec.compile()  # to_xml needs a compiled spec
    return spec.to_xml()


MODELS = {"arm_1x3": arm_1x3, "arm_3x3": arm_3x3}
MODELS_DIR = Path(__file__).resolve().parent.parent.parent / "models"


def write_models(directory: Path = MODELS_DIR) -> list[Path]:
    """Write models/arm_*.xml from the builder (atomically)."""
    return [
        write_text_atomic(Path(directory) / f"{name}.xml", arm_xml(make())) for name, make in MODELS.items()
    ]


# ------------------------------------------------------------------------ reading a model


def muscle_names(arm: ArmSpec) -> list[list[str]]:
    """Per section, the muscles' names (their actuator, whole-muscle tendon and sensor names)."""
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


def tip_in_base(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Tip site position in the arm's base frame."""
    return base_frame_position(model, data, data.site("tip").xpos)


def bend_in_base(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The arm's total bend (rad): the angle between the base's axis and the tip's (the
    ``tip_quat`` sensor)."""
    base = data.xmat[model.body("base").id].reshape(3, 3)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, data.sensor("tip_quat").data)
    axis = base.T @ rotation.reshape(3, 3)[:, 2]
    return float(math.acos(np.clip(axis[2], -1.0, 1.0)))


def gravity_in_base(arm: ArmSpec) -> np.ndarray:
    """Gravity (m/s^2) expressed in the base frame."""
    if not arm.gravity:
        return np.zeros(3)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(ORIENTATIONS[arm.orientation]))
    return rotation.reshape(3, 3).T @ np.array([0.0, 0.0, -9.81])


#: Most MuJoCo steps one :func:`settle` takes (counted, not timed). The settles the package asks
#: for are 1-60 s of simulated time, 60 000 steps at the default arm's 1 ms; a small, light
#: section's chosen step can be 1 us, where 40 s is 4e7 steps (half an hour): it stops here
#: instead, unsettled, with a warning (about 20 s of CPU for a small arm).
MAX_SETTLE_STEPS = 500_000


def settle(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    pressures_Pa,
    t_max_s: float = 6.0,
    vel_tol: float = 1e-6,
    max_steps: int = MAX_SETTLE_STEPS,
) -> bool:
    """Hold the pressures and step until the arm is still (or ``t_max_s`` of simulated time, or
    ``max_steps`` steps: then a warning says how far it got); returns whether it settled. Raises
    if the state stops being finite, and for pressures that are not one finite value per
    actuator inside its control range (MuJoCo would zero a NaN and clamp the rest silently),
    a ``t_max_s`` that is not a finite time >= 0 s and a ``max_steps`` that is not a whole
    number >= 1."""
    # a NaN or negative t_max_s returned 'not settled' at once without a step, inf ran until
    # max_steps; max_steps 0 or -5 warned of 'stopped after 0 steps', 2.5 ran 100 steps
    t_end = as_float(t_max_s)
    if not (math.isfinite(t_end) and t_end >= 0.0):
        raise ValueError(f"arm.settle: t_max_s must be a finite simulated time >= 0 s, got {t_max_s!r}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, numbers.Integral) or max_steps < 1:
        raise ValueError(
            f"arm.settle: max_steps must be a whole number of MuJoCo steps >= 1, got {max_steps!r}"
        )
    pressures = np.asarray(pressures_Pa, dtype=float)
    if pressures.ndim > 1 and pressures.size == model.nu:
        pressures = pressures.ravel()  # a nested list per section is the same pressures
    if pressures.shape != (model.nu,):
        raise ValueError(
            f"arm.settle: pressures_Pa needs one pressure per actuator ({model.nu}), got shape {pressures.shape}"
        )
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    limited = model.actuator_ctrllimited.astype(bool)
    bad = ~np.isfinite(pressures) | (limited & ((pressures < low) | (pressures > high)))
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(
            f"arm.settle: pressures_Pa[{i}] = {pressures[i]:g} Pa is not a finite pressure inside the actuator's "
            f"control range {low[i]:g} .. {high[i]:g} Pa (MuJoCo would zero or clamp it)"
        )
    check_pressure_Pa(pressures, "arm.settle: pressures_Pa")
    data.ctrl[:] = pressures
    steps = 0
    while data.time < t_max_s:
        if steps >= max_steps:
            warnings.warn(
                f"arm.settle: stopped after {steps} steps of {model.opt.timestep * 1e3:g} ms at t = "
                f"{data.time:.4g} s of the {t_max_s:g} s asked for (the step bound); the arm is not at rest",
                RuntimeWarning,
                stacklevel=2,
            )
            return False
        for _ in range(100):
            mujoco.mj_step(model, data)
        steps += 100
        if not np.all(np.isfinite(data.qpos)):
            raise FloatingPointError(f"arm state not finite at t = {data.time:.3f} s")
        if np.abs(data.qvel).max() < vel_tol:
            return True
    return False


def segment_tendons(model: mujoco.MjModel, name: str) -> np.ndarray:
    """Tendon ids of muscle ``name``'s segments (the tendons after its whole-muscle tendon)."""
    whole = model.tendon(name).id
    count = sum(1 for t in range(whole + 1, model.ntendon) if model.tendon(t).name.startswith(name + "_k"))
    return np.arange(whole + 1, whole + 1 + count)


def muscle_segment_lengths(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """Current length of each segment of muscle ``name``, m: the length the plugin gives the
    segment (its arc length, see :class:`SegmentLengths`)."""
    return SegmentLengths(model, [name])(data)


# ---------------------------------------------------------------- the segments' arc geometry
#
# The same geometry as the plugin's (efam_muscle.c, "arc geometry"), written from the same
# derivation: a link bends by the universal joint's swing (angle theta about the axis along
# sigma) and twists by tau; the bundle's disks are the swing-transported frames, so a muscle at
# offset (x, y) sits at Rz(-T) (x, y) in the MuJoCo frame of its link's proximal disk (T: the
# twists of all proximal links), and each half-link's arc at the muscle has length
# e phi(theta) + (y' sigma_x - x' sigma_y) / 2, phi(t) = (t / 2) / tan(t / 2) (blended into
# the linear e + (y' a - x' b) / 2 for bends beyond ARC_EXACT_UP_TO_RAD).

#: up to this bend of one link (rad) a segment's length is its arc's; beyond, it blends (C2 in
#: the bend) into the linear tendon geometry, fully at ARC_LINEAR_FROM_RAD (the swing is singular
#: at pi; a link bent that far is far outside the muscles' admissible lengths)
ARC_EXACT_UP_TO_RAD = 2.0
ARC_LINEAR_FROM_RAD = 2.5
_SERIES_BELOW = 0.25  # phi and t / sin t by their series in t^2 (to t^12) below this angle
_PHI_SERIES = (1.0, -1 / 12, -1 / 720, -1 / 30240, -1 / 1209600, -1 / 47900160, -691 / 1307674368000)
_T_OVER_SIN_SERIES = (1.0, 1 / 6, 7 / 360, 31 / 15120, 127 / 604800, 73 / 3421440, 1414477 / 653837184000)


def _link_hinges(model: mujoco.MjModel) -> list:
    """Per body: (hinge about x, hinge about y) if it is a link's node (two such hinges,
    otherwise only slides); None if it does not turn (slides or no joints); False for anything
    else (the world, other rotating joints: where the bundle's frame is rooted)."""
    types, axes = np.asarray(model.jnt_type), np.asarray(model.jnt_axis)
    first, count = np.asarray(model.body_jntadr), np.asarray(model.body_jntnum)
    hinge, slide = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
    out = [False]
    for body in range(1, model.nbody):
        turning = [j for j in range(first[body], first[body] + count[body]) if types[j] != slide]
        x = [j for j in turning if types[j] == hinge and list(axes[j]) == [1, 0, 0]]
        y = [j for j in turning if types[j] == hinge and list(axes[j]) == [0, 1, 0]]
        if not turning:
            out.append(None)
        else:
            out.append((x[0], y[0]) if len(turning) == 2 and len(x) == len(y) == 1 else False)
    return out


def _series(coefficients, t2):
    out = np.zeros_like(t2)
    for c in coefficients[::-1]:
        out = out * t2 + c
    return out


class SegmentLengths:
    """The lengths the plugin gives the segments of muscles ``names`` (m, concatenated in that
    order): each segment's arc length in its half-link when the muscle's plugin instance has
    ``arc_geometry`` on (the arms :func:`build_spec` makes: from ``data.qpos``), else its
    tendon's length (``data.ten_length``: after mj_forward). Parses the model once."""

    def __init__(self, model: mujoco.MjModel, names):
        tendons = [segment_tendons(model, n) for n in names]
        arc = []
        for name, t in zip(names, tendons):
            instance = model.actuator_plugin[model.actuator(name).id]
            config = plugin.instance_config(model, instance) if instance >= 0 and t.size else {}
            arc.append(np.full(t.size, config.get("arc_geometry") == "1"))
        self.tendons = np.concatenate(tendons).astype(int) if tendons else np.zeros(0, int)
        self.arc = np.concatenate(arc) if arc else np.zeros(0, bool)
        kinds = _link_hinges(model)
        links = [b for b in range(model.nbody) if kinds[b]]
        index = {b: k for k, b in enumerate(links)}
        hinges = [kinds[b] for b in links]
        self.qpos_a = np.array([model.jnt_qposadr[hx] for hx, _ in hinges], dtype=int)
        self.qpos_b = np.array([model.jnt_qposadr[hy] for _, hy in hinges], dtype=int)
        self.x_first = np.array([hx < hy for hx, hy in hinges], dtype=bool)
        # proximal[k, j]: link j is proximal to link k (its twist turns link k's muscles)
        self.proximal = np.zeros((len(links), len(links)))
        for k, b in enumerate(links):
            p = model.body_parentid[b]
            while kinds[p] is not False:
                if p in index:
                    self.proximal[k, index[p]] = 1.0
                p = model.body_parentid[p]
        rows = np.array([self._segment(model, t, index) for t in self.tendons[self.arc]]).reshape(-1, 4)
        self.link, self.slide = rows[:, 0].astype(int), rows[:, 1].astype(int)
        self.x, self.y = rows[:, 2], rows[:, 3]

    @staticmethod
    def _segment(model, tendon, index):
        """(link index, slide qpos address, x, y) of a segment tendon e + (y a - x b) / 2."""
        slide = coef_x = coef_y = node = None
        for w in range(model.tendon_adr[tendon], model.tendon_adr[tendon] + model.tendon_num[tendon]):
            j, c = model.wrap_objid[w], model.wrap_prm[w]
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
                slide = model.jnt_qposadr[j]
            elif list(model.jnt_axis[j]) == [1, 0, 0]:
                coef_x, node = c, model.jnt_bodyid[j]
            else:
                coef_y = c
        return index[node], slide, -2.0 * coef_y, 2.0 * coef_x

    def __call__(self, data: mujoco.MjData) -> np.ndarray:
        """The segment lengths in state ``data``."""
        out = data.ten_length[self.tendons]
        if self.arc.any():
            out[self.arc] = self.arc_lengths(data.qpos)
        return out

    def arc_lengths(self, qpos) -> np.ndarray:
        """The arc-geometry segments' lengths at joint positions ``qpos``."""
        qpos = np.asarray(qpos)
        a, b = qpos[self.qpos_a], qpos[self.qpos_b]
        sa, ca, sb, cb = np.sin(a), np.cos(a), np.sin(b), np.cos(b)
        u = np.where(self.x_first, [sa * cb, sb], [sa, ca * sb])  # (2, links)
        sin_theta = np.hypot(u[0], u[1])
        theta = np.arctan2(sin_theta, ca * cb)
        blend = np.clip((theta - ARC_EXACT_UP_TO_RAD) / (ARC_LINEAR_FROM_RAD - ARC_EXACT_UP_TO_RAD), 0.0, 1.0)
        weight = 1.0 - blend**3 * (10.0 - 15.0 * blend + 6.0 * blend**2)  # 1: the arc, 0: linear
        small = theta < _SERIES_BELOW
        safe = np.where(small | (weight == 0), 1.0, theta)
        safe_sin = np.where(small | (weight == 0), 1.0, sin_theta)
        t2 = theta**2
        phi = np.where(small, _series(_PHI_SERIES, t2), 0.5 * safe / np.tan(0.5 * safe))
        ratio = np.where(small, _series(_T_OVER_SIN_SERIES, t2), safe / safe_sin)
        sigma = ratio * u
        twist = np.where(self.x_first, 1.0, -1.0) * 2.0 * np.arctan2(np.sin(a / 2) * np.sin(b / 2),
                                                                    np.cos(a / 2) * np.cos(b / 2))  # fmt: skip
        T = (self.proximal @ (weight * twist))[self.link]
        x = np.cos(T) * self.x + np.sin(T) * self.y
        y = -np.sin(T) * self.x + np.cos(T) * self.y
        k, e = self.link, qpos[self.slide]
        arc = e * phi[k] + 0.5 * (y * sigma[0, k] - x * sigma[1, k])
        linear = e + 0.5 * (y * a[k] - x * b[k])
        return weight[k] * arc + (1.0 - weight[k]) * linear


__all__ = [
    "MODELS",
    "MODELS_DIR",
    "arm_xml",
    "base_frame_position",
    "build_model",
    "build_spec",
    "gravity_in_base",
    "muscle_names",
    "muscle_pressures",
    "muscle_segment_lengths",
    "node_inertias",
    "SegmentLengths",
    "segment_coefficients",
    "segment_tendons",
    "settle",
    "tip_in_base",
    "write_models",
]


def _quenched_settle(model, data, pressures_Pa, duration_s):
    data.ctrl[:] = np.ravel(pressures_Pa)
    end, kinetic, momentum = data.time + duration_s, 0.0, np.zeros(model.nv)
    while data.time < end - 1e-12:
        mujoco.mj_step(model, data)
        mujoco.mj_mulM(model, data, momentum, data.qvel)
        now = 0.5 * float(data.qvel @ momentum)
        if now < kinetic:
            data.qvel[:] = 0.0
            now = 0.0
        kinetic = now
    if not np.all(np.isfinite(data.qpos)):
        raise FloatingPointError(f"arm state not finite at t = {data.time:.3f} s")


def static_equilibrium(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    pressures_Pa,
    settle_s: float = 1.0,
    tol_N: float = 1e-9,
    rounds: int = 4,
) -> bool:
    """Put the arm at rest under constant pressures: a short settle to reach the branch the arm
    falls into (an undamped arm's settle is quenched: every velocity is zeroed whenever the
    kinetic energy falls, a descent to the nearest minimum of the potential energy instead of
    a swing through wild bends), then Newton on qpos (finite-difference stiffness) until the
    net generalized force is below ``tol_N``; if Newton does not get there (an arm still far
    from rest, e.g. rolling up into loops), another settle and Newton, up to ``rounds`` times.
    The pressure states are set to the pressures. Returns whether it converged (the state is
    left at the best point found)."""
    for _ in range(rounds):
        if model.dof_damping.any() or model.tendon_damping.any():
            # a short settle by design (Newton follows): its whole length, whatever the step
            steps = int(math.ceil(settle_s / model.opt.timestep)) + 100
            settle(model, data, pressures_Pa, t_max_s=data.time + settle_s, vel_tol=0.0, max_steps=steps)
        else:
            _quenched_settle(model, data, pressures_Pa, settle_s)
        data.ctrl[:] = np.ravel(pressures_Pa)
        lagged = np.flatnonzero(model.actuator_actadr >= 0)
        data.act[model.actuator_actadr[lagged]] = data.ctrl[lagged]
        if _newton(model, data, tol_N):
            return True
    return False


def _newton(model, data, tol_N) -> bool:
    q = data.qpos.copy()
    r = generalized_force(model, data)
    h = 1e-7
    for _ in range(50):
        if np.max(np.abs(r)) < tol_N:
            return True
        K = force_jacobian(model, data, q, r, h)
        step = np.linalg.lstsq(K, -r, rcond=None)[0]
        for scale in (1.0, 0.5, 0.25, 0.1, 0.03, 0.01):
            data.qpos[:] = q + scale * step
            trial = generalized_force(model, data)
            if np.linalg.norm(trial) < np.linalg.norm(r):
                q, r = data.qpos.copy(), trial
                break
        else:
            break
    data.qpos[:] = q
    generalized_force(model, data)
    return bool(np.max(np.abs(r)) < tol_N)
