"""Bundle domain: one EFAM section of three FAM1 muscles (18.2 mm from the axis, D = 4 disks), upright.

The section extends under equal pressures (from 0.17 m to about 0.33 m between 0.15 and 0.9 of
the rated 517 kPa) and bends towards its lower-pressure muscles. Actions: three pressure
fractions of rated in [0, 1], through a 50 ms pressure lag. Control step 100 ms (10 Hz),
episodes of 10 s (100 steps).
"""

from __future__ import annotations

from dm_control.utils import containers

from . import arm_glue, common, tasks, workspace

_DEFAULT_TIME_LIMIT = 10.0  # s
_CONTROL_TIMESTEP = 0.1  # s: 10 Hz, twice the pressure lag's time constant
#: reach/track success radius
TARGET_RADIUS_M = 0.01
#: reach_payload: payload mass drawn per episode
PAYLOAD_RANGE_KG = (0.0, 0.1)
#: push: target force
PUSH_FORCE_RANGE_N = (5.0, 40.0)
#: the part of the shape space targets and starts are drawn from
LIMITS = workspace.WorkspaceLimits(max_bend_deg=90.0)

SUITE = containers.TaggedTasks()


def make_arm(**arm_options):
    """The domain's ``ArmSpec`` (``arm_options`` override its fields, e.g. ``pressure_tau_s``)."""
    return arm_glue.bundle_spec(**arm_options)


class Physics(common.EfamPhysics):
    """Physics of the bundle domain."""


def _environment(task_class, scene, time_limit, random, environment_kwargs, arm_options, **task_options):
    spec = make_arm(**(arm_options or {}))
    task = task_class(spec, LIMITS, random=random, **task_options)
    return common.make_environment(
        Physics, spec, task, time_limit=time_limit, control_timestep=_CONTROL_TIMESTEP,
        environment_kwargs=environment_kwargs, target_radius_m=TARGET_RADIUS_M, **scene,
    )  # fmt: skip


@SUITE.add("benchmarking")
def reach(time_limit=_DEFAULT_TIME_LIMIT, random=None, environment_kwargs=None, arm_options=None):
    """Tip to a random reachable target, within 1 cm."""
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
    """Press a force plate above the tip with a target force of 5-40 N."""
    return _environment(
        tasks.Push, {"force_plate": True}, time_limit, random, environment_kwargs, arm_options,
        force_range_N=PUSH_FORCE_RANGE_N,
    )  # fmt: skip


@SUITE.add("extra")
def reach_payload(time_limit=_DEFAULT_TIME_LIMIT, random=None, environment_kwargs=None, arm_options=None):
    """:func:`reach` with an unobserved payload of 0-100 g on the tip, drawn per episode."""
    return _environment(
        tasks.ReachPayload, {"payload_max_kg": PAYLOAD_RANGE_KG[1]}, time_limit, random, environment_kwargs,
        arm_options, target_radius_m=TARGET_RADIUS_M, payload_range_kg=PAYLOAD_RANGE_KG,
    )  # fmt: skip
