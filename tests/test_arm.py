"""The MuJoCo arm: its structure, masses, segmented muscles (plugin vs Muscle.push) and its shape
against the muscle model (free length) and the continuum reference (gravity off and on)."""

import itertools
import math

import mujoco
import numpy as np
import pytest

from efam_mujoco import arm, load_muscle, plugin
from efam_mujoco.arm import PAPER_PRESSURES_PA, ArmSpec, SectionSpec, continuum, paper_section

FAM1 = load_muscle("FAM1")
FAM2 = load_muscle("FAM2")
STATIC = dict(gravity=False, pressure_tau_s=0.0)


def warnings(data):
    return {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(data.warning) if w.number}


def at_rest(spec, pressures):
    """The MuJoCo arm at rest under ``pressures`` (flat), and its tip in the base frame."""
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    assert arm.static_equilibrium(model, data, pressures)
    return model, data, arm.tip_in_base(model, data)


# ------------------------------------------------------------------------ models and build


@pytest.mark.parametrize("name", sorted(arm.MODELS))
def test_committed_model_is_the_builders_output(name):
    committed = (arm.MODELS_DIR / f"{name}.xml").read_text()
    assert committed == arm.arm_xml(arm.MODELS[name]()), (
        f"models/{name}.xml is stale: run `python -m efam_mujoco.arm --write-models`"
    )


@pytest.mark.parametrize("name", sorted(arm.MODELS))
def test_committed_model_structure(name):
    """One lagged actuator per muscle; per muscle a whole tendon and 2D segments; only slides and
    hinges, none limited, no equality constraint; at qpos0 the arm is straight at rest length."""
    spec = arm.MODELS[name]()
    model = mujoco.MjModel.from_xml_path(str(arm.MODELS_DIR / f"{name}.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    count = sum(len(s.muscles) for s in spec.sections)
    D = spec.sections[0].disks
    assert model.nu == count and model.na == count
    assert model.ntendon == count * (1 + 2 * D)
    assert model.neq == 0 and not model.jnt_limited.any() and not model.tendon_limited.any()
    assert {int(t) for t in model.jnt_type} == {
        int(mujoco.mjtJoint.mjJNT_SLIDE),
        int(mujoco.mjtJoint.mjJNT_HINGE),
    }
    assert model.nv == 4 * D * len(spec.sections)
    for name_ in itertools.chain(*arm.muscle_names(spec)):
        # the XML keeps 6 significant digits of each half-link's length (0.0106362 of 0.01063625)
        assert data.ten_length[model.tendon(name_).id] == pytest.approx(FAM1.rest_length_m, rel=1e-5)
        np.testing.assert_allclose(
            arm.muscle_segment_lengths(model, data, name_), FAM1.rest_length_m / (2 * D), rtol=1e-5
        )
    np.testing.assert_allclose(data.sensor("tip_pos").data, data.site("tip").xpos)
    expect_tip = sum(s.rest_length_m for s in spec.sections)
    np.testing.assert_allclose(np.linalg.norm(data.site("tip").xpos), expect_tip, rtol=1e-5)


def test_masses_follow_table1():
    """Per muscle: two aluminium end fittings (solid, 2.54 cm x 2.133 cm) and swage tubes (2.54 cm,
    0.884 in bore, 1 in outside), a latex tube (17.78 cm, 1.9/2.22 cm) and a Kevlar sleeve
    (50.8 cm x 2.22 cm x 0.279 mm, half fibre). Moving: everything but the first section's
    base-end parts (its fittings and a quarter of one link's share of the spread mass)."""
    fitting = 2700 * math.pi * 0.02133**2 / 4 * 0.0254
    swage = 2700 * math.pi * (0.0254**2 - (0.884 * 0.0254) ** 2) / 4 * 0.0254
    latex = 930 * math.pi * (0.0222**2 - 0.019**2) / 4 * 0.1778
    sleeve = 1440 * 0.5 * math.pi * 0.0222 * 0.279e-3 * 0.508
    end, body = fitting + swage, latex + sleeve
    assert arm.muscle_part_masses() == pytest.approx((end, body), rel=1e-12)
    assert 0.08 < 2 * end + body < 0.1  # a ~90 g muscle
    for payload in (0.0, 0.7):
        spec = arm.arm_3x3(payload_kg=payload, disks=4)
        model = arm.build_model(spec)
        moving = model.body_subtreemass[model.body("s1h1").id]
        expect = 3 * 3 * (2 * end + body) - 3 * (end + body / 16) + payload
        assert moving == pytest.approx(expect, rel=1e-12)
        loads = continuum.arm_loads(spec)
        total = sum(pm.mass_kg for pm in loads["point_masses"])
        total += sum(rho * s.rest_length_m for rho, s in zip(loads["line_densities_kg_per_m"], spec.sections))
        assert total == pytest.approx(expect + 3 * body / 16, rel=1e-12)  # the continuum spreads all of it


def test_default_radius_fits_3_4_6_8_muscles():
    """Neighbours 10 % of a diameter apart: r = 1.1 d / (2 sin(pi / M))."""
    for count in (3, 4, 6, 8):
        section = SectionSpec(muscles=(FAM1,) * count)
        assert section.radius_m == pytest.approx(1.1 * FAM1.rest_diameter_m / (2 * math.sin(math.pi / count)))
        arm.build_model(ArmSpec(sections=(SectionSpec(muscles=(FAM1,) * count, disks=2),)))


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
    with pytest.raises(ValueError, match="mode"):
        ArmSpec(sections=(paper_section(),), mode="rigid")


# ------------------------------------------------------------------ the segmented muscles


def numeric_gradients(model, data, geometry, h=1e-6):
    """(segments, nv): d(segment length)/d(qvel direction) by central differences of the
    geometry's lengths (joint positions moved along each dof with mj_integratePos)."""
    out = np.empty((geometry.tendons.size, model.nv))
    q0 = data.qpos.copy()
    for i in range(model.nv):
        lengths = []
        for step in (h, -h):
            q = q0.copy()
            direction = np.zeros(model.nv)
            direction[i] = step
            mujoco.mj_integratePos(model, q, direction, 1.0)
            lengths.append(geometry.arc_lengths(q))
        out[:, i] = (lengths[0] - lengths[1]) / (2 * h)
    return out


def test_segment_forces_are_the_muscle_model():
    """Mid-motion, every segment k of every muscle carries push(P, N l_k) along the gradient of
    its length l_k (its arc length, :class:`arm.SegmentLengths`; N = 2D segments of equal
    resting length), at the muscle's one pressure state: actuator + plugin passive forces =
    sum_k push(P, N l_k) grad l_k (to the finite differences' 1e-7). Sensors: the whole muscle's
    tendon length (the sum of its segments' tendons) and push(P, that length)."""
    spec = ArmSpec(sections=(paper_section(disks=3, muscle="FAM1"), paper_section(disks=3, muscle="FAM2")))
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    data.ctrl[:] = np.linspace(50e3, 500e3, model.nu)
    for _ in range(300):
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    names = [n for s in arm.muscle_names(spec) for n in s]
    geometry = arm.SegmentLengths(model, names)
    lengths, gradients = geometry(data), numeric_gradients(model, data, geometry)
    assert np.abs(lengths - data.ten_length[geometry.tendons]).max() > 1e-6  # not the tendons'
    expect = np.zeros(model.nv)
    pressures = arm.muscle_pressures(model, data)
    for m, ((name, muscle), p) in enumerate(
        zip([(n, FAM1 if n.startswith("s1") else FAM2) for n in names], pressures)
    ):
        segments = arm.segment_tendons(model, name)
        N = len(segments)
        assert N == 6
        for k in range(N):
            expect += muscle.push(p, N * lengths[m * N + k]) * gradients[m * N + k]
        total = data.ten_length[model.tendon(name).id]
        assert total == pytest.approx(data.ten_length[segments].sum(), rel=1e-13)
        assert data.sensor(f"len_{name}").data[0] == total
        assert data.sensor(f"force_{name}").data[0] == pytest.approx(
            muscle.push(p, total), rel=1e-9, abs=1e-9
        )
    plugin_part = data.qfrc_passive - data.qfrc_damper - data.qfrc_spring + data.qfrc_actuator
    scale = np.abs(expect).max()
    np.testing.assert_allclose(plugin_part, expect, rtol=0, atol=1e-7 * scale)


def _segment_xml(segments, extra=""):
    return f"""<mujoco><extension><plugin plugin="efam.muscle"><instance name="m">
{plugin.config_xml(load_muscle("FAM1"))}
<config key="segments" value="{segments}"/>{extra}</instance></plugin></extension>
<worldbody><body><joint name="a" type="slide"/><joint name="b" type="slide"/>
<geom size="0.01" mass="0.1"/></body></worldbody>
<tendon><fixed name="whole"><joint joint="a" coef="1"/><joint joint="b" coef="1"/></fixed>
<fixed name="k1"><joint joint="a" coef="1"/></fixed><fixed name="k2"><joint joint="b" coef="1"/></fixed></tendon>
<actuator><plugin instance="m" tendon="whole"/></actuator></mujoco>"""


def test_segment_config_is_validated_with_the_key_named():
    plugin.load()
    mujoco.MjModel.from_xml_string(_segment_xml(2))
    for bad, message in [("0", "segments"), ("1.5", "segments"), ("x", "segments"), ("3", "do not exist")]:
        with pytest.raises(ValueError, match=message):
            mujoco.MjModel.from_xml_string(_segment_xml(bad))
    with pytest.raises(ValueError, match="segments must be a whole number"):
        plugin.plugin_config(FAM1, segments=0)


def test_arc_geometry_config_is_validated_with_the_key_named():
    plugin.load()
    arc = '<config key="arc_geometry" value="1"/>'
    with pytest.raises(ValueError, match="arc_geometry.*segment tendon 'k1'.*1 wraps"):
        mujoco.MjModel.from_xml_string(_segment_xml(2, arc))  # a slide alone is no half-link
    with pytest.raises(ValueError, match="'arc_geometry' must be"):
        mujoco.MjModel.from_xml_string(_segment_xml(2, '<config key="arc_geometry" value="2"/>'))
    with pytest.raises(ValueError, match="arc_geometry' = 1 needs segmented muscles"):
        mujoco.MjModel.from_xml_string(
            _segment_xml(2, arc).replace('key="segments" value="2"', 'key="segments" value="1"')
        )
    with pytest.raises(ValueError, match="arc_geometry needs segmented muscles"):
        plugin.plugin_config(FAM1, arc_geometry=True)


def test_copied_data_has_its_own_arc_geometry():
    """mj_copyData (copy.copy) gives the copy the plugin's arc geometry of its own: both step to
    the same forces, and the copy outlives the original."""
    import copy
    import gc

    model = arm.build_model(arm.arm_1x3(disks=3, pressure_tau_s=0.0))
    data = mujoco.MjData(model)
    data.ctrl[:] = [400e3, 100e3, 250e3]
    for _ in range(50):
        mujoco.mj_step(model, data)
    twin = copy.copy(data)
    mujoco.mj_step(model, data)
    mujoco.mj_step(model, twin)
    np.testing.assert_array_equal(twin.qfrc_passive, data.qfrc_passive)
    del data
    gc.collect()
    mujoco.mj_step(model, twin)
    assert np.all(np.isfinite(twin.qfrc_passive)) and np.abs(twin.qfrc_passive).max() > 0


def test_instance_config_reads_back_the_builders_keys():
    """plugin.instance_config parses a compiled model's keys in the plugin's attribute order:
    every muscle key of every instance reads back as the builder wrote it."""
    spec = ArmSpec(sections=(paper_section(disks=2, muscle="FAM1"), paper_section(disks=2, muscle="FAM2")))
    model = arm.build_model(spec)
    written = [plugin.plugin_config(m, segments=4, arc_geometry=True) for m in (FAM1, FAM2)]
    assert [plugin.instance_config(model, i) for i in range(model.nplugin)] == written
    with pytest.raises(ValueError, match="does not exist"):
        plugin.instance_config(model, model.nplugin)


def test_pressure_lag_is_first_order_and_shared_by_the_segments():
    tau = 0.05
    spec = arm.arm_1x3(pressure_tau_s=tau, disks=2)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    data.ctrl[:] = 400e3
    while data.time < tau - 1e-12:
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(arm.muscle_pressures(model, data), 400e3 * (1 - math.exp(-1)), rtol=1e-9)
    assert model.na == model.nu == 3
    no_lag = arm.build_model(arm.arm_1x3(pressure_tau_s=0.0, disks=2))
    assert no_lag.na == 0
    d2 = mujoco.MjData(no_lag)
    d2.ctrl[:] = 9e9  # beyond ctrlrange: clamped, as MuJoCo applies it
    np.testing.assert_allclose(arm.muscle_pressures(no_lag, d2), spec.max_pressure_Pa)


# ------------------------------------------------------------------ shape: gravity off


@pytest.mark.parametrize("muscle", ["FAM1", "FAM2"])
def test_equal_pressures_section_is_an_arc_of_free_length(muscle):
    """Gravity off, equal pressures: the section is straight at the muscle's free length (an arc
    of zero curvature): Done-when, within 0.5 % (measured: 1e-9)."""
    spec = ArmSpec(sections=(paper_section(muscle=muscle),), **STATIC)
    model = arm.build_model(spec)
    reference = load_muscle(muscle)
    worst = 0.0
    for p in PAPER_PRESSURES_PA:
        data = mujoco.MjData(model)
        assert arm.static_equilibrium(model, data, [p] * 3)
        tip = arm.tip_in_base(model, data)
        worst = max(worst, abs(tip[2] / reference.free_length(p) - 1))
        assert np.hypot(tip[0], tip[1]) < 1e-9
    assert worst < 0.005
    print(f"\n{muscle}: section length vs free length, worst {worst:.1e}")


@pytest.mark.parametrize(
    "muscles, pressures_kPa",
    [
        (3, [[100, 400, 400]]),  # planar: bends in the x-z plane, 1.15 rad per link
        (3, [[300, 200, 100]]),  # oblique, 185 deg
        (4, [[480, 30, 250, 400], [50, 450, 300, 100]]),  # two oblique sections: twist carried on
        (6, [[500, 400, 20, 60, 300, 450], [200, 20, 480, 100, 350, 400]]),
    ],
)
def test_constant_curvature_is_exact_at_four_disks(muscles, pressures_kPa):
    """Gravity off: with 4 disks per section, every segment of every muscle has the continuum's
    muscle length and the tip is the continuum's constant-curvature tip, to 1e-6 of the rest
    length (measured: 1e-12), in and out of the coordinate planes and across sections (the
    segments' arc geometry: tangent lengths R tan(theta/2) and the universal joints' twist
    undone; the linear tendon geometry missed by 3-10 % here)."""
    section = SectionSpec(muscles=(FAM1,) * muscles, disks=4)
    spec = ArmSpec(sections=(section,) * len(pressures_kPa), **STATIC)
    pressures = [np.array(p) * 1e3 for p in pressures_kPa]
    model, data, tip = at_rest(spec, np.concatenate(pressures))
    reference = continuum.solve_arm(spec.sections, pressures)
    error = np.linalg.norm(tip - reference.tip_position_m) / spec.rest_length_m
    assert error < 1e-6, f"tip off by {error:.2e} of the rest length"
    for names, state in zip(arm.muscle_names(spec), reference.sections):
        for name, length in zip(names, state.muscle_lengths_m):
            np.testing.assert_allclose(8 * arm.muscle_segment_lengths(model, data, name), length, rtol=1e-9)
    print(f"\n{muscles} muscles x {len(pressures)}: tip error {error:.1e} of the rest length")


def _bent_arm(bends):
    """A 2x4 arm at D = 3 with random small bends and extensions, the links in ``bends`` set to
    (bend_x, bend_y), random pressures; mj_forward done."""
    spec = ArmSpec(sections=(SectionSpec(muscles=(FAM1,) * 4, disks=3),) * 2, **STATIC)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(7)
    hinge = model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
    data.qpos[:] += np.where(hinge, rng.normal(0.0, 0.3, model.nq), rng.normal(0.0, 0.003, model.nq))
    for link, angles in bends.items():
        for axis, angle in zip("xy", angles):
            data.qpos[model.joint(f"{link}_bend_{axis}").qposadr[0]] = angle
    data.ctrl[:] = rng.uniform(0.0, 500e3, model.nu)
    mujoco.mj_forward(model, data)
    names = [n for s in arm.muscle_names(spec) for n in s]
    forces = data.qfrc_passive - data.qfrc_damper - data.qfrc_spring + data.qfrc_actuator
    return model, data, names, forces


def test_arc_forces_derive_from_the_muscle_potential():
    """The plugin's muscle forces are minus the gradient of the muscles' energy at fixed pressure
    (energy.MusclePotential: each segment's push integrated over its length), by central
    differences: conservative."""
    from efam_mujoco.arm import energy

    spec = ArmSpec(sections=(SectionSpec(muscles=(FAM1,) * 4, disks=4),) * 2, **STATIC)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    assert arm.static_equilibrium(model, data, [480e3, 30e3, 250e3, 400e3, 50e3, 450e3, 300e3, 100e3])
    rng = np.random.default_rng(7)  # near that rest pose (bent 3.8 and 4.3 rad), other pressures
    hinge = model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
    data.qpos[:] += np.where(hinge, rng.normal(0.0, 0.05, model.nq), rng.normal(0.0, 3e-4, model.nq))
    data.ctrl[:] = rng.uniform(0.0, 500e3, model.nu)
    mujoco.mj_forward(model, data)
    forces = data.qfrc_passive - data.qfrc_damper - data.qfrc_spring + data.qfrc_actuator
    names = [n for s in arm.muscle_names(spec) for n in s]
    potential = energy.MusclePotential(model, names, [FAM1] * len(names), data.ctrl)
    q0, h = data.qpos.copy(), 1e-5  # steps over many cells of the potential's table
    gradient = np.empty(model.nv)
    for i in range(model.nv):
        values = []
        for step in (h, -h):
            data.qpos[:] = q0
            direction = np.zeros(model.nv)
            direction[i] = step
            mujoco.mj_integratePos(model, data.qpos, direction, 1.0)
            values.append(potential(data))
        gradient[i] = (values[0] - values[1]) / (2 * h)
    np.testing.assert_allclose(forces, -gradient, rtol=0, atol=1e-6 * np.abs(forces).max())


def test_arc_geometry_blends_into_the_linear_geometry_beyond_two_radians():
    """A link bent 2.25 rad (in the blend) and one 2.7 rad (linear geometry; the swing is
    singular at pi): the forces stay finite and are still push(P, N l) along the gradient of
    the blended lengths (far beyond the muscles' admissible lengths: the lock-out acts)."""
    model, data, names, forces = _bent_arm({"s1d2": (2.25, 0.0), "s2d3": (0.3, 2.8)})
    geometry = arm.SegmentLengths(model, names)
    lengths, gradients = geometry(data), numeric_gradients(model, data, geometry)
    N = 6
    expect = sum(FAM1.push(data.ctrl[k // N], N * lengths[k]) * gradients[k] for k in range(lengths.size))
    assert np.all(np.isfinite(forces))
    np.testing.assert_allclose(forces, expect, rtol=0, atol=1e-7 * np.abs(expect).max())


def random_pressures(rng, count, strong):
    """Uniform in the tested range, or strongly differential (one or two muscles near full
    pressure, the others near zero)."""
    if not strong:
        return rng.uniform(0.0, arm.MAX_TESTED_PRESSURE_PA, count)
    p = rng.uniform(0.0, 0.1, count)
    p[rng.choice(count, size=rng.integers(1, count), replace=False)] = rng.uniform(0.85, 1.0)
    return p * arm.MAX_TESTED_PRESSURE_PA


@pytest.mark.parametrize("muscles", [3, 4, 6])
@pytest.mark.parametrize("sections", [1, 2, 3])
def test_random_pressures_match_the_continuum_reference(muscles, sections):
    """Gravity off, random pressure sets (every second one strongly differential), default D:
    no limit but the muscles' admissible lengths (there are no joint limits), and the tip is
    within 1 % of the arm's rest length of the continuum reference (here: CC). Two sets per
    layout here; bench/bench_arm.py --sweep runs 200 per layout."""
    rng = np.random.default_rng(100 * muscles + sections)
    section = SectionSpec(muscles=(FAM1,) * muscles)
    spec = ArmSpec(sections=(section,) * sections, **STATIC)
    model = arm.build_model(spec)
    for case in range(2):
        pressures = [random_pressures(rng, muscles, strong=case % 2 == 1) for _ in range(sections)]
        data = mujoco.MjData(model)
        assert arm.static_equilibrium(model, data, np.concatenate(pressures))
        reference = continuum.solve_arm(spec.sections, pressures)
        error = np.linalg.norm(arm.tip_in_base(model, data) - reference.tip_position_m) / spec.rest_length_m
        assert error < 0.01, f"{np.round(np.concatenate(pressures) / 1e3)} kPa: tip off by {error:.2%}"


def test_bundle_bends_towards_the_lower_pressure_muscle():
    spec = ArmSpec(sections=(paper_section(disks=4),), **STATIC)
    for low in range(3):
        pressures = [350e3] * 3
        pressures[low] = 250e3
        _, _, tip = at_rest(spec, pressures)
        alpha = math.radians(120 * low)
        assert tip[:2] @ [math.cos(alpha), math.sin(alpha)] > 0.99 * np.linalg.norm(tip[:2]) > 0.02


# ------------------------------------------------------------------ shape: gravity on


@pytest.mark.parametrize(
    "orientation, sections, pressures_kPa, payload_kg",
    [
        ("hanging", 2, [200, 300, 300], 0.0),
        ("hanging", 1, [400, 250, 250], 1.0),
        ("upright", 1, [517, 517, 517], 0.0),
        ("upright", 1, [517, 480, 480], 0.2),
        ("horizontal", 1, [300, 300, 300], 0.0),
        ("horizontal", 1, [300, 450, 450], 1.0),
        ("horizontal", 2, [300, 400, 400], 0.5),
    ],
)
def test_gravity_and_tip_loads_match_the_continuum_reference(
    orientation, sections, pressures_kPa, payload_kg
):
    """Gravity on, the arm's own weight and a 0-1 kg tip load, default D: tip within 1 % of the
    arm's rest length of the continuum reference (the rod under its distributed and lumped
    masses; not a constant-curvature arc)."""
    spec = ArmSpec(
        sections=(paper_section(),) * sections,
        orientation=orientation,
        payload_kg=payload_kg,
        pressure_tau_s=0.0,
    )
    pressures = [np.array(pressures_kPa) * 1e3] * sections
    _, _, tip = at_rest(spec, np.concatenate(pressures))
    reference = continuum.solve_arm_spec(spec, pressures)
    error = np.linalg.norm(tip - reference.tip_position_m) / spec.rest_length_m
    assert error < 0.01, f"tip off by {error:.2%}"
    print(f"\n{orientation} x{sections}, {payload_kg} kg: tip error {error:.3%} of rest length")


def test_mixed_muscles_in_one_section():
    """FAM1 (two laws) and FAM2 side by side: slightly different free lengths at one pressure,
    so the section bends a little, as the continuum reference of the mixed bundle says."""
    muscles = (load_muscle("FAM1"), load_muscle("FAM2"), load_muscle("FAM1", law="linear"))
    section = SectionSpec(muscles=muscles, angles_deg=(0, 110, 235))
    spec = ArmSpec(sections=(section,), **STATIC)
    _, _, tip = at_rest(spec, [120e3] * 3)
    reference = continuum.solve_arm([section], [[120e3] * 3])
    assert reference.sections[0].bend_angle_rad > 0.2
    assert np.linalg.norm(tip - reference.tip_position_m) / spec.rest_length_m < 0.01


def test_no_warnings_through_pressure_steps():
    """Full pressure steps and a differential step under gravity with a 1 kg payload, 3 s: finite,
    no MuJoCo warnings (shipped time step)."""
    spec = arm.arm_1x3(orientation="horizontal", payload_kg=1.0)
    model = arm.build_model(spec)
    data = mujoco.MjData(model)
    while data.time < 3.0:
        data.ctrl[:] = 0.0 if data.time < 1 else spec.max_pressure_Pa
        if data.time > 2:
            data.ctrl[0] = 0.0
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos)) and warnings(data) == {}


def test_affine_reference_is_the_muscle_tangent_per_segment():
    """The bench's built-in actuators: one per segment, the muscle's tangent at half the pressure
    range and its free length, in the segment's length (slope x N)."""
    spec = arm.arm_1x3(pressure_tau_s=0.0, disks=2)
    model = arm.build_model(spec, muscles="affine")
    assert model.nu == 3 * 4
    p0 = spec.max_pressure_Pa / 2
    l0 = FAM1.free_length(p0) / 4
    gain, bias0, bias1 = (
        model.actuator_gainprm[0, 0],
        model.actuator_biasprm[0, 0],
        model.actuator_biasprm[0, 1],
    )
    assert gain * p0 + bias0 + bias1 * l0 == pytest.approx(0.0, abs=1e-6)
    slope = (FAM1.push(p0, 4 * l0 + 1e-4) - FAM1.push(p0, 4 * l0 - 1e-4)) / 2e-4
    assert bias1 == pytest.approx(4 * slope, rel=1e-3)
    with pytest.raises(ValueError, match="muscles must be"):
        arm.build_spec(spec, muscles="python")
