"""The arm's statics: the continuum (Kirchhoff rod) reference, now in :mod:`efam_mujoco.arm.continuum`.

Kept so that ``from efam_mujoco.statics import solve_arm, solve_section, ...`` goes on working;
the mid-arc cut of earlier versions is replaced by the rod's boundary-value problem, and the
constant-curvature solution is its unloaded special case.
"""

from .arm.continuum import (
    ArmState,
    ContinuumError,
    PointMass,
    SectionState,
    cc_frame,
    solve_arm,
    solve_arm_spec,
    solve_section,
    solve_section_cc,
)

StaticsError = ContinuumError


def muscle_lengths(section, arc_length_m: float, kx: float, ky: float):
    """Lengths of a section's muscles on a CC arc: L_i = s (1 - r_i (kx cos alpha_i + ky sin alpha_i))."""
    import numpy as np

    a = np.asarray(section.angles_rad, dtype=float)
    r = np.broadcast_to(np.asarray(section.radius_m, dtype=float), a.shape)
    return arc_length_m * (1.0 - r * (kx * np.cos(a) + ky * np.sin(a)))


__all__ = [
    "ArmState",
    "PointMass",
    "SectionState",
    "StaticsError",
    "cc_frame",
    "muscle_lengths",
    "solve_arm",
    "solve_arm_spec",
    "solve_section",
    "solve_section_cc",
]
