"""Bundle domain: one EFAM section of three FAM1 muscles (18.2 mm from the axis, D = 4 disks), upright.

The section extends under equal pressures (from 0.17 m to about 0.33 m between 0.15 and 0.9 of
the rated 517 kPa) and bends towards its lower-pressure muscles. Actions: three pressure
fractions of rated in [0, 1], through a 50 ms pressure lag. Control step 100 ms (10 Hz),
episodes of 10 s (100 steps). Tasks (:mod:`.tasks`): ``reach``, ``track``, ``extend``, ``push``
and ``reach_payload``.
"""

from __future__ import annotations

from . import arm_glue, common, tasks, workspace


class Physics(common.EfamPhysics):
    """Physics of the bundle domain."""


DOMAIN = tasks.Domain(
    make_arm=arm_glue.bundle_spec,  # arm_options override its ArmSpec fields
    physics_class=Physics,
    # targets and starts: bends up to 90 degrees (pressures 0.15-0.9 of rated)
    limits=workspace.WorkspaceLimits(max_bend_deg=90.0),
    target_radius_m=0.01,  # reach, track: success within 1 cm
    payload_range_kg=(0.0, 0.1),  # reach_payload: a steel ball of 0-100 g
    push_force_range_N=(5.0, 40.0),  # push: the plate is above the upright tip
)
SUITE = tasks.make_suite(DOMAIN)
