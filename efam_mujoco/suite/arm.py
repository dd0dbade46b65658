"""Arm domain: three EFAM sections of three FAM1 muscles each, hanging from its base.

Each section extends under equal pressures and bends towards its lower-pressure muscles;
targets keep every section within 60 degrees of bend. Actions: nine pressure fractions of rated
in [0, 1] (base section first), through a 50 ms pressure lag. Control step 100 ms (10 Hz), episodes
of 10 s (100 steps).
"""

from __future__ import annotations

from dm_control.utils import containers

from . import arm_glue, common, tasks, workspace

_DEFAULT_TIME_LIMIT = 10.0  # s
_CONTROL_TIMESTEP = 0.1  # s: 10 Hz, twice the pressure lag's time constant
#: reach/track success radius
TARGET_RADIUS_M = 0.02
#: reach_payload: payload mass drawn per episode
PAYLOAD_RANGE_KG = (0.0, 0.2)
#: push: target force (the hanging arm buckles sideways above ~8 N)
PUSH_FORCE_RANGE_N = (1.0, 6.0)
#: the part of the shape space targets and starts are drawn from
LIMITS = workspace.WorkspaceLimits(max_bend_deg=60.0)

SUITE = containers.TaggedTasks()


def make_arm(**arm_options):
    """The domain's ``ArmSpec`` (``arm_options`` override its fields, e.g. ``pressure_tau_s``)."""
    return arm_glue.arm_spec(**arm_options)


class Physics(common.EfamPhysics):
    """Physics of the arm domain."""


def _environment(task_class, scene, time_limit, random, environment_kwargs, arm_options, **task_options):
    spec = make_arm(**(arm_options or {}))
    task = task_class(spec, LIMITS, random=random, **task_options)
    return common.make_environment(
        Physics, spec, task, time_limit=time_limit, control_timestep=_CONTROL_TIMESTEP,
        environment_kwargs=environment_kwargs, target_radius_m=TARGET_RADIUS_M, **scene,
    )  # fmt: skip


@SUITE.add("benchmarking")
def reach(time_limit=_DEFAULT_TIME_LIMIT, random=None, environment_kwargs=None, arm_options=None):
    """Tip to a random reachable target, within 2 cm."""
    return _environment(
        tasks.Reach, {}, time_limit, random, environment_kwargs, arm_options, target_radius_m=TARGET_RADIUS_M
    )


@SUITE.add("benchmarking")
def track(time_limit=_DEFAULT_TIME_LIMIT, random=None, environment_kwargs=None, arm_options=None):
    """Tip on a target that circles the axis every 5-10 s."""
    return _environment(
        tasks.Track, {}, time_limit, random, environment_kwargs, arm_options, target_radius_m=TARGET_RADIUS_M
    )


@SUITE.add("benchmarking")
def extend(time_limit=_DEFAULT_TIME_LIMIT, random=None, environment_kwargs=None, arm_options=None):
    """Section length to a random target, within 2 mm."""
    return _environment(tasks.Extend, {}, time_limit, random, environment_kwargs, arm_options)


@SUITE.add("benchmarking")
def push(time_limit=_DEFAULT_TIME_LIMIT, random=None, environment_kwargs=None, arm_options=None):
    """Press a force plate below the tip with a target force of 1-6 N."""
    return _environment(
        tasks.Push, {"force_plate": True}, time_limit, random, environment_kwargs, arm_options,
        force_range_N=PUSH_FORCE_RANGE_N,
    )  # fmt: skip


@SUITE.add("extra")
def reach_payload(time_limit=_DEFAULT_TIME_LIMIT, random=None, environment_kwargs=None, arm_options=None):
    """:func:`reach` with an unobserved payload of 0-200 g on the tip, drawn per episode."""
    return _environment(
        tasks.ReachPayload, {"payload_max_kg": PAYLOAD_RANGE_KG[1]}, time_limit, random, environment_kwargs,
        arm_options, target_radius_m=TARGET_RADIUS_M, payload_range_kg=PAYLOAD_RANGE_KG,
    )  # fmt: skip
