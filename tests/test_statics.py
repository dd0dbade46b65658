"""Constant-curvature statics against closed forms and independent root finds."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from efam_mujoco import load_muscle
from efam_mujoco.arm import PAPER_PRESSURES_PA, SectionSpec
from efam_mujoco.statics import PointMass, cc_frame, muscle_lengths, solve_arm, solve_section

FAM1 = load_muscle("FAM1")
FAM2 = load_muscle("FAM2")


def bundle(muscle=FAM1, radius=0.02, angles=None):
    return SectionSpec(muscles=(muscle,) * 3, radius_m=radius, angles_deg=angles)


# ------------------------------------------------------------------------- kinematics


def test_cc_frame_quarter_circle():
    R = 0.2
    pos, rot = cc_frame(math.pi / 2 * R, 1 / R, 0.0)  # bends towards +x
    np.testing.assert_allclose(pos, [R, 0, R], atol=1e-15)
    np.testing.assert_allclose(rot @ [0, 0, 1], [1, 0, 0], atol=1e-15)  # tip tangent along +x


def test_cc_frame_bend_direction_and_straight_limit():
    pos, rot = cc_frame(0.3, 0.0, 2.0)  # towards +y
    assert pos[1] > 0 and abs(pos[0]) < 1e-15
    np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-14)
    straight, _ = cc_frame(0.3, 0.0, 0.0)
    nearly, _ = cc_frame(0.3, 1e-9, 0.0)
    np.testing.assert_allclose(straight, [0, 0, 0.3], atol=1e-15)
    np.testing.assert_allclose(nearly, straight, atol=1e-9)


def test_muscle_length_is_arc_at_its_radius():
    """A muscle at angle alpha, radius r follows a concentric arc of radius 1/kappa - r cos(phi - alpha)."""
    section = bundle(angles=(0, 100, 230))
    s, kappa, phi = 0.25, 3.0, math.radians(40)
    lengths = muscle_lengths(section, s, kappa * math.cos(phi), kappa * math.sin(phi))
    for L, alpha in zip(lengths, section.angles_rad):
        assert L == pytest.approx((1 / kappa - 0.02 * math.cos(phi - alpha)) * kappa * s, rel=1e-13)


# ------------------------------------------------------------------------ single section


@pytest.mark.parametrize("muscle", [FAM1, FAM2], ids=["FAM1", "FAM2"])
def test_equal_pressures_straight_at_free_length(muscle):
    for p in PAPER_PRESSURES_PA:
        state, arm = solve_section(bundle(muscle), [p] * 3)
        assert state.arc_length_m == pytest.approx(muscle.free_length(p), rel=1e-9)
        assert state.curvature_per_m < 1e-9
        np.testing.assert_allclose(arm.tip_position_m, [0, 0, muscle.free_length(p)], atol=1e-9)


def test_unloaded_bundle_each_muscle_at_its_free_length():
    """Three muscles, no load: three force-free equations for three unknowns, so every muscle
    carries no force; for evenly spaced muscles s is their mean length and the curvature follows
    from the first Fourier component of the lengths."""
    pressures = np.array([120e3, 260e3, 410e3])
    state, _ = solve_section(bundle(), pressures)
    free = np.array([FAM1.free_length(p) for p in pressures])
    np.testing.assert_allclose(state.muscle_lengths_m, free, rtol=1e-9)
    angles = np.radians([0, 120, 240])
    s = free.mean()
    kx = -2 * np.sum(free * np.cos(angles)) / (3 * s * 0.02)
    ky = -2 * np.sum(free * np.sin(angles)) / (3 * s * 0.02)
    assert state.arc_length_m == pytest.approx(s, rel=1e-9)
    np.testing.assert_allclose(state.curvature_xy_per_m, [kx, ky], rtol=1e-8)


def test_bends_towards_the_lower_pressure_muscle():
    for low in range(3):
        pressures = [300e3] * 3
        pressures[low] = 200e3
        state, arm = solve_section(bundle(), pressures)
        alpha = math.radians(120 * low)
        assert math.cos(state.bend_direction_rad - alpha) == pytest.approx(1.0, abs=1e-9)
        tip_xy = arm.tip_position_m[:2]
        assert tip_xy @ [math.cos(alpha), math.sin(alpha)] > 0.01


def test_axial_tip_load_each_muscle_carries_a_share():
    """Equal pressures and a compressive force f along the axis: every muscle pushes f/M, so
    its length is the root of push(P, L) = f/M (found here independently)."""
    p, f = 310e3, 60.0
    state, _ = solve_section(bundle(), [p] * 3, tip_force_N=(0, 0, -f))
    expect = brentq(lambda L: FAM1.push(p, L) - f / 3, FAM1.rest_length_m, FAM1.max_length_m)
    assert state.arc_length_m == pytest.approx(expect, rel=1e-9)
    np.testing.assert_allclose(state.muscle_forces_N, f / 3, rtol=1e-8)


def test_tip_moment_balanced_by_muscle_forces():
    """A pure tip moment about y bends the section in the xz plane; the muscle forces have no
    net axial force and their moment about the mid-arc point cancels the applied one."""
    m_y = 0.8
    state, _ = solve_section(bundle(), [300e3] * 3, tip_moment_N_m=(0, m_y, 0))
    F, angles = state.muscle_forces_N, np.radians([0, 120, 240])
    assert abs(F.sum()) < 1e-7
    # the moment is the same at every cut: compare in the base frame's y (the bend plane's normal)
    assert 0.02 * np.sum(F * np.cos(angles)) == pytest.approx(m_y, rel=1e-8)
    assert abs(np.sum(F * np.sin(angles))) < 1e-7
    # +M_y turns the tip towards +x
    assert state.curvature_xy_per_m[0] > 0 and abs(state.curvature_xy_per_m[1]) < 1e-9
    # the pushed-on side (cos alpha > 0) is shortened, the other lengthened
    assert F[0] > 0 > F[1]


# --------------------------------------------------------------------------- multi-section


def test_sections_without_load_are_independent():
    sections = [bundle(), bundle(FAM2, angles=(30, 150, 270)), bundle()]
    pressures = [[200e3, 250e3, 300e3], [400e3, 300e3, 350e3], [150e3, 150e3, 150e3]]
    arm = solve_arm(sections, pressures)
    p, R = np.zeros(3), np.eye(3)
    for section, press, state in zip(sections, pressures, arm.sections):
        alone, _ = solve_section(section, press)
        assert state.arc_length_m == pytest.approx(alone.arc_length_m, rel=1e-9)
        np.testing.assert_allclose(state.curvature_xy_per_m, alone.curvature_xy_per_m, rtol=1e-7, atol=1e-9)
        dp, dR = cc_frame(alone.arc_length_m, *alone.curvature_xy_per_m)
        p, R = p + R @ dp, R @ dR
    np.testing.assert_allclose(arm.tip_position_m, p, atol=1e-9)
    np.testing.assert_allclose(arm.tip_rotation, R, atol=1e-9)


def test_coplanar_sections_with_equal_bends_form_one_arc():
    state, _ = solve_section(bundle(), [200e3, 300e3, 300e3])
    arm = solve_arm([bundle()] * 2, [[200e3, 300e3, 300e3]] * 2)
    pos, _ = cc_frame(2 * state.arc_length_m, *state.curvature_xy_per_m)
    np.testing.assert_allclose(arm.tip_position_m, pos, atol=1e-9)


def test_hanging_arm_sections_carry_the_weight_below_them():
    """Gravity along the axis of a straight hanging two-section arm (base frame +z = down):
    each section's muscles push back the weight beyond the middle of the section."""
    masses = [PointMass(0, 0.5, 0.2), PointMass(0, 1.0, 0.3), PointMass(1, 0.5, 0.2), PointMass(1, 1.0, 0.4)]
    g, p = 9.81, 300e3
    arm = solve_arm([bundle()] * 2, [[p] * 3] * 2, gravity_m_s2=(0, 0, g), point_masses=masses)
    # section 2, cut at its middle: half the mass at 0.5 plus the tip mass; section 1: half of
    # its middle mass, its end plate and all of section 2
    loads = [g * (0.1 + 0.3 + 0.2 + 0.4), g * (0.1 + 0.4)]
    for state, load in zip(arm.sections, loads):
        expect = brentq(
            lambda L, w=load: FAM1.push(p, L) + w / 3, FAM1.min_length_m + 1e-6, FAM1.max_length_m
        )
        assert state.arc_length_m == pytest.approx(expect, rel=1e-9)
        assert state.curvature_per_m < 1e-9


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="3 muscles but 2 pressures"):
        solve_section(bundle(), [1e5, 2e5])
    with pytest.raises(ValueError, match="2 sections but 1 pressure lists"):
        solve_arm([bundle()] * 2, [[1e5] * 3])
