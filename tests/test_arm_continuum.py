"""The continuum reference (Kirchhoff rod of muscles) against closed forms and independent root finds."""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from efam_mujoco import load_muscle
from efam_mujoco.arm import PAPER_PRESSURES_PA, SectionSpec
from efam_mujoco.arm.continuum import PointMass, cc_frame, solve_arm, solve_section
from efam_mujoco.statics import muscle_lengths

FAM1 = load_muscle("FAM1")
FAM2 = load_muscle("FAM2")


def bundle(muscle=FAM1, radius=0.02, angles=None):
    return SectionSpec(muscles=(muscle,) * 3, radius_m=radius, angles_deg=angles)


# ------------------------------------------------------------------------- kinematics


def test_cc_frame_quarter_circle():
    R = 0.2
    pos, rot = cc_frame(math.pi / 2 * R, 1 / R, 0.0)  # bends towards +x
    np.testing.assert_allclose(pos, [R, 0, R], atol=1e-15)
    np.testing.assert_allclose(rot @ [0, 0, 1], [1, 0, 0], atol=1e-15)


def test_cc_frame_bend_direction_and_straight_limit():
    pos, rot = cc_frame(0.3, 0.0, 2.0)  # towards +y
    assert pos[1] > 0 and abs(pos[0]) < 1e-15
    np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-14)
    straight, _ = cc_frame(0.3, 0.0, 0.0)
    nearly, _ = cc_frame(0.3, 1e-9, 0.0)
    np.testing.assert_allclose(straight, [0, 0, 0.3], atol=1e-15)
    np.testing.assert_allclose(nearly, straight, atol=1e-9)


def test_muscle_length_is_arc_at_its_radius():
    section = bundle(angles=(0, 100, 230))
    s, kappa, phi = 0.25, 3.0, math.radians(40)
    lengths = muscle_lengths(section, s, kappa * math.cos(phi), kappa * math.sin(phi))
    for L, alpha in zip(lengths, section.angles_rad):
        assert L == pytest.approx((1 / kappa - 0.02 * math.cos(phi - alpha)) * kappa * s, rel=1e-13)


# ------------------------------------------------------------------ unloaded: the CC case


@pytest.mark.parametrize("muscle", [FAM1, FAM2], ids=["FAM1", "FAM2"])
def test_equal_pressures_straight_at_free_length(muscle):
    for p in PAPER_PRESSURES_PA:
        state, arm = solve_section(bundle(muscle), [p] * 3)
        assert state.arc_length_m == pytest.approx(muscle.free_length(p), rel=1e-9)
        assert state.curvature_per_m < 1e-9
        np.testing.assert_allclose(arm.tip_position_m, [0, 0, muscle.free_length(p)], atol=1e-9)


def test_unloaded_bundle_each_muscle_at_its_free_length():
    """Three muscles, no load: every muscle carries no force; for evenly spaced muscles s is their
    mean length and the curvature follows from the first Fourier component of the lengths."""
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
        assert arm.tip_position_m[:2] @ [math.cos(alpha), math.sin(alpha)] > 0.01


def test_sections_without_load_are_independent():
    sections = [bundle(), bundle(FAM2, angles=(30, 150, 270)), bundle()]
    pressures = [[200e3, 250e3, 300e3], [400e3, 300e3, 350e3], [150e3, 150e3, 150e3]]
    arm = solve_arm(sections, pressures)
    p, R = np.zeros(3), np.eye(3)
    for section, press, state in zip(sections, pressures, arm.sections):
        alone, _ = solve_section(section, press)
        assert state.arc_length_m == pytest.approx(alone.arc_length_m, rel=1e-9)
        dp, dR = cc_frame(alone.arc_length_m, *alone.curvature_xy_per_m)
        p, R = p + R @ dp, R @ dR
    np.testing.assert_allclose(arm.tip_position_m, p, atol=1e-9)
    np.testing.assert_allclose(arm.tip_rotation, R, atol=1e-9)


# ----------------------------------------------------------------------- loaded: the rod


def test_axial_tip_load_each_muscle_carries_a_share():
    """Equal pressures and a compressive force f along the axis: every muscle pushes f/M, so its
    length is the root of push(P, L) = f/M (found here independently)."""
    p, f = 310e3, 60.0
    state, arm = solve_section(bundle(), [p] * 3, tip_force_N=(0, 0, -f))
    expect = brentq(lambda L: FAM1.push(p, L) - f / 3, FAM1.rest_length_m, FAM1.max_length_m)
    assert arm.tip_position_m[2] == pytest.approx(expect, rel=1e-8)
    np.testing.assert_allclose(state.muscle_forces_N, f / 3, rtol=1e-6)


def test_hanging_arm_stretch_follows_the_weight_below():
    """A straight hanging two-section arm (gravity along the base frame's +z): at s the muscles
    pull back the weight below s, so the local stretch nu(s) solves 3 push(P, nu L) = -w(s); the
    length is the integral of nu (computed here by quad and brentq, independently)."""
    g, p, rho = 9.81, 300e3, 0.4
    masses = [PointMass(0, 1.0, 0.3), PointMass(1, 1.0, 0.4)]
    arm = solve_arm(
        [bundle()] * 2,
        [[p] * 3] * 2,
        gravity_m_s2=(0, 0, g),
        point_masses=masses,
        line_densities_kg_per_m=[rho, rho],
    )
    L = FAM1.rest_length_m

    def stretch(weight):
        return (
            brentq(lambda nu: 3 * FAM1.push(p, nu * L) + weight, 0.5, 4.0, xtol=1e-14)
            if weight
            else FAM1.free_length(p) / L
        )

    below = [lambda s: g * (0.3 + 0.4 + rho * (2 * L - s)), lambda s: g * (0.4 + rho * (L - s))]
    length = sum(quad(lambda s, w=w: stretch(w(s)), 0, L, epsabs=1e-13)[0] for w in below)
    assert arm.tip_position_m[2] == pytest.approx(length, rel=1e-8)
    # straight down by symmetry, to the solver's precision (a bound of 1e-12 m failed on another
    # machine at 8.9e-12 m: rounding in the solve, not a sideways pull)
    assert abs(arm.tip_position_m[0]) < 1e-9 * length


def test_small_tip_force_bends_like_a_cantilever():
    """A small lateral tip force f: deflection f L^3 / (3 EI), with the bundle's bending stiffness
    from the muscles' axial stiffness k = -d push / d L at the free length: EI = L^2 sum k x^2."""
    p, f = 310e3, 1e-3
    section = bundle()
    state0, arm0 = solve_section(section, [p] * 3)
    _, arm = solve_section(section, [p] * 3, tip_force_N=(f, 0, 0))
    L0 = FAM1.free_length(p)
    k = -(FAM1.push(p, L0 + 1e-7) - FAM1.push(p, L0 - 1e-7)) / 2e-7
    x = 0.02 * np.cos(np.radians([0, 120, 240]))
    # per unit reference length: moment = sum F x, F = -k L_ref dlambda, dlambda = -kappa_ref x
    L_ref = FAM1.rest_length_m
    EI_ref = k * L_ref * np.sum(x**2)  # moment per unit curvature in the reference arc coordinate
    nu = L0 / L_ref
    deflection = f * L0**3 / (3 * EI_ref * nu)  # curvature per deformed length = kappa_ref / nu
    assert arm.tip_position_m[0] - arm0.tip_position_m[0] == pytest.approx(deflection, rel=2e-3)


def test_pure_tip_moment_gives_an_arc():
    """A moment at the tip is the same at every cut: constant curvature, with the muscles' moment
    balancing it and no net axial force."""
    m_y = 0.8
    _, arm = solve_section(bundle(), [300e3] * 3, tip_moment_N_m=(0, m_y, 0))
    backbone = arm.backbone_m
    # points of an arc in the xz plane lie on a circle: fit its centre from three points
    a, b, c = backbone[0], backbone[len(backbone) // 2], backbone[-1]
    centre_x = (np.dot(c, c) - np.dot(a, a)) / (2 * (c[0] - a[0]))  # a at the origin, centre on x
    radii = np.hypot(backbone[:, 0] - centre_x, backbone[:, 2])
    np.testing.assert_allclose(radii, abs(centre_x), rtol=1e-7)
    # in the xz plane to the solver's precision (relative: an absolute 1e-12 m is rounding-bound)
    assert arm.tip_position_m[0] > 0 and abs(arm.tip_position_m[1]) < 1e-9 * np.linalg.norm(
        arm.tip_position_m
    )
    assert b is not None


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="3 muscles but 2 pressures"):
        solve_section(bundle(), [1e5, 2e5])
    with pytest.raises(ValueError, match="2 sections but 1 pressure lists"):
        solve_arm([bundle()] * 2, [[1e5] * 3])
    with pytest.raises(ValueError, match="line_densities"):
        solve_arm([bundle()], [[1e5] * 3], line_densities_kg_per_m=[-1.0])
