"""Shared pieces of the EFAM suite: the scene around the arm, the ``Physics`` with named
accessors, and the base task (normalised pressure actions, randomised start).

Actions are pressure commands as fractions of each muscle's rated pressure, in [0, 1] (the
action spec is named ``pressure_fraction_of_rated``): action 1 asks for the actuator's upper
ctrl limit, the highest pressure the muscle was characterised at (517.1 kPa for the paper's
FAM1). The command reaches the muscle through the arm's first-order pressure lag (valve and
tube), time constant ``ArmSpec.pressure_tau_s``, 50 ms by default.

Every accessor reads named bodies, sites, sensors, actuators and tendons and computes the rest
geometrically; none reads a joint name or a constraint (see :mod:`.arm_glue`).
"""

from __future__ import annotations

import collections
import math
import numbers
import warnings

import mujoco as mj
import numpy as np
from dm_control import mujoco
from dm_control.mujoco import wrapper
from dm_control.suite import base
from dm_env import specs

from . import arm_glue, workspace

#: name of the action spec: the scaling is part of the name
ACTION_NAME = "pressure_fraction_of_rated"
#: seconds of physics run at the random initial pressures before an episode starts
WARMUP_S = 0.5

# ------------------------------------------------------------------------------ the scene

_MATERIALS = {
    # name: rgba (dm_control's reward colouring blends <name>_default into <name>_highlight)
    "self": (0.55, 0.55, 0.6, 1.0),
    "self_default": (0.55, 0.55, 0.6, 1.0),
    "self_highlight": (0.25, 0.6, 0.35, 1.0),
    "effector": (0.85, 0.2, 0.15, 1.0),
    "effector_default": (0.85, 0.2, 0.15, 1.0),
    "effector_highlight": (0.2, 0.75, 0.3, 1.0),
    "target": (0.95, 0.75, 0.1, 0.45),
    "target_default": (0.95, 0.75, 0.1, 0.45),
    "target_highlight": (0.2, 0.75, 0.3, 0.45),
}
EFFECTOR_RADIUS_M = 0.008
#: site group of the muscle anchors (hidden in MuJoCo's viewer, whose default shows groups 0-2)
MUSCLE_SITE_GROUP = 5
#: the force plate is stiff (MuJoCo's soft contacts scale with the light tip's effective mass:
#: the defaults let a 100 N push sink centimetres into the plate)
PLATE_SOLREF = (0.004, 1.0)
PLATE_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)


def _look_at(position, target):
    """MuJoCo ``xyaxes`` of a camera at ``position`` looking at ``target`` (world z up)."""
    forward = np.asarray(target, float) - np.asarray(position, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return np.concatenate([right, up]).tolist()


def build_scene(
    arm_spec,
    *,
    target_radius_m: float = 0.01,
    force_plate: bool = False,
    payload_max_kg: float = 0.0,
) -> mj.MjSpec:
    """The arm of ``arm_spec`` in a scene: floor, skybox, lights, cameras ``side`` (the
    builder's), ``front`` and ``perspective``; an effector ball on the tip, a mocap ``target``
    and sensor ``tip_vel``; optionally a ``force_plate`` (touch sensor ``plate_force``; the
    only contact pair of the model) and a ``payload`` body on the tip plate (its mass is set
    per episode)."""
    spec = arm_glue.build_arm_spec(arm_spec)
    spec.modelname = arm_spec.name
    _name_unnamed(spec)
    for name, rgba in _MATERIALS.items():
        spec.add_material(name=name, rgba=list(rgba))
    spec.add_texture(
        name="skybox", type=mj.mjtTexture.mjTEXTURE_SKYBOX, builtin=mj.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[0.6, 0.75, 0.9], rgb2=[0.08, 0.1, 0.15], width=512, height=512,
    )  # fmt: skip
    spec.add_texture(
        name="grid", type=mj.mjtTexture.mjTEXTURE_2D, builtin=mj.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=[0.82, 0.82, 0.8], rgb2=[0.68, 0.68, 0.66], width=256, height=256, mark=mj.mjtMark.mjMARK_EDGE,
        markrgb=[0.6, 0.6, 0.6],
    )  # fmt: skip
    grid = spec.add_material(name="grid", texrepeat=[6, 6], reflectance=0.1)
    grid.textures[mj.mjtTextureRole.mjTEXROLE_RGB] = "grid"

    quat = arm_glue.base_quaternion(arm_spec)
    axis = np.zeros(9)
    mj.mju_quat2Mat(axis, quat)
    axis = axis.reshape(3, 3)[:, 2]  # the arm's axis in the world
    reach = 2.2 * arm_glue.rest_length_m(arm_spec)  # about the longest the arm gets
    floor_z = min(0.0, float(axis[2]) * reach) - 0.05
    world = spec.worldbody
    world.add_geom(
        name="floor", type=mj.mjtGeom.mjGEOM_PLANE, size=[1.5 * reach, 1.5 * reach, 0.05], pos=[0, 0, floor_z],
        material="grid", contype=0, conaffinity=0,
    )  # fmt: skip
    # the mount the base hangs from or stands on
    mount_z = 0.015 if axis[2] < 0 else -0.015
    world.add_geom(
        name="mount", type=mj.mjtGeom.mjGEOM_BOX, size=[0.06, 0.06, 0.01], pos=[0, 0, mount_z],
        material="self", contype=0, conaffinity=0,
    )  # fmt: skip
    centre = axis * 0.5 * reach
    world.add_light(name="key", pos=(centre + [0.6 * reach, -0.8 * reach, 1.2 * reach]).tolist(),
                    dir=(-np.array([0.6, -0.8, 1.2])).tolist(), diffuse=[0.6, 0.6, 0.6], castshadow=True)  # fmt: skip
    for name, offset in (
        ("front", [1.6 * reach, 0.0, 0.2 * reach]),
        ("perspective", [1.1 * reach, -1.1 * reach, 0.6 * reach]),
    ):
        position = centre + offset
        world.add_camera(name=name, pos=position.tolist(), xyaxes=_look_at(position, centre))

    _add_muscle_anchors(spec, arm_spec)
    tip_site = spec.site("tip")
    tip_body = tip_site.parent
    tip_body.add_geom(
        name="effector", type=mj.mjtGeom.mjGEOM_SPHERE, size=[EFFECTOR_RADIUS_M, 0, 0], pos=list(tip_site.pos),
        material="effector", mass=0, contype=1 if force_plate else 0, conaffinity=0,
    )  # fmt: skip
    spec.add_sensor(
        name="tip_vel", type=mj.mjtSensor.mjSENS_FRAMELINVEL, objtype=mj.mjtObj.mjOBJ_SITE, objname="tip"
    )
    target = world.add_body(name="target", mocap=True, pos=(axis * arm_glue.rest_length_m(arm_spec)).tolist())
    target.add_geom(
        name="target", type=mj.mjtGeom.mjGEOM_SPHERE, size=[target_radius_m, 0, 0], material="target",
        contype=0, conaffinity=0,
    )  # fmt: skip
    if force_plate:
        spec.option.disableflags &= ~int(mj.mjtDisableBit.mjDSBL_CONTACT)
        plate = world.add_body(name="force_plate", quat=quat.tolist())
        half = 0.3 * reach
        plate.add_geom(
            name="force_plate", type=mj.mjtGeom.mjGEOM_BOX, size=[half, half, 0.004], pos=[0, 0, 0.004],
            rgba=[0.3, 0.35, 0.45, 1], contype=0, conaffinity=1, condim=3, friction=[1.5, 0.005, 0.0001],
            solref=list(PLATE_SOLREF), solimp=list(PLATE_SOLIMP),
        )  # fmt: skip
        plate.add_site(
            name="plate_site", type=mj.mjtGeom.mjGEOM_BOX, size=[half, half, 0.02], rgba=[0, 0, 0, 0]
        )
        spec.add_sensor(name="plate_force", type=mj.mjtSensor.mjSENS_TOUCH, objtype=mj.mjtObj.mjOBJ_SITE,
                        objname="plate_site")  # fmt: skip
    if payload_max_kg > 0:
        radius = (3 * payload_max_kg / (4 * math.pi * 7800.0)) ** (1 / 3)  # a steel ball
        payload = tip_body.add_body(
            name="payload", pos=(np.array(tip_site.pos) + [0, 0, radius + 0.006]).tolist()
        )
        payload.add_geom(
            name="payload", type=mj.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], mass=payload_max_kg,
            rgba=[0.3, 0.3, 0.32, 1], contype=0, conaffinity=0,
        )  # fmt: skip
    return spec


def _add_muscle_anchors(spec: mj.MjSpec, arm_spec) -> None:
    """Invisible sites ``{muscle}_at{k}`` where each muscle crosses its section's base plate
    (k = 0) and its spacer disks (k = 1..D), sized to the muscle's outer radius: what
    :meth:`EfamPhysics.render` draws the muscles between (the muscles are fixed tendons, which
    MuJoCo does not draw; drawing them at render time costs the physics step nothing)."""
    chains = arm_glue.section_chains([body.name for body in spec.bodies])
    names = iter(arm_glue.muscle_names(arm_spec))
    for section, chain in zip(arm_spec.sections, chains):
        for muscle, (x, y) in zip(section.muscles, section.offsets_m()):
            name = next(names)
            for k, body in enumerate(chain):
                spec.body(body).add_site(
                    name=f"{name}_at{k}", pos=[float(x), float(y), 0.0], size=[muscle.rest_outer_radius_m, 0, 0],
                    group=MUSCLE_SITE_GROUP, rgba=[0, 0, 0, 0],
                )  # fmt: skip


def _name_unnamed(spec: mj.MjSpec) -> None:
    """Name every unnamed element (dm_control's suite wants all components named)."""
    for kind in ("geoms", "lights", "equalities", "cameras", "sites", "textures", "materials", "tendons"):
        for index, element in enumerate(getattr(spec, kind)):
            if not element.name:
                parent = getattr(element, "parent", None)
                prefix = parent.name if parent is not None and getattr(parent, "name", "") else kind[:-1]
                element.name = f"{prefix}_{kind.rstrip('s')}{index}"


def make_physics(physics_class, scene: mj.MjSpec):
    """A dm_control ``Physics`` of ``physics_class`` from a scene spec."""
    model = scene.compile()
    return physics_class.from_model(wrapper.MjModel(model))


# ------------------------------------------------------------------------------ physics


class _Layout:
    """Indices into the model, found by name once per model."""

    def __init__(self, model):
        names = [model.id2name(i, "body") for i in range(model.nbody)]
        self.base = names.index("base")
        # per section, as plain ints for the per-step accessors: its backbone bodies (its base
        # plate, then its disks) and its (base, end plate) pair
        self.backbone_chains = [[names.index(n) for n in chain] for chain in arm_glue.section_chains(names)]
        self.section_ends = [(chain[0], chain[-1]) for chain in self.backbone_chains]
        sensor = lambda n: int(model.sensor_adr[model.name2id(n, "sensor")])
        self.tip_pos = sensor("tip_pos")
        self.tip_vel = sensor("tip_vel")
        has_plate = "plate_force" in [model.id2name(i, "sensor") for i in range(model.nsensor)]
        self.plate_force = sensor("plate_force") if has_plate else None
        self.actuator_names = [model.id2name(a, "actuator") for a in range(model.nu)]
        self.tendons = np.array([model.name2id(n, "tendon") for n in self.actuator_names])
        self.rated = np.array(model.actuator_ctrlrange[:, 1], dtype=float)
        if np.any(self.rated <= 0):
            raise ValueError(
                "model: every muscle actuator needs a positive upper ctrl limit (its rated pressure)"
            )
        self.act_adr = np.array(model.actuator_actadr)
        self.all_lagged = bool(np.all(self.act_adr >= 0))
        self.target_mocap = int(model.body_mocapid[model.name2id("target", "body")])
        # per muscle: its anchor sites (base plate, then disks), width and colour, for drawing
        site_names = [model.id2name(i, "site") for i in range(model.nsite)]
        self.muscle_anchors = []
        for name in self.actuator_names:
            anchors = [i for i, site in enumerate(site_names) if (site or "").startswith(name + "_at")]
            anchors.sort(key=lambda i: int(site_names[i][len(name) + 3 :]))
            if anchors:
                colour = model.tendon_rgba[model.name2id(name, "tendon")].copy()
                self.muscle_anchors.append((np.array(anchors), float(model.site_size[anchors[0], 0]), colour))


class _Views:
    """The raw ``mujoco.MjData`` arrays the accessors read (dm_control's wrapped attribute access
    costs microseconds per call: more than the accessors themselves)."""

    def __init__(self, data):
        raw = data.ptr
        self.owner = data  # the dm_control wrapper these views belong to
        self.data_ptr, self.model_ptr = raw, data.model.ptr
        self.warnings = raw.warning.number  # MuJoCo's warning counters
        for name in (
            "sensordata",
            "xpos",
            "xmat",
            "mocap_pos",
            "act",
            "ctrl",
            "ten_length",
            "actuator_force",
            "site_xpos",
        ):
            setattr(self, name, getattr(raw, name))


class EfamPhysics(mujoco.Physics):
    """``Physics`` of an EFAM arm, with named accessors (world frame unless said otherwise).

    Steps are plain ``mj_step`` calls (``legacy_step = False``): after a step the kinematics
    and sensors are those MuJoCo computed at the start of its last physics step (1 ms before the
    integrated state), as everywhere ``mj_step`` is used. dm_control's legacy stepping splits the
    first and last step in two, which costs measurably on the light bundle.
    """

    legacy_step = False

    def step(self, nstep: int = 1) -> None:
        """Advance ``nstep`` physics steps with ``mj_step``. A MuJoCo warning raised on the way
        is reported by dm_control's own check (``PhysicsError``, or a log line inside
        ``suppress_physics_errors``), as in ``Physics.step``; the counters are compared here
        first because that check's context manager costs about 1 % of a bundle control step."""
        views = self.views
        counts = views.warnings
        before = counts.tobytes()  # the cheapest snapshot: two method calls per step in all
        mj.mj_step(views.model_ptr, views.data_ptr, nstep)
        if counts.tobytes() != before:  # counters only grow during a step
            after = counts.copy()
            counts[:] = np.frombuffer(before, dtype=counts.dtype)
            with self.check_invalid_state():  # raises or logs with dm_control's message
                counts[:] = after

    @property
    def layout(self) -> _Layout:
        """Model indices (bodies, sites, actuators, sensors) the accessors use, computed once per model."""
        layout = self.__dict__.get("_efam_layout")
        if layout is None:
            layout = self.__dict__["_efam_layout"] = _Layout(self.model)
        return layout

    @property
    def views(self) -> _Views:
        """Cached numpy views into the current mjData, rebuilt after a reload or copy."""
        views = self.__dict__.get("_efam_views")
        if views is None or views.owner is not self._data:  # new data after a reload or copy
            views = self.__dict__["_efam_views"] = _Views(self.data)
        return views

    # -- rendering
    def render(
        self, height=240, width=320, camera_id=-1, overlays=(), depth=False, segmentation=False,
        scene_option=None, render_flag_overrides=None, scene_callback=None,
    ):  # fmt: skip
        """``dm_control``'s ``Physics.render`` with the muscles drawn (see :meth:`draw_muscles`)
        before any ``scene_callback`` of the caller."""
        check_image_size(height, width, "height, width")

        def callback(physics, scene):
            physics.draw_muscles(scene)
            if scene_callback is not None:
                scene_callback(physics, scene)

        return super().render(
            height, width, camera_id, overlays, depth, segmentation, scene_option, render_flag_overrides,
            scene_callback=callback,
        )  # fmt: skip

    def draw_muscles(self, scene) -> int:
        """Add each muscle to a ``mujoco.MjvScene`` as capsules of its outer radius and its
        tendon's colour, straight from plate to plate through its anchor sites (MuJoCo does not
        draw the muscles' fixed tendons). Returns the number of capsules added (fewer when the
        scene is full)."""
        site_xpos = self.views.site_xpos
        added = 0
        for anchors, radius, colour in self.layout.muscle_anchors:
            points = site_xpos[anchors]
            for start, end in zip(points[:-1], points[1:]):
                if scene.ngeom >= scene.maxgeom:
                    return added
                scene.ngeom += 1  # first: the bindings expose only the first ngeom geoms
                geom = scene.geoms[scene.ngeom - 1]
                mj.mjv_initGeom(
                    geom, mj.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.zeros(9), colour
                )
                mj.mjv_connector(geom, mj.mjtGeom.mjGEOM_CAPSULE, radius, start, end)
                geom.category = mj.mjtCatBit.mjCAT_DYNAMIC
                added += 1
        return added

    # -- frames
    def base_frame(self):
        """Position and rotation matrix of the arm's base plate."""
        b, views = self.layout.base, self.views
        return views.xpos[b].copy(), views.xmat[b].reshape(3, 3).copy()

    def to_world(self, point_in_base):
        """A point given in the arm's base frame, in the world."""
        p, R = self.base_frame()
        return p + R @ np.asarray(point_in_base, float)

    def to_base(self, point_in_world):
        """A world point in the arm's base frame."""
        p, R = self.base_frame()
        return R.T @ (np.asarray(point_in_world, float) - p)

    # -- tip
    def tip_position(self) -> np.ndarray:
        """Tip site position (sensor ``tip_pos``), m."""
        adr = self.layout.tip_pos
        return self.views.sensordata[adr : adr + 3].copy()

    def tip_velocity(self) -> np.ndarray:
        """Tip site linear velocity (sensor ``tip_vel``), m/s."""
        adr = self.layout.tip_vel
        return self.views.sensordata[adr : adr + 3].copy()

    def target_position(self) -> np.ndarray:
        """Position of the mocap ``target``, m."""
        return self.views.mocap_pos[self.layout.target_mocap].copy()

    def set_target_position(self, position) -> None:
        """Move the target marker (mocap body) to ``position`` (world frame, m)."""
        self.views.mocap_pos[self.layout.target_mocap] = position

    def tip_to_target_distance(self) -> float:
        """Distance from the tip to the target, m."""
        views, adr = self.views, self.layout.tip_pos
        return math.dist(views.mocap_pos[self.layout.target_mocap], views.sensordata[adr : adr + 3])

    # -- sections
    def section_bends(self) -> np.ndarray:
        """Per section, the bend as a vector theta (cos phi, sin phi) in its base plate's frame
        (rad): theta the angle between the base and end plate axes, phi the direction the end
        plate's axis leans towards."""
        layout = self.layout
        xmat = self.views.xmat.tolist()  # every body's row-major 3x3, as floats: one numpy call
        out = [(0.0, 0.0)] * len(layout.section_ends)
        for j, (b, e) in enumerate(layout.section_ends):
            R0, R1 = xmat[b], xmat[e]
            # the end plate's axis (third column of R1) in the base plate's frame (R0^T z1)
            vx = R0[0] * R1[2] + R0[3] * R1[5] + R0[6] * R1[8]
            vy = R0[1] * R1[2] + R0[4] * R1[5] + R0[7] * R1[8]
            vz = R0[2] * R1[2] + R0[5] * R1[5] + R0[8] * R1[8]
            lateral = math.hypot(vx, vy)
            if lateral > 1e-12:
                scale = math.atan2(lateral, vz) / lateral
                out[j] = (vx * scale, vy * scale)
        return np.array(out)

    def section_lengths(self) -> np.ndarray:
        """Per section, the backbone length: the polyline through its plates' centres, m."""
        return np.array(self.section_length_values())

    def section_length_values(self) -> list[float]:
        """:meth:`section_lengths` as a list of floats (the per-step rewards' form: every numpy
        call costs microseconds after a control step's physics)."""
        return arm_glue.backbone_lengths(self.views.xpos.tolist(), self.layout.backbone_chains)

    # -- muscles
    def rated_pressures_Pa(self) -> np.ndarray:
        """Each muscle's rated pressure (its actuator's upper ctrl limit), Pa: action 1."""
        return self.layout.rated.copy()

    def muscle_pressures_Pa(self) -> np.ndarray:
        """The pressure each muscle acts with (after the lag), Pa."""
        layout, views = self.layout, self.views
        if layout.all_lagged:  # the default: every muscle's pressure is its activation
            return views.act[layout.act_adr]
        return arm_glue.muscle_pressures_Pa(layout.act_adr, views.act, views.ctrl, layout.rated)

    def muscle_pressure_fractions(self) -> np.ndarray:
        """:meth:`muscle_pressures_Pa` over the rated pressures."""
        return self.muscle_pressures_Pa() / self.layout.rated

    def muscle_lengths(self) -> np.ndarray:
        """Tendon length of each muscle, m."""
        return self.views.ten_length[self.layout.tendons].copy()

    def muscle_forces(self) -> np.ndarray:
        """Actuator force of each muscle, N (push positive)."""
        return self.views.actuator_force.copy()

    def set_pressure_fractions(self, fractions) -> None:
        """Command pressures (fractions of rated) and set the lagged pressure state to them."""
        pressures = np.clip(np.asarray(fractions, float), 0.0, 1.0) * self.layout.rated
        views, adr = self.views, self.layout.act_adr
        views.ctrl[:] = pressures
        views.act[adr[adr >= 0]] = pressures[adr >= 0]

    # -- force plate
    def plate_force(self) -> float:
        """Normal force on the force plate (touch sensor ``plate_force``), N."""
        if self.layout.plate_force is None:
            raise ValueError("this model has no force plate")
        return float(self.views.sensordata[self.layout.plate_force])


# -------------------------------------------------------------------------------- tasks


def refuse_unreal_action(action) -> None:
    """Refuse an action that is not real numbers, naming its dtype: complex, text or objects
    ended deep in numpy's casting rules (or, cast by the gym adapter, went through with numpy's
    warning)."""
    dtype = np.asarray(action).dtype
    if dtype.kind not in "fiu":
        raise ValueError(f"action must be real pressure fractions in [0, 1], got an array of dtype {dtype}")


class EfamTask(base.Task):
    """Base task: actions are pressure fractions of rated in [0, 1]; an episode starts from a
    random reachable shape (random pressures within the workspace limits, held for
    ``WARMUP_S``)."""

    def __init__(self, arm_spec, limits: workspace.WorkspaceLimits, random=None):
        super().__init__(random=random)
        self.arm_spec = arm_spec
        self.limits = limits

    def action_spec(self, physics):
        return specs.BoundedArray(
            shape=(physics.model.nu,), dtype=np.float64, minimum=0.0, maximum=1.0, name=ACTION_NAME
        )

    def before_step(self, action, physics):
        """Pressure fractions in [0, 1] to the actuators' controls. An action outside [0, 1] is
        clipped with a warning (once per task: saturation is never silent, as in the gym
        wrapper); a non-finite one is an error (MuJoCo would take NaN controls), and so is one
        of another shape than the action spec's (numpy would spread a single number over every
        muscle without a word, and name a wrong length only as a broadcasting failure)."""
        action = getattr(action, "continuous_actions", action)
        if np.shape(action) != physics.views.ctrl.shape:
            raise ValueError(
                f"action must hold one pressure fraction per muscle, shape {physics.views.ctrl.shape} "
                f"(the action spec's), got shape {np.shape(action)}"
            )
        refuse_unreal_action(action)
        low, high = np.min(action), np.max(action)
        if not (low >= 0.0 and high <= 1.0):
            if not (np.isfinite(low) and np.isfinite(high)):
                raise ValueError(
                    f"action must be finite pressure fractions in [0, 1], got {np.asarray(action).tolist()}"
                )
            if not getattr(self, "_told_clipped", False):
                self._told_clipped = True
                warnings.warn(
                    f"action {np.asarray(action).tolist()} is outside [0, 1]: clipped to the muscles' pressure "
                    "range (said once per task)",
                    RuntimeWarning,
                    stacklevel=2,
                )
        # np.clip costs more than the two ufuncs on arrays this small
        np.multiply(np.minimum(np.maximum(action, 0.0), 1.0), physics.layout.rated, out=physics.views.ctrl)

    def initialize_episode(self, physics):
        physics.forward()  # the base frame, for targets given in it
        self.initialize_task(physics)
        start = workspace.sample_pressures(self.arm_spec, self.random, self.start_limits())
        physics.set_pressure_fractions(start)
        steps = int(round(WARMUP_S / physics.model.opt.timestep))
        physics.step(steps)
        physics.data.time = 0.0
        super().initialize_episode(physics)

    def initialize_task(self, physics):
        """Draw the episode's target (subclasses)."""

    def start_limits(self) -> workspace.WorkspaceLimits:
        """Where the random initial shape is drawn from (by default, the task's limits)."""
        return self.limits

    def common_observations(self, physics) -> collections.OrderedDict:
        """Tip position and velocity, lagged pressures (fractions of rated), section bends and
        lengths (read directly: this runs every control step)."""
        layout, sensordata = physics.layout, physics.views.sensordata
        obs = collections.OrderedDict()
        obs["tip_position"] = sensordata[layout.tip_pos : layout.tip_pos + 3].copy()
        obs["tip_velocity"] = sensordata[layout.tip_vel : layout.tip_vel + 3].copy()
        obs["pressures"] = physics.muscle_pressure_fractions()
        obs["section_bends"] = physics.section_bends().ravel()
        obs["section_lengths"] = physics.section_lengths()
        return obs


def check_image_size(height, width, argument: str) -> None:
    """Refuse an image size that is not whole numbers of pixels >= 1 each way (ValueError naming
    ``argument``): dm_control checks only the framebuffer's upper bound; a negative size fails in
    numpy with a message naming nothing, a zero one gives an empty image."""
    for value in (height, width):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
            raise ValueError(
                f"{argument}: an image is at least 1 x 1 pixels (whole numbers), got {height!r} x {width!r}"
            )


def make_environment(
    physics_class, arm_spec, task, *, time_limit, control_timestep, environment_kwargs=None, **scene_options
):
    """A ``control.Environment`` of ``task`` on ``arm_spec`` in its scene."""
    from dm_control.rl import control

    physics = make_physics(physics_class, build_scene(arm_spec, **scene_options))
    options = {"legacy_step": False, **(environment_kwargs or {})}  # see EfamPhysics
    return control.Environment(
        physics, task, time_limit=time_limit, control_timestep=control_timestep, **options
    )
