"""The EFAM suite passes the checks dm_control applies to its own suite (suite_test.py), for
every task, and runs random steps without a MuJoCo warning (1000 on the bundle here; the arm's
1000 in bench/bench_suite.py).

Adapted from dm_control's checks where the suite differs on purpose: actions are pressure
fractions in [0, 1] (dm_control's benchmarking tasks use [-1, 1]).
"""

from __future__ import annotations

import numpy as np
import pytest
from dm_control.rl import control

from efam_mujoco import suite
from efam_mujoco.suite import common

TASKS = [pytest.param(d, t, id=f"{d}-{t}") for d, t in suite.ALL_TASKS]


def random_policy(action_spec, seed):
    random = np.random.RandomState(seed)
    return lambda time_step: random.uniform(action_spec.minimum, action_spec.maximum, size=action_spec.shape)


def trajectory(domain, task, seed, episodes=2, steps=10, **load_kwargs):
    env = suite.load(domain, task, task_kwargs={"random": seed}, **load_kwargs)
    policy = random_policy(env.action_spec(), seed)
    for _ in range(episodes):
        time_step = env.reset()
        yield time_step
        for _ in range(steps):
            time_step = env.step(policy(time_step))
            yield time_step
            if time_step.last():
                break


def test_registry():
    assert set(suite.ALL_TASKS) == set(suite.BENCHMARKING) | set(suite.EXTRA)
    assert not set(suite.BENCHMARKING) & set(suite.EXTRA)
    for domain in ("bundle", "arm"):
        assert set(suite.TASKS_BY_DOMAIN[domain]) >= {"reach", "track", "extend", "push", "reach_payload"}
    assert len(suite.ALL_TASKS) == sum(len(t) for t in suite.TASKS_BY_DOMAIN.values())


def test_load_refuses_unknown_names():
    with pytest.raises(ValueError, match="unknown domain 'cheetah'"):
        suite.load("cheetah", "run")
    with pytest.raises(ValueError, match="unknown task 'swim' in domain 'bundle'"):
        suite.load("bundle", "swim")
    with pytest.raises(ValueError, match=r"unknown task_kwargs \['seed'\]"):
        suite.load("bundle", "reach", task_kwargs={"seed": 1})


@pytest.mark.parametrize("random", [1.5, -1, 2**32, True, "0", float("nan")])
def test_load_names_a_seed_that_is_no_seed(random):
    # numpy said "Cannot cast scalar from dtype('float64')", or "Seed must be between 0 and
    # 2**32 - 1" without naming the key; True was taken as seed 1
    with pytest.raises(ValueError, match=r"task_kwargs\['random'\] must be a whole-number seed"):
        suite.load("bundle", "reach", task_kwargs={"random": random})


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"task_kwargs": [1]}, "task_kwargs must be a dict"),
        ({"environment_kwargs": {"control_timestep": 0.05}}, "control_timestep are set by the task"),
        ({"environment_kwargs": {"n_sub_steps": 2}}, "n_sub_steps are set by the task"),
    ],
)
def test_load_refuses_kwargs_it_cannot_take_by_name(kwargs, words):
    # dm_control said "got multiple values for keyword argument 'control_timestep'" (for any
    # value) and "Both n_sub_steps and control_timestep were supplied"
    with pytest.raises((TypeError, ValueError), match=words):
        suite.load("bundle", "reach", **kwargs)


def test_an_action_that_is_not_real_numbers_is_refused_by_name():
    env = suite.load("bundle", "reach", task_kwargs={"random": 0})
    env.reset()
    with pytest.raises(ValueError, match="real pressure fractions.*complex128"):
        env.step(np.array([0.5 + 1j, 0.5, 0.5]))
    with pytest.raises(ValueError, match="real pressure fractions.*object"):
        env.step(np.array([None, 0.5, 0.5], dtype=object))


@pytest.mark.parametrize("time_limit", [-1, 0, float("nan"), "10", True])
def test_load_refuses_a_time_limit_that_is_not_a_positive_length(time_limit):
    with pytest.raises(ValueError, match="time_limit must be a positive episode length in s"):
        suite.load("bundle", "reach", task_kwargs={"time_limit": time_limit})


def test_a_time_limit_of_any_numeric_type_is_read():
    # a numpy scalar or a 0-d array is one number (they loaded before the check came)
    for limit in (np.float32(2.0), np.array(2.0), np.int64(2)):
        assert suite.load("bundle", "reach", task_kwargs={"time_limit": limit}).reset().first()


def test_an_infinite_time_limit_is_dm_controls_no_limit():
    env = suite.load("bundle", "reach", task_kwargs={"time_limit": float("inf")})
    assert env.reset().first()
    zero = np.zeros(env.action_spec().shape)
    assert not any(env.step(zero).last() for _ in range(5))  # no episode end from the limit


def test_render_refuses_an_image_without_pixels():
    physics = suite.load("bundle", "reach").physics
    for height, width in [(0, 0), (-1, 320), (240, 0), (2.5, 320)]:
        with pytest.raises(ValueError, match=r"height, width: an image is at least 1 x 1 pixels"):
            physics.render(height, width)


@pytest.mark.parametrize("domain,task", TASKS)
def test_model_components_named_and_cameras(domain, task):
    env = suite.load(domain, task)
    model = env.physics.model
    kinds = [
        ("body", "nbody"), ("joint", "njnt"), ("geom", "ngeom"), ("site", "nsite"), ("camera", "ncam"),
        ("light", "nlight"), ("texture", "ntex"), ("material", "nmat"), ("equality", "neq"),
        ("tendon", "ntendon"), ("actuator", "nu"), ("sensor", "nsensor"),
    ]  # fmt: skip
    for kind, size in kinds:
        for index in range(getattr(model, size)):
            assert model.id2name(index, kind), f"{domain}-{task}: unnamed {kind} {index}"
    assert model.ncam >= 2
    for camera in ("side", "front", "perspective"):
        model.name2id(camera, "camera")


#: random steps per task in CI: 1000 on the bundle; 200 on the arm (100 physics steps each at
#: ~12 000/s), whose 1000-step run is in bench/bench_suite.py (random_steps)
RANDOM_STEPS = {"bundle": 1000, "arm": 200}


@pytest.mark.parametrize("domain,task", TASKS)
def test_spec_conformance_and_random_steps(domain, task):
    """Spec conformance, reward and discount ranges, observations that change, and
    ``RANDOM_STEPS`` of random actions (across episode ends) with MuJoCo's warning counters
    still at zero."""
    env = suite.load(domain, task, task_kwargs={"random": 3})
    action_spec = env.action_spec()
    assert action_spec.name == common.ACTION_NAME
    np.testing.assert_array_equal(action_spec.minimum, 0.0)
    np.testing.assert_array_equal(action_spec.maximum, 1.0)
    assert action_spec.shape == (env.physics.model.nu,)
    observation_spec = env.observation_spec()
    policy = random_policy(action_spec, 3)
    seen = {name: [] for name in observation_spec}
    time_step = env.reset()
    steps = 0
    while True:
        observation = dict(time_step.observation)
        for name, spec in observation_spec.items():
            value = observation.pop(name)
            assert value.shape == spec.shape and value.dtype == spec.dtype, name
            assert np.all(np.isfinite(value)), name
            seen[name].append(value)
        assert not observation, f"observations not in the spec: {list(observation)}"
        if time_step.first():
            assert time_step.reward is None and time_step.discount is None
        else:
            assert isinstance(time_step.reward, float) and 0.0 <= time_step.reward <= 1.0
            assert isinstance(time_step.discount, float) and 0.0 <= time_step.discount <= 1.0
        if steps == RANDOM_STEPS[domain]:
            break
        time_step = env.reset() if time_step.last() else env.step(policy(time_step))
        steps += 0 if time_step.first() else 1
    warnings = env.physics.data.warning.number
    assert np.all(warnings == 0), f"MuJoCo warnings: {warnings}"
    for name, values in seen.items():
        stacked = np.array(values)
        constant = np.all(stacked == stacked[0], axis=0)
        assert not np.any(constant), f"{name} has constant elements over {steps} steps"


@pytest.mark.parametrize("domain,task", TASKS)
def test_deterministic_under_a_seed(domain, task):
    first = list(trajectory(domain, task, seed=0))
    second = list(trajectory(domain, task, seed=0))
    assert len(first) == len(second)
    for a, b in zip(first, second):
        assert a.step_type == b.step_type and a.reward == b.reward and a.discount == b.discount
        for key in a.observation:
            np.testing.assert_array_equal(a.observation[key], b.observation[key], err_msg=key)
    other = list(trajectory(domain, task, seed=1, episodes=1, steps=0))
    assert not np.array_equal(other[0].observation["pressures"], first[0].observation["pressures"])


@pytest.mark.parametrize("domain,task", TASKS)
def test_physics_copy_steps_identically(domain, task):
    env = suite.load(domain, task, task_kwargs={"random": 5})
    env.reset()
    env.step(np.full(env.action_spec().shape, 0.6))
    copy = env.physics.copy()
    assert type(copy) is type(env.physics)
    for physics in (env.physics, copy):
        physics.data.ctrl[:] = 0.4 * physics.rated_pressures_Pa()
        physics.step(50)
    np.testing.assert_array_equal(copy.tip_position(), env.physics.tip_position())
    np.testing.assert_array_equal(copy.section_bends(), env.physics.section_bends())
    np.testing.assert_array_equal(copy.muscle_pressures_Pa(), env.physics.muscle_pressures_Pa())


@pytest.mark.parametrize("domain,task", TASKS)
def test_reset_randomises_and_observations_do_not_share_memory(domain, task):
    env = suite.load(domain, task, task_kwargs={"random": 42})
    first = env.reset().observation
    second = env.reset().observation
    assert not all(np.array_equal(first[k], second[k]) for k in first)
    assert env.physics.data.time == 0.0
    after = env.step(np.zeros(env.action_spec().shape)).observation
    for name, array in second.items():
        assert not np.may_share_memory(array, after[name]), name


@pytest.mark.parametrize("domain,task", TASKS)
def test_environment_kwargs_pass_through(domain, task):
    env = suite.load(domain, task, environment_kwargs={"flat_observation": True})
    assert set(env.observation_spec()) == {control.FLAT_OBSERVATION_KEY}


@pytest.mark.parametrize("domain,task", [("bundle", "reach"), ("arm", "push")])
def test_visualize_reward_colours(domain, task):
    env = suite.load(domain, task, task_kwargs={"random": 0}, visualize_reward=True)
    env.reset()
    time_step = env.step(np.full(env.action_spec().shape, 0.5))
    colours = env.physics.named.model.mat_rgba
    blend = float(np.clip(time_step.reward, 0, 1)) ** 4
    for material in ("self", "effector", "target"):
        expected = blend * colours[material + "_highlight"] + (1 - blend) * colours[material + "_default"]
        np.testing.assert_allclose(colours[material], expected, atol=1e-6)  # float32 colours


def test_pressure_lag_is_on_by_default_and_configurable():
    env = suite.load("bundle", "reach", task_kwargs={"random": 0})
    env.reset()
    before = env.physics.muscle_pressure_fractions()
    env.step(np.ones(3))  # one 100 ms control step towards full pressure through a 50 ms lag
    after = env.physics.muscle_pressure_fractions()
    expected = 1.0 - (1.0 - before) * np.exp(-0.1 / 0.05)
    np.testing.assert_allclose(after, expected, atol=1e-9)
    instant = suite.load("bundle", "reach", task_kwargs={"random": 0, "arm_options": {"pressure_tau_s": 0.0}})
    instant.reset()
    instant.step(np.full(3, 0.7))
    np.testing.assert_allclose(instant.physics.muscle_pressure_fractions(), 0.7)


@pytest.mark.parametrize("domain,disks", [("bundle", 4), ("arm", 3)])
def test_muscles_are_drawn_between_the_plates(domain, disks):
    """Each muscle is drawn as one capsule per link, of its outer radius, running parallel to
    the axis at the section radius from it when the arm is straight (equal pressures, no
    gravity): the geometry of the paper's bundle, not read back from the drawing code."""
    import mujoco

    arm_options = {"gravity": False, "disks": disks}
    env = suite.load(domain, "reach", task_kwargs={"random": 0, "arm_options": arm_options})
    env.reset()
    physics = env.physics
    physics.data.qpos[:] = physics.model.qpos0  # the straight pose: equal pressures keep it straight
    physics.data.qvel[:] = 0.0
    physics.set_pressure_fractions(np.full(physics.model.nu, 0.5))
    physics.step(1000)  # settle the length
    spec = env.task.arm_spec
    scene = mujoco.MjvScene(physics.model.ptr, 2000)
    mujoco.mjv_updateScene(
        physics.model.ptr, physics.data.ptr, mujoco.MjvOption(), None, mujoco.MjvCamera(),
        mujoco.mjtCatBit.mjCAT_ALL, scene,
    )  # fmt: skip
    before = scene.ngeom
    added = physics.draw_muscles(scene)
    sections = len(spec.sections)
    assert added == scene.ngeom - before == 3 * sections * disks
    base, rotation = physics.base_frame()
    geoms = scene.geoms[before : scene.ngeom]
    for index, geom in enumerate(geoms):
        section = spec.sections[index // (3 * disks)]
        muscle = (index // disks) % 3
        assert geom.type == mujoco.mjtGeom.mjGEOM_CAPSULE
        assert geom.size[0] == pytest.approx(section.muscles[muscle].rest_outer_radius_m)
        axis_in_base = rotation.T @ np.asarray(geom.mat).reshape(3, 3)[:, 2]
        assert abs(axis_in_base[2]) == pytest.approx(1.0, abs=1e-6)  # parallel to the straight axis
        centre = rotation.T @ (np.asarray(geom.pos) - base)
        angle = section.angles_rad[muscle]
        np.testing.assert_allclose(
            centre[:2], section.radius_m * np.array([np.cos(angle), np.sin(angle)]), atol=1e-6
        )
    # the links' capsules stack up to the tip: their half-lengths add to the arm's length
    tip_in_base = rotation.T @ (physics.tip_position() - base)
    lengths = 2 * np.array([g.size[2] for g in geoms]).reshape(sections, 3, disks).sum(axis=2)
    assert lengths.sum(axis=0) == pytest.approx(np.full(3, tip_in_base[2]), rel=1e-3)


@pytest.mark.filterwarnings("ignore:.*logging.warn.*:DeprecationWarning")  # dm_control's own log call
def test_an_unstable_state_raises_physics_error_or_logs_when_suppressed():
    """The suite's lean step keeps dm_control's contract: a MuJoCo warning during a step raises
    ``PhysicsError`` naming it, or only logs inside ``suppress_physics_errors``; the warning
    counters end as MuJoCo left them."""
    env = suite.load("bundle", "reach", task_kwargs={"random": 0})
    env.reset()
    physics = env.physics
    physics.data.qvel[0] = np.nan
    with pytest.raises(control.PhysicsError, match="mjWARN_BADQVEL"):
        physics.step(3)
    bad_qvel = int(physics.data.warning.number[int(common.mj.mjtWarning.mjWARN_BADQVEL)])
    assert bad_qvel == 1
    env.reset()
    physics.data.qvel[0] = np.nan
    with physics.suppress_physics_errors():
        physics.step(3)  # logged, not raised
    assert physics.data.warning.number.sum() >= 1
    env.reset()
    physics.step(100)  # a sound state steps without complaint
    assert physics.data.warning.number.sum() == 0


def test_long_tail_tolerance_is_dm_controls():
    """The tasks' reward function gives dm_control's ``tolerance(..., sigmoid="long_tail")``
    values: inside, on and outside the bounds, both sides, zero and wide margins, NaN."""
    from dm_control.utils import rewards

    from efam_mujoco.suite.tasks import long_tail_tolerance

    random = np.random.RandomState(0)
    cases = [
        (0.0, (0.0, 0.01), 0.1),
        (0.01, (0.0, 0.01), 0.1),
        (0.02, (0.0, 0.01), 0.0),
        (5.0, (1.0, 1.0), 2.0),
    ]
    for _ in range(2000):
        lower = random.uniform(-1, 1)
        upper = lower + random.choice([0.0, random.uniform(0, 1)])
        margin = random.choice([0.0, random.uniform(1e-3, 3)])
        cases.append((random.uniform(-3, 3), (lower, upper), margin))
    for x, bounds, margin in cases:
        expected = rewards.tolerance(x, bounds=bounds, margin=margin, sigmoid="long_tail")
        assert long_tail_tolerance(x, bounds, margin) == pytest.approx(expected, rel=1e-14, abs=1e-15)
    assert np.isnan(rewards.tolerance(np.nan, bounds=(0, 1), margin=1, sigmoid="long_tail"))
    assert np.isnan(long_tail_tolerance(np.nan, (0, 1), 1))
    with pytest.raises(ValueError):
        long_tail_tolerance(0.0, (1.0, 0.0), 1.0)
    with pytest.raises(ValueError):
        long_tail_tolerance(0.0, (0.0, 1.0), -1.0)
