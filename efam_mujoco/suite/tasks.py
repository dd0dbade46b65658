"""The suite's tasks, shared by every domain: reach, track, extend, push, reach_payload.

Rewards are in [0, 1], from :func:`dm_control.utils.rewards.tolerance` with its ``long_tail``
sigmoid (evaluated by :func:`long_tail_tolerance`, the same function on one float). Targets come from the
reachable workspace (:mod:`.workspace`): each is where the suite's statics puts the arm at
rest under admissible pressures, so every episode is solvable.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dm_control.utils import containers

from ..units import as_float
from . import arm_glue, common, workspace

# ------------------------------------------------------------------------------------- reach


#: ``long_tail``'s scale at dm_control's default value 0.1 at the margin: sqrt(1 / 0.1 - 1)
_LONG_TAIL_SCALE = math.sqrt(1.0 / 0.1 - 1.0)


def long_tail_tolerance(x: float, bounds: tuple[float, float], margin: float) -> float:
    """``dm_control.utils.rewards.tolerance(x, bounds, margin, sigmoid="long_tail")`` for one
    float, in plain Python: 1 inside the bounds, else ``1 / ((d s)^2 + 1)`` with d the distance
    to the nearer bound over ``margin`` and s = 3 (0.1 at the margin); 0 outside when
    ``margin`` is 0. The same values as dm_control's (a test compares them); its dozen numpy
    calls, cold after the physics of a control step, were the largest Python cost of a step."""
    lower, upper = bounds
    if lower > upper or margin < 0:
        raise ValueError(f"tolerance: needs lower <= upper and margin >= 0, got {bounds}, {margin}")
    if lower <= x <= upper:
        return 1.0
    if margin == 0:
        return 0.0
    distance = (lower - x if x < lower else x - upper) / margin
    return 1.0 / ((distance * _LONG_TAIL_SCALE) ** 2 + 1.0)


class Reach(common.EfamTask):
    """Bring the tip to a target drawn from the reachable workspace and hold it there.

    Reward: 1 within ``target_radius_m`` of the target, falling off with a long tail to 0.1 at
    ten radii further. An episode is a success when the tip ends within the radius.
    """

    def __init__(self, arm_spec, limits, target_radius_m: float, payload_range_kg=(0.0, 0.0), random=None):
        super().__init__(arm_spec, limits, random=random)
        if not (target_radius_m > 0):
            raise ValueError(f"reach: target_radius_m must be positive, got {target_radius_m}")
        lo, hi = payload_range_kg
        if not (0 <= lo <= hi):
            raise ValueError(f"reach: payload_range_kg must satisfy 0 <= lo <= hi, got {payload_range_kg}")
        self.target_radius_m = float(target_radius_m)
        self.payload_range_kg = (float(lo), float(hi))
        self.payload_kg = 0.0
        self.target_in_base = np.zeros(3)

    def initialize_task(self, physics):
        lo, hi = self.payload_range_kg
        if hi > 0:
            self.payload_kg = float(self.random.uniform(lo, hi))
            _set_payload(physics, self.payload_kg, hi)
        target, _ = workspace.sample_target(
            self.arm_spec, self.random, self.limits, payload_kg=self.payload_kg
        )
        self.target_in_base = target
        physics.set_target_position(physics.to_world(target))

    def get_observation(self, physics):
        obs = self.common_observations(physics)
        obs["target_position"] = physics.target_position()
        return obs

    def get_reward(self, physics):
        radius = self.target_radius_m
        return long_tail_tolerance(physics.tip_to_target_distance(), (0.0, radius), 10 * radius)

    def success(self, physics) -> bool:
        """The tip is within ``target_radius_m`` of the target."""
        return physics.tip_to_target_distance() <= self.target_radius_m


def _set_payload(physics, mass_kg: float, built_mass_kg: float) -> None:
    """Give the ``payload`` body ``mass_kg`` (its inertia scaled with it)."""
    body = physics.model.name2id("payload", "body")
    if not hasattr(physics, "_payload_inertia"):
        physics.__dict__["_payload_inertia"] = physics.model.body_inertia[body].copy() / built_mass_kg
    physics.model.body_mass[body] = mass_kg
    physics.model.body_inertia[body] = physics.__dict__["_payload_inertia"] * mass_kg


class ReachPayload(Reach):
    """:class:`Reach` with a payload on the tip whose mass is drawn per episode and not observed
    (a steel ball; the target is reachable with that payload)."""


# ------------------------------------------------------------------------------------- track


class Track(Reach):
    """Follow a target that circles through the workspace.

    Each episode draws a reachable shape of bend theta and direction phi per section; the target
    is where the suite's statics puts the tip as every section's bend direction turns by
    2 pi t / T (period T in ``period_range_s``): a closed loop around the arm's axis, sampled
    at ``LOOP_POINTS`` shapes and interpolated by a Fourier series. Reward as in
    :class:`Reach`, at every step.
    """

    LOOP_POINTS = 12
    HARMONICS = 3

    def __init__(self, arm_spec, limits, target_radius_m, period_range_s=(5.0, 10.0), random=None):
        super().__init__(arm_spec, limits, target_radius_m, random=random)
        self.period_range_s = period_range_s
        self._coefficients = np.zeros((2 * self.HARMONICS + 1, 3))
        self.period_s = period_range_s[1]
        self._target_velocity = [0.0, 0.0, 0.0]
        self._world_constant, self._world_harmonics = [0.0, 0.0, 0.0], []

    def initialize_task(self, physics):
        self.period_s = float(self.random.uniform(*self.period_range_s))
        sections = arm_glue.section_muscles(self.arm_spec)
        shapes = [
            workspace.sample_section_shape(
                section, self.arm_spec.max_pressure_Pa, self.loop_limits(), self.random
            )[0]
            for section in sections
        ]
        direction = self.random.choice([-1.0, 1.0])
        phases = 2 * math.pi * np.arange(self.LOOP_POINTS) / self.LOOP_POINTS
        loop = []
        for index, phase in enumerate(phases):
            pressures = []
            for (s, kx, ky), section in zip(shapes, sections):
                c, si = math.cos(direction * phase), math.sin(direction * phase)
                rotated = (s, c * kx - si * ky, si * kx + c * ky)
                pressures.append(_shape_pressures(section, rotated, self.arm_spec.max_pressure_Pa))
            tip, _ = arm_glue.reference_tip(self.arm_spec, np.concatenate(pressures), warm=index > 0)
            loop.append(tip)
        self._coefficients = _fourier_fit(phases, np.array(loop), self.HARMONICS)
        # the same series in the world frame, as plain floats: evaluated every control step
        base_position, R = physics.base_frame()
        world = self._coefficients @ R.T
        world[0] += base_position
        self._world_constant = world[0].tolist()
        self._world_harmonics = [
            (world[2 * h - 1].tolist(), world[2 * h].tolist()) for h in range(1, self.HARMONICS + 1)
        ]
        self.target_in_base = self.target_at(0.0)[0]
        self._update_target(physics, 0.0)

    def loop_limits(self) -> workspace.WorkspaceLimits:
        """Shapes the loop turns through: bends at most 2/3 of the workspace's, so that the
        rotated shapes stay reachable."""
        return workspace.WorkspaceLimits(self.limits.pressure_range, self.limits.max_bend_deg * 2 / 3)

    def target_at(self, time_s: float):
        """Target position and velocity (base frame) at ``time_s``."""
        omega = 2 * math.pi / self.period_s
        return _fourier_eval(self._coefficients, omega * time_s, omega)

    def _update_target(self, physics, time_s):
        omega = 2 * math.pi / self.period_s
        phase = omega * time_s
        position, velocity = list(self._world_constant), [0.0, 0.0, 0.0]
        for h, (a, b) in enumerate(self._world_harmonics, start=1):
            c, s = math.cos(h * phase), math.sin(h * phase)
            for i in range(3):
                position[i] += a[i] * c + b[i] * s
                velocity[i] += h * omega * (b[i] * c - a[i] * s)
        physics.set_target_position(position)
        self._target_velocity = velocity

    def after_step(self, physics):
        # observation and reward of this step see the target where it is now
        self._update_target(physics, physics.data.time)
        super().after_step(physics)

    def get_observation(self, physics):
        obs = super().get_observation(physics)
        obs["target_velocity"] = np.array(self._target_velocity)
        return obs


def _shape_pressures(section, shape, max_pressure_Pa):
    """Pressures (Pa) that hold a section unloaded in the arc ``shape = (s, kx, ky)``."""
    muscles, radii, angles = section
    s, kx, ky = shape
    lengths = s * (1.0 - radii * (kx * np.cos(angles) + ky * np.sin(angles)))
    return np.array(
        [arm_glue.pressure_for_free_length(m, L, max_pressure_Pa) for m, L in zip(muscles, lengths)]
    )


def _fourier_fit(phases, points, harmonics):
    columns = [np.ones_like(phases)]
    for h in range(1, harmonics + 1):
        columns += [np.cos(h * phases), np.sin(h * phases)]
    basis = np.column_stack(columns)
    coefficients, *_ = np.linalg.lstsq(basis, points, rcond=None)
    return coefficients


def _fourier_eval(coefficients, phase, omega):
    """Position and velocity of the series (rows: constant, then cos h, sin h per harmonic)."""
    h = np.arange(1, (len(coefficients) - 1) // 2 + 1)
    cos, sin = np.cos(h * phase), np.sin(h * phase)
    basis = np.empty(len(coefficients))
    basis[0], basis[1::2], basis[2::2] = 1.0, cos, sin
    rate = np.empty(len(coefficients))
    rate[0], rate[1::2], rate[2::2] = 0.0, -h * omega * sin, h * omega * cos
    return basis @ coefficients, rate @ coefficients


# ------------------------------------------------------------------------------------ extend


class Extend(common.EfamTask):
    """Hold every section at a target length (its backbone length).

    Targets are the section lengths at which the suite's statics holds the arm with equal
    pressures in each section (a fraction drawn per section from the workspace's pressure
    range). Reward: the mean over sections of 1 within ``tolerance_m`` of the target, falling
    off to 0.1 at 10 tolerances further.
    """

    def __init__(self, arm_spec, limits, tolerance_m: float = 0.002, random=None):
        super().__init__(arm_spec, limits, random=random)
        self.tolerance_m = float(tolerance_m)
        self.target_lengths = np.zeros(len(arm_spec.sections))

    def initialize_task(self, physics):
        lo, hi = self.limits.pressure_range
        counts = [len(s.muscles) for s in self.arm_spec.sections]
        fractions = np.concatenate([np.full(n, self.random.uniform(lo, hi)) for n in counts])
        _, lengths = arm_glue.reference_tip(self.arm_spec, fractions * self.arm_spec.max_pressure_Pa)
        self.target_lengths = np.asarray(lengths, dtype=float)
        physics.set_target_position(physics.to_world([0.0, 0.0, float(self.target_lengths.sum())]))

    def get_observation(self, physics):
        obs = self.common_observations(physics)
        obs["target_lengths"] = self.target_lengths.copy()
        return obs

    def length_errors(self, physics) -> np.ndarray:
        """Section lengths minus their targets (m), one per section."""
        return physics.section_lengths() - self.target_lengths

    def get_reward(self, physics):
        errors = [a - b for a, b in zip(physics.section_length_values(), self.target_lengths.tolist())]
        bounds, margin = (0.0, self.tolerance_m), 10 * self.tolerance_m
        return sum(long_tail_tolerance(abs(e), bounds, margin) for e in errors) / len(errors)

    def success(self, physics) -> bool:
        """Whether every section length is within the tolerance of its target."""
        return bool(np.all(np.abs(self.length_errors(physics)) <= self.tolerance_m))


# -------------------------------------------------------------------------------------- push


class Push(common.EfamTask):
    """Press the tip on a force plate with a target force.

    The plate faces the arm across its axis, at the arm's straight length under equal
    pressures drawn from the lower part of the workspace's range: the arm extends to touch it.
    The target normal force is drawn from ``force_range_N``. Reward: 1 within
    ``tolerance_fraction`` of the target force (at least 0.5 N), falling off to 0.1 at a
    difference equal to the target.
    """

    def __init__(
        self, arm_spec, limits, force_range_N=(5.0, 40.0), tolerance_fraction: float = 0.1, random=None
    ):
        super().__init__(arm_spec, limits, random=random)
        lo, hi = force_range_N
        if not (0 < lo <= hi):
            raise ValueError(f"push: force_range_N must satisfy 0 < lo <= hi, got {force_range_N}")
        self.force_range_N = (float(lo), float(hi))
        self.tolerance_fraction = float(tolerance_fraction)
        self.target_force_N = lo
        self.plate_distance_m = 0.0
        self._plate_fraction = limits.pressure_range[1]

    def initialize_task(self, physics):
        lo, hi = self.limits.pressure_range
        fraction = self.random.uniform(lo + 0.1 * (hi - lo), lo + 0.4 * (hi - lo))
        count = sum(len(s.muscles) for s in self.arm_spec.sections)
        tip, _ = arm_glue.reference_tip(
            self.arm_spec, np.full(count, fraction * self.arm_spec.max_pressure_Pa)
        )
        self.plate_distance_m = float(tip[2] + common.EFFECTOR_RADIUS_M)
        self._plate_fraction = fraction
        self.target_force_N = float(self.random.uniform(*self.force_range_N))
        body = physics.model.name2id("force_plate", "body")
        physics.model.body_pos[body] = physics.to_world([0.0, 0.0, self.plate_distance_m])
        physics.set_target_position(physics.to_world([0.0, 0.0, self.plate_distance_m]))

    def start_limits(self) -> workspace.WorkspaceLimits:
        """Start short of the plate and nearly straight, so the tip starts on the arm's side."""
        lo, _ = self.limits.pressure_range
        return workspace.WorkspaceLimits(
            (lo, lo + 0.7 * (self._plate_fraction - lo)), min(30.0, self.limits.max_bend_deg)
        )

    def get_observation(self, physics):
        obs = self.common_observations(physics)
        obs["plate_force"] = np.array([physics.plate_force()])
        obs["target_force"] = np.array([self.target_force_N])
        obs["plate_distance"] = np.array([self.plate_distance_m])
        return obs

    def get_reward(self, physics):
        error = abs(physics.plate_force() - self.target_force_N)
        bound = max(0.5, self.tolerance_fraction * self.target_force_N)
        return long_tail_tolerance(error, (0.0, bound), self.target_force_N)

    def success(self, physics) -> bool:
        """Whether the plate force is within the tolerance of the target force."""
        bound = max(0.5, self.tolerance_fraction * self.target_force_N)
        return abs(physics.plate_force() - self.target_force_N) <= bound


# ------------------------------------------------------------------- the tasks on a domain


@dataclass(frozen=True)
class Domain:
    """What one domain of the suite sets: its arm, ``Physics`` class, workspace limits, reach
    radius, payload and push-force ranges, episode length and control step."""

    make_arm: Callable  # (**arm_options) -> ArmSpec: arm_options override its fields
    physics_class: type
    limits: workspace.WorkspaceLimits  # the part of the shape space targets and starts come from
    target_radius_m: float  # reach, track, reach_payload: success radius
    payload_range_kg: tuple[float, float]  # reach_payload: payload mass drawn per episode
    push_force_range_N: tuple[float, float]  # push: target force drawn per episode
    time_limit_s: float = 10.0  # 100 control steps
    control_timestep_s: float = 0.1  # 10 Hz: twice the pressure lag's time constant

    def environment(self, task_name, time_limit=None, random=None, environment_kwargs=None, arm_options=None):
        """A ``control.Environment`` of task ``task_name`` on this domain's arm in its scene."""
        time_limit = self.time_limit_s if time_limit is None else time_limit
        # refused before the arm is built: dm_control would end a non-positive episode at its
        # first step, and a NaN one never; inf is dm_control's "no limit" and stays allowed
        seconds = as_float(time_limit)  # a numpy scalar or 0-d array is one number too
        if math.isnan(seconds) or seconds <= 0:
            raise ValueError(
                f"time_limit must be a positive episode length in s (inf: no limit), got {time_limit!r}"
            )
        time_limit = seconds
        spec = self.make_arm(**(arm_options or {}))
        radius = {"target_radius_m": self.target_radius_m}
        task_class, scene, task_options = {
            "reach": (Reach, {}, radius),
            "track": (Track, {}, radius),
            "extend": (Extend, {}, {}),
            "push": (Push, {"force_plate": True}, {"force_range_N": self.push_force_range_N}),
            "reach_payload": (
                ReachPayload, {"payload_max_kg": self.payload_range_kg[1]},
                {**radius, "payload_range_kg": self.payload_range_kg},
            ),
        }[task_name]  # fmt: skip
        task = task_class(spec, self.limits, random=random, **task_options)
        return common.make_environment(
            self.physics_class, spec, task, time_limit=time_limit,
            control_timestep=self.control_timestep_s, environment_kwargs=environment_kwargs,
            target_radius_m=self.target_radius_m, **scene,
        )  # fmt: skip


def make_suite(domain: Domain) -> containers.TaggedTasks:
    """dm_control's task registry of ``domain``: ``reach``, ``track``, ``extend``, ``push``
    (tagged ``benchmarking``) and ``reach_payload`` (``extra``), each a function
    ``(time_limit, random, environment_kwargs, arm_options) -> Environment``."""
    radius_cm = f"{domain.target_radius_m * 100:g} cm"
    force_N = "{:g}-{:g} N".format(*domain.push_force_range_N)
    payload_g = "{:g}-{:g} g".format(*(1000 * m for m in domain.payload_range_kg))
    docs = {
        "reach": ("benchmarking", f"Tip to a random reachable target, within {radius_cm}."),
        "track": ("benchmarking", f"Tip within {radius_cm} of a target that circles the axis every 5-10 s."),
        "extend": ("benchmarking", "Every section's length to a random target, within 2 mm."),
        "push": ("benchmarking", f"Press a force plate across the tip's path with a target force of {force_N}."),
        "reach_payload": ("extra", f"``reach`` with an unobserved payload of {payload_g} on the tip, drawn per episode."),
    }  # fmt: skip
    suite = containers.TaggedTasks()
    for name, (tag, doc) in docs.items():
        suite.add(tag)(_task_function(domain, name, doc))
    return suite


def _task_function(domain: Domain, name: str, doc: str):
    def task(time_limit=None, random=None, environment_kwargs=None, arm_options=None):
        return domain.environment(name, time_limit, random, environment_kwargs, arm_options)

    task.__name__ = task.__qualname__ = name
    task.__doc__ = doc
    return task
