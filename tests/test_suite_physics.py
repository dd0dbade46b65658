"""The suite's physics accessors, workspace and controllers against independent references:
the muscle's own free length, the arm's own pressure reader, the constant-curvature statics,
closed-form arc geometry. Plus the offscreen render (MUJOCO_GL=egl) and the CLI."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest

from efam_mujoco import arm, statics, suite
from efam_mujoco.cli import main as efam_main
from efam_mujoco.suite import arm_glue, controllers, workspace


def settled_bundle(fractions, seconds=3.0):
    env = suite.load("bundle", "reach", task_kwargs={"random": 0, "arm_options": {"gravity": False}})
    env.reset()
    physics = env.physics
    physics.set_pressure_fractions(fractions)
    physics.step(int(seconds / physics.timestep()))
    return env, physics


def test_pressures_match_the_arm_reader():
    env = suite.load("arm", "reach", task_kwargs={"random": 1})
    env.reset()
    env.step(np.linspace(0.1, 0.9, 9))
    physics = env.physics
    reference = arm.muscle_pressures(physics.model.ptr, physics.data.ptr)
    np.testing.assert_array_equal(physics.muscle_pressures_Pa(), reference)


def test_equal_pressures_without_gravity_give_a_straight_section_at_the_free_length():
    fraction = 0.5
    env, physics = settled_bundle(np.full(3, fraction))
    muscle = env.task.arm_spec.sections[0].muscles[0]
    free = muscle.free_length(fraction * env.task.arm_spec.max_pressure_Pa)
    assert physics.section_lengths()[0] == pytest.approx(free, rel=2e-3)
    assert np.abs(physics.section_bends()).max() < 0.01  # rad, still relaxing from the random start
    np.testing.assert_allclose(physics.muscle_lengths(), free, rtol=2e-3)


def test_section_bend_matches_constant_curvature_statics():
    fractions = np.array([0.35, 0.5, 0.5])
    env, physics = settled_bundle(fractions)
    section = env.task.arm_spec.sections[0]
    state, _ = statics.solve_section(section, fractions * env.task.arm_spec.max_pressure_Pa)
    bx, by = physics.section_bends()[0]
    assert math.hypot(bx, by) == pytest.approx(state.bend_angle_rad, abs=math.radians(1.5))
    assert math.atan2(by, bx) == pytest.approx(state.bend_direction_rad, abs=math.radians(1.0))
    # the tip site, measured in the base frame, against the arc's tip
    tip = physics.to_base(physics.tip_position())
    assert np.linalg.norm(tip - statics.cc_frame(state.arc_length_m, *state.curvature_xy_per_m)[0]) < 0.005


def test_workspace_samples_are_reachable_unloaded_arcs():
    """Unloaded, the sampled pressures hold each muscle at its free length on the sampled arc
    (closed form); the suite's statics (the domain's MuJoCo model at rest) meets the arc's tip
    at D = 4 as at D = 16 (the segments' arc geometry is exact for unloaded arcs; the linear
    tendon geometry was 1.2 % off at D = 4), to the statics' tolerance."""
    random = np.random.RandomState(0)
    limits = workspace.WorkspaceLimits(max_bend_deg=80.0)
    spec = arm_glue.bundle_spec(gravity=False)
    fine = arm_glue.bundle_spec(gravity=False, disks=16)
    (muscles, radii, angles) = arm_glue.section_muscles(spec)[0]
    for _ in range(4):
        (s, kx, ky), fractions = workspace.sample_section_shape(
            (muscles, radii, angles), spec.max_pressure_Pa, limits, random
        )
        assert np.all((fractions >= 0.15 - 1e-9) & (fractions <= 0.9 + 1e-9))
        assert math.hypot(kx, ky) * s <= math.radians(80.0) + 1e-9
        pressures = fractions * spec.max_pressure_Pa
        lengths = [m.free_length(p) for m, p in zip(muscles, pressures)]
        np.testing.assert_allclose(
            lengths, s * (1 - radii * (kx * np.cos(angles) + ky * np.sin(angles))), rtol=1e-4
        )
        arc_tip = statics.cc_frame(s, kx, ky)[0]
        coarse_error = np.linalg.norm(arm_glue.reference_tip(spec, pressures)[0] - arc_tip)
        fine_error = np.linalg.norm(arm_glue.reference_tip(fine, pressures)[0] - arc_tip)
        assert coarse_error < 1e-4 * s and fine_error < 1e-4 * s  # measured: about 5e-6 of s
    with pytest.raises(ValueError, match="pressure_range"):
        workspace.WorkspaceLimits(pressure_range=(0.9, 0.2))
    ws = workspace.compute_workspace(arm_glue.bundle_spec(), samples=8, seed=1)
    assert ws.tips_m.shape == (8, 3) and ws.radial_reach_m > 0.02


def test_reference_tip_is_where_the_simulated_arm_rests():
    """The suite's statics against a plain simulation of the same arm left to settle."""
    fractions = np.array([0.3, 0.6, 0.45])
    env, physics = settled_bundle(fractions, seconds=8.0)  # the slowest mode creeps for seconds
    spec = env.task.arm_spec
    tip, lengths = arm_glue.reference_tip(spec, fractions * spec.max_pressure_Pa)
    np.testing.assert_allclose(physics.to_base(physics.tip_position()), tip, atol=2e-4)
    np.testing.assert_allclose(physics.section_lengths(), lengths, atol=2e-4)


def test_inverse_statics_meets_targets():
    # gravity off: one arc through the target is the closed-form inverse; the discretised arm
    # (D = 4) puts its tip within its discretisation error (~1 % of the length) of it
    spec = arm_glue.bundle_spec(gravity=False)
    target, _ = workspace.sample_target(spec, np.random.RandomState(3))
    seed = controllers.cc_arc_pressures(spec, target)
    tip, _ = arm_glue.reference_tip(spec, seed * spec.max_pressure_Pa)
    assert np.linalg.norm(tip - target) < 0.004
    solution = controllers.inverse_statics(spec, target)
    assert solution.error_m(target) < 1e-4
    # gravity on, three sections: the least-squares solve lands on the reference target
    spec = arm_glue.arm_spec()
    target, _ = workspace.sample_target(
        spec, np.random.RandomState(4), workspace.WorkspaceLimits(max_bend_deg=60)
    )
    solution = controllers.inverse_statics(spec, target)
    assert solution.error_m(target) < 1e-3
    assert solution.jacobian_m.shape == (3, 9)


def test_inverse_statics_jacobian_is_the_rest_tips_at_the_solution():
    """The feedback's Jacobian against central differences of the statics at the solution.
    Bundle-reach seed 18's target lies where one direction is weak (smallest singular value
    about 0.1 m per unit fraction): a Broyden estimate got it 16 times too small there, and the
    feedback drove the tip 201 mm off."""
    env = suite.load("bundle", "reach", task_kwargs={"random": 18})
    env.reset()
    spec = env.task.arm_spec
    target = env.physics.to_base(env.physics.target_position())
    solution = controllers.inverse_statics(spec, target)
    h, rated = 1e-3, spec.max_pressure_Pa
    central = np.empty((3, 3))
    for i in range(3):
        plus, minus = solution.fractions.copy(), solution.fractions.copy()
        plus[i] += h
        minus[i] -= h
        tip_plus = arm_glue.reference_tip(spec, plus * rated)[0]
        tip_minus = arm_glue.reference_tip(spec, minus * rated)[0]
        central[:, i] = (tip_plus - tip_minus) / (2 * h)
    np.testing.assert_allclose(solution.jacobian_m, central, atol=0.01 * np.abs(central).max())
    assert np.linalg.svd(central, compute_uv=False)[-1] > 0.05  # weak, but not singular
    _, success, error = controllers.run_episode(env, controllers.InverseStaticsController(env))
    assert success and error < 0.01, error


def test_controller_reaches_and_random_does_not():
    """Two bundle episodes and one arm episode (the 50-episode figures: bench/bench_suite.py)."""
    for domain, seeds, radius in (("bundle", (0, 1), 0.01), ("arm", (0,), 0.02)):
        for seed in seeds:
            env = suite.load(domain, "reach", task_kwargs={"random": seed})
            _, success, error = controllers.run_episode(env, controllers.InverseStaticsController(env))
            assert success and error < radius, (domain, seed, error)
    env = suite.load("bundle", "reach", task_kwargs={"random": 0})
    _, success, error = controllers.run_episode(env, controllers.RandomPolicy(env, seed=0))
    assert not success and error > 0.01


RENDER = """
import numpy as np
from efam_mujoco import suite
for domain in ("bundle", "arm"):
    env = suite.load(domain, "push", task_kwargs={"random": 0})
    env.reset()
    for camera in ("side", "front", "perspective"):
        image = env.physics.render(120, 160, camera_id=camera)
        assert image.shape == (120, 160, 3)
        assert image.std() > 10 and 20 < image.mean() < 235, (domain, camera, image.mean(), image.std())
print("rendered")
"""


def test_render_headless_with_egl():
    env = {**os.environ, "MUJOCO_GL": "egl", "PYOPENGL_PLATFORM": "egl"}
    child = subprocess.run(
        [sys.executable, "-c", RENDER], env=env, capture_output=True, text=True, timeout=300
    )
    assert child.returncode == 0 and "rendered" in child.stdout, child.stderr[-2000:]


def test_cli_lists_and_refuses(capsys):
    assert efam_main(["suite", "--list"]) == 0
    out = capsys.readouterr().out
    assert "bundle-reach  (benchmarking)" in out and "arm-reach_payload  (extra)" in out
    assert efam_main(["suite", "--domain", "octopus"]) == 2
    assert "no task octopus-reach" in capsys.readouterr().err
    assert efam_main(["suite", "--task", "extend", "--episodes", "1"]) == 0
    assert "bundle-extend               random: success" in capsys.readouterr().out


def test_track_target_velocity_is_the_derivative_of_its_path():
    env = suite.load("bundle", "track", task_kwargs={"random": 2})
    env.reset()
    task = env.task
    for t in (0.0, 1.3, 4.0):
        position, velocity = task.target_at(t)
        h = 1e-5
        ahead, _ = task.target_at(t + h)
        behind, _ = task.target_at(t - h)
        np.testing.assert_allclose(velocity, (ahead - behind) / (2 * h), atol=1e-6)
    # a closed loop: back where it started after one period
    np.testing.assert_allclose(task.target_at(task.period_s)[0], task.target_at(0.0)[0], atol=1e-9)
