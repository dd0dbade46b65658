"""Arm domain: three EFAM sections of three FAM1 muscles each, hanging from its base.

Each section extends under equal pressures and bends towards its lower-pressure muscles;
targets keep every section within 60 degrees of bend. Actions: nine pressure fractions of rated
in [0, 1] (base section first), through a 50 ms pressure lag. Control step 100 ms (10 Hz), episodes
of 10 s (100 steps). Tasks (:mod:`.tasks`): ``reach``, ``track``, ``extend``, ``push`` and
``reach_payload``.
"""

from __future__ import annotations

from . import arm_glue, common, tasks, workspace


class Physics(common.EfamPhysics):
    """Physics of the arm domain."""


DOMAIN = tasks.Domain(
    make_arm=arm_glue.arm_spec,  # hanging: upright, it buckles under its own weight
    physics_class=Physics,
    limits=workspace.WorkspaceLimits(max_bend_deg=60.0),  # per section
    target_radius_m=0.02,  # reach, track: success within 2 cm
    payload_range_kg=(0.0, 0.2),  # reach_payload: a steel ball of 0-200 g
    # push: the plate is below the hanging tip; pushed harder, the arm buckles sideways (~8 N)
    push_force_range_N=(1.0, 6.0),
)
SUITE = tasks.make_suite(DOMAIN)
