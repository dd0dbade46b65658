"""The MuJoCo arm against the muscle model (Eqs. 2, 9) and constant-curvature statics."""

import itertools
import math

import mujoco
import numpy as np
import pytest

from efam_mujoco import arm, load_muscle
from efam_mujoco.arm import PAPER_PRESSURES_PA, ArmSpec, SectionSpec, paper_section
from efam_mujoco.statics import solve_arm, solve_section

FAM1 = load_muscle("FAM1")
FAM2 = load_muscle("FAM2")
# quasi-static runs: gravity off, no pressure lag, damping near critical for both modes
STATIC = dict(gravity=False, pressure_tau_s=0.0, axial_damping_N_s_per_m=40.0, bend_damping_N_m_s_per_rad=0.1)


def settle(model, data, pressures, t_max=6.0, vel_tol=1e-6):
    arm.settle(model, data, pressures, t_max_s=t_max, vel_tol=vel_tol)
    return data


tip_in_base = arm.tip_in_base


def warnings(data):
    return {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(data.warning) if w.number}


# ------------------------------------------------------------------------ models and build


@pytest.mark.parametrize("name", sorted(arm.MODELS))
def test_committed_model_is_the_builders_output(name):
    committed = (arm.MODELS_DIR / f"{name}.xml").read_text()
    assert committed == arm.arm_xml(arm.MODELS[name]()), (
        f"models/{name}.xml is stale: run `python -m efam_mujoco.arm --write-models`"
    )


@pytest.mark.parametrize("name", sorted(arm.MODELS))
def test_committed_model_structure(name):
    spec = arm.MODELS[name]()
    model = mujoco.MjModel.from_xml_path(str(arm.MODELS_DIR / f"{name}.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    count = sum(len(s.muscles) for s in spec.sections)
    assert model.nu == count and model.na == count  # one lagged plugin actuator per muscle
    assert model.ntendon == count
    np.testing.assert_allclose(data.ten_length, FAM1.rest_length_m, rtol=1e-6)  # rest at qpos0
    np.testing.assert_allclose(data.sensor("tip_pos").data, data.site("tip").xpos)
    np.testing.assert_allclose(
        data.sensor("tip_quat").data, data.xquat[model.site_bodyid[model.site("tip").id]]
    )
    expect_tip = sum(s.rest_length_m for s in spec.sections)
    np.testing.assert_allclose(np.linalg.norm(data.site("tip").xpos), expect_tip, rtol=1e-6)


def test_masses_follow_table1():
    """Per muscle: two aluminium end fittings (solid, 2.54 cm x 2.133 cm) and swage tubes (2.54 cm,
    0.884 in bore, 1 in outside), a latex tube (17.78 cm, 1.9/2.22 cm) and a Kevlar sleeve
    (50.8 cm x 2.22 cm x 0.279 mm, half fibre). The moving mass of an arm is everything but the
    base-end parts of the first section."""
    fitting = 2700 * math.pi * 0.02133**2 / 4 * 0.0254
    swage = 2700 * math.pi * (0.0254**2 - (0.884 * 0.0254) ** 2) / 4 * 0.0254
    latex = 930 * math.pi * (0.0222**2 - 0.019**2) / 4 * 0.1778
    sleeve = 1440 * 0.5 * math.pi * 0.0222 * 0.279e-3 * 0.508
    end, body = fitting + swage, latex + sleeve
    assert arm.muscle_part_masses() == pytest.approx((end, body), rel=1e-12)
    assert 0.08 < 2 * end + body < 0.1  # a ~90 g muscle
    for payload in (0.0, 0.7):
        spec = arm.arm_3x3(payload_kg=payload)
        model = arm.build_model(spec)
        moving = model.body_subtreemass[model.body("s1d1").id]
        assert moving == pytest.approx(3 * 3 * (2 * end + body) - 3 * (end + body / 8) + payload, rel=1e-12)
        assert sum(pm.mass_kg for pm in arm.point_masses(spec)) == pytest.approx(moving, rel=1e-12)


def test_bad_specs_are_named():
    with pytest.raises(ValueError, match="at least 3"):
        SectionSpec(muscles=(FAM1, FAM1))
    with pytest.raises(ValueError, match="overlap"):
        SectionSpec(muscles=(FAM1,) * 3, radius_m=0.01)
    with pytest.raises(ValueError, match="3 muscles but 2 angles_deg"):
        SectionSpec(muscles=(FAM1,) * 3, angles_deg=(0, 90))
    with pytest.raises(ValueError, match="orientation"):
        ArmSpec(sections=(paper_section(),), orientation="sideways")
    with pytest.raises(ValueError, match="pressure_tau_s"):
        ArmSpec(sections=(paper_section(),), pressure_tau_s=-1)


# ----------------------------------------------------------------- statics: the Done-when


@pytest.mark.parametrize("muscle", ["FAM1", "FAM2"])
def test_equal_pressures_section_length_is_free_length(muscle):
    """Gravity off, equal pressures: the section stays straight at the muscle's free length."""
    spec = ArmSpec(sections=(paper_section(muscle=muscle),), **STATIC)
    model = arm.build_model(spec)
    reference = load_muscle(muscle)
    for p in PAPER_PRESSURES_PA:
        data = settle(model, mujoco.MjData(model), [p] * 3)
        tip = tip_in_base(model, data)
        assert tip[2] == pytest.approx(reference.free_length(p), rel=0.01)
        assert np.hypot(tip[0], tip[1]) < 1e-6


@pytest.mark.parametrize("muscle", ["FAM1", "FAM2"])
def test_held_at_rest_length_force_is_blocked_force(muscle):
    """Tip plate welded at the resting length: the muscles push with M x Eq. 9 together."""
    spec = ArmSpec(sections=(paper_section(muscle=muscle),), hold_tip=True, **STATIC)
    model = arm.build_model(spec)
    reference = load_muscle(muscle)
    for p in PAPER_PRESSURES_PA:
        data = settle(model, mujoco.MjData(model), [p] * 3, t_max=1.0)
        total_push = data.actuator_force.sum()
        assert total_push == pytest.approx(-3 * reference.blocked_force(p), rel=0.005)
        np.testing.assert_allclose(data.ten_length, reference.rest_length_m, rtol=1e-4)


def unequal_triples(max_bend_deg=120.0):
    """Every unequal triple of the paper's pressures whose section bends at most max_bend_deg
    (a 20 mm bundle curls up beyond that; the disks' hinge limits allow 240 deg)."""
    section = paper_section()
    for triple in itertools.product(PAPER_PRESSURES_PA, repeat=3):
        if len(set(triple)) > 1:
            state, arm_state = solve_section(section, triple)
            if math.degrees(state.bend_angle_rad) <= max_bend_deg:
                yield triple, state, arm_state


def test_unequal_pressures_tip_matches_constant_curvature():
    spec = ArmSpec(sections=(paper_section(),), **STATIC)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    worst, cases = 0.0, 0
    for triple, state, reference in unequal_triples():
        mujoco.mj_resetData(model, data)
        settle(model, data, triple)
        error = np.linalg.norm(tip_in_base(model, data) - reference.tip_position_m) / state.arc_length_m
        worst, cases = max(worst, error), cases + 1
        assert error < 0.02, f"pressures {np.round(np.array(triple) / 1e3, 1)} kPa: tip off by {error:.2%}"
    assert cases >= 30
    print(f"\n{cases} unequal triples: worst tip error {worst:.3%} of section length")


def test_three_section_arm_matches_constant_curvature():
    # the whole arm's bending mode is slow (soft sections, long lever): more bend damping
    spec = ArmSpec(sections=(paper_section(),) * 3, **{**STATIC, "bend_damping_N_m_s_per_rad": 0.6})
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    kpa = 1e3
    cases = [
        [
            [310 * kpa, 310 * kpa, 413 * kpa],
            [413 * kpa, 310 * kpa, 413 * kpa],
            [517 * kpa, 413 * kpa, 413 * kpa],
        ],
        [[207 * kpa, 310 * kpa, 310 * kpa], [517 * kpa] * 3, [310 * kpa, 517 * kpa, 413 * kpa]],
    ]
    for pressures in cases:
        mujoco.mj_resetData(model, data)
        settle(model, data, pressures, t_max=20.0)
        reference = solve_arm(spec.sections, pressures)
        length = sum(s.arc_length_m for s in reference.sections)
        error = np.linalg.norm(tip_in_base(model, data) - reference.tip_position_m) / length
        assert error < 0.02, f"tip off by {error:.2%} of the arm's length"
        print(f"\n3x3 arm: tip error {error:.3%} of arm length")
        np.testing.assert_allclose(
            data.ten_length.reshape(3, 3), [s.muscle_lengths_m for s in reference.sections], rtol=0.01
        )


def test_bundle_bends_towards_the_lower_pressure_muscle():
    spec = ArmSpec(sections=(paper_section(),), **STATIC)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    for low in range(3):
        pressures = [350e3] * 3
        pressures[low] = 250e3
        mujoco.mj_resetData(model, data)
        settle(model, data, pressures, t_max=2.0, vel_tol=1e-3)
        alpha = math.radians(120 * low)
        tip_xy = tip_in_base(model, data)[:2]
        assert tip_xy @ [math.cos(alpha), math.sin(alpha)] > 0.9 * np.linalg.norm(tip_xy) > 0.02


def test_mixed_muscles_in_one_section():
    """FAM1 (two laws) and FAM2 side by side: slightly different free lengths at one pressure,
    so the section bends a little, as the statics of the mixed bundle says."""
    muscles = (load_muscle("FAM1"), load_muscle("FAM2"), load_muscle("FAM1", law="linear"))
    section = SectionSpec(muscles=muscles, angles_deg=(0, 110, 235))
    spec = ArmSpec(sections=(section,), **STATIC)
    model = arm.build_model(spec)
    data = settle(model, mujoco.MjData(model), [120e3] * 3)
    state, reference = solve_section(section, [120e3] * 3)
    assert state.bend_angle_rad > 0.2
    error = np.linalg.norm(tip_in_base(model, data) - reference.tip_position_m) / state.arc_length_m
    assert error < 0.02


# ------------------------------------------------------------------------- the actuators


def test_sensors_and_forces_are_the_muscle_model():
    """Mid-motion: force sensors = actuator forces = Muscle.push at the sensed tendon length and
    the filtered pressure; length sensors = tendon lengths."""
    spec = arm.arm_3x3()
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    data.ctrl[:] = np.linspace(100e3, 500e3, model.nu)
    for _ in range(150):
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    pressures = arm.muscle_pressures(model, data)
    for name, p in zip(itertools.chain(*arm.muscle_names(spec)), pressures):
        length = data.sensor(f"len_{name}").data[0]
        assert length == data.ten_length[model.tendon(name).id]
        force = data.sensor(f"force_{name}").data[0]
        assert force == data.actuator_force[model.actuator(name).id]
        assert force == pytest.approx(FAM1.push(p, length), rel=1e-9, abs=1e-9)


def test_pressure_lag_is_first_order():
    tau = 0.05
    spec = arm.arm_1x3(pressure_tau_s=tau)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    data.ctrl[:] = 400e3
    while data.time < tau - 1e-12:
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(arm.muscle_pressures(model, data), 400e3 * (1 - math.exp(-1)), rtol=1e-9)
    no_lag = arm.build_model(arm.arm_1x3(pressure_tau_s=0.0))
    assert no_lag.na == 0
    d2 = mujoco.MjData(no_lag)
    d2.ctrl[:] = 9e9  # beyond ctrlrange: clamped, as MuJoCo applies it
    np.testing.assert_allclose(arm.muscle_pressures(no_lag, d2), spec.max_pressure_Pa)


# ---------------------------------------------------------------------------- robustness


@pytest.mark.parametrize("orientation", ["upright", "hanging", "horizontal"])
@pytest.mark.parametrize("payload_kg", [0.0, 1.0])
def test_gravity_pressure_steps_stay_finite(orientation, payload_kg):
    """Gravity on, shipped time step: 10 s of zero pressure, steps to full pressure in one time
    step, a differential step, and back; with the shipped lag and (hanging) without any lag."""
    lags = [arm.ArmSpec.pressure_tau_s] + ([0.0] if orientation == "hanging" else [])
    for tau in lags:
        spec = arm.arm_3x3(orientation=orientation, payload_kg=payload_kg, pressure_tau_s=tau)
        assert spec.timestep_s == arm.ArmSpec.timestep_s
        model = arm.build_model(spec)
        data = mujoco.MjData(model)
        full = spec.max_pressure_Pa
        while data.time < 10.0:
            t = data.time
            data.ctrl[:] = 0.0 if t < 3 else full
            if 6 < t < 8:
                data.ctrl[::3] = 0.0
            mujoco.mj_step(model, data)
        assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
        assert np.all(np.isfinite(data.sensordata))
        assert warnings(data) == {}, f"tau={tau}: {warnings(data)}"


def test_affine_reference_is_the_muscle_tangent():
    """The bench's built-in actuators: the muscle model's tangent at half the pressure range and
    the free length there (zero force, the model's slopes in pressure and length)."""
    spec = arm.arm_1x3(pressure_tau_s=0.0)
    model = arm.build_model(spec, muscles="affine")
    p0 = spec.max_pressure_Pa / 2
    l0 = FAM1.free_length(p0)
    gain, bias0, bias1 = (
        model.actuator_gainprm[0, 0],
        model.actuator_biasprm[0, 0],
        model.actuator_biasprm[0, 1],
    )
    assert gain * p0 + bias0 + bias1 * l0 == pytest.approx(0.0, abs=1e-6)
    assert gain == pytest.approx(
        (FAM1.push(p0 * 1.01, l0) - FAM1.push(p0 * 0.99, l0)) / (0.02 * p0), rel=1e-3
    )
    assert bias1 == pytest.approx((FAM1.push(p0, l0 + 1e-4) - FAM1.push(p0, l0 - 1e-4)) / 2e-4, rel=1e-3)
    with pytest.raises(ValueError, match="muscles must be"):
        arm.build_spec(spec, muscles="python")
