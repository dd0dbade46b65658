"""The native efam.muscle plugin against the Python reference model and against MuJoCo's rules.

Forces are read from MuJoCo (a spatial tendon between a fixed site and a plate on a slide
joint, mj_forward) and compared with ``Muscle.push`` at the tendon length MuJoCo reports.
"""

from __future__ import annotations

import copy
import gc
import math
import threading

import mujoco
import numpy as np
import pytest
from mujoco import rollout

import efam_mujoco
from efam_mujoco import Muscle, StressLaw, load_muscle
from efam_mujoco import plugin as efam_plugin
from efam_mujoco.plugin import PluginLoadError, config_xml, instance_xml, plugin_config

TABLE4_LAWS = ("linear", "polynomial", "exponential_decay", "exponent")
PSI = 6894.757


def model_xml(muscle: Muscle, actuator_attrs: str = "", config: dict[str, str] | None = None) -> str:
    """One muscle on a spatial tendon from the origin to a plate that slides along z."""
    if config is None:
        config = plugin_config(muscle)
    lines = "\n".join(f'        <config key="{k}" value="{v}"/>' for k, v in config.items())
    return f"""
<mujoco model="one_muscle">
  <option timestep="0.001" gravity="0 0 0"/>
  <extension><plugin plugin="efam.muscle"/></extension>
  <worldbody>
    <site name="base" pos="0 0 0"/>
    <body name="plate" pos="0 0 {muscle.rest_length_m!r}">
      <joint name="slide" type="slide" axis="0 0 1"/>
      <geom type="box" size="0.02 0.02 0.002" mass="0.2"/>
      <site name="end" pos="0 0 0"/>
    </body>
  </worldbody>
  <tendon><spatial name="t1"><site site="base"/><site site="end"/></spatial></tendon>
  <actuator>
    <plugin name="m1" plugin="efam.muscle" tendon="t1" {actuator_attrs}>
{lines}
    </plugin>
  </actuator>
</mujoco>"""


def compile_muscle(muscle: Muscle, actuator_attrs: str = ""):
    model = mujoco.MjModel.from_xml_string(model_xml(muscle, actuator_attrs))
    return model, mujoco.MjData(model)


def force_at(model, data, muscle: Muscle, pressure: float, length: float) -> tuple[float, float]:
    """(MuJoCo actuator force, tendon length) with the plate placed so the tendon has ``length``."""
    data.qpos[0] = length - muscle.rest_length_m
    data.ctrl[0] = pressure
    mujoco.mj_forward(model, data)
    return float(data.actuator_force[0]), float(data.actuator_length[0])


def contractile(**kw) -> Muscle:
    """A McKibben-like muscle (braid angle 60 deg > 35.26 deg: contracts under pressure)."""
    return Muscle(
        rest_length_m=0.15,
        rest_diameter_m=0.02,
        theta_rest_deg=60.0,
        bladder_volume_m3=9e-6,
        deadband_Pa=2e4,
        stress=StressLaw("linear", (1.5e6, 1.0)),
        name="mckibben",
        **kw,
    )


def muscles_under_test() -> dict[str, Muscle]:
    cases = {}
    for preset in ("FAM1", "FAM2"):
        for law in TABLE4_LAWS:
            cases[f"{preset}-{law}"] = load_muscle(preset, law=law)
    fam1 = load_muscle("FAM1")
    cases["FAM1-sigmoid"] = fam1.with_stress(StressLaw("sigmoid", (1.5e6, 1.9, 1.2e5, 13.0)))
    cases["FAM2-arccot"] = load_muscle("FAM2").with_stress(StressLaw("arccot", (1.4e6, 2.0, 2.0e5, 9.0)))
    cases["contractile"] = contractile()
    cases["contractile-tension_only"] = contractile(tension_only=True, lock_stiffness_N_per_m=5e3)
    return cases


MUSCLES = muscles_under_test()


def probe_lengths(muscle: Muscle) -> np.ndarray:
    """A dense grid over the admissible range, its exact ends, and lengths beyond both ends."""
    lo, hi = muscle.min_length_m, muscle.max_length_m
    inside = np.linspace(lo, hi, 161)
    outside = [0.5 * lo, 0.99 * lo, lo - 1e-9, hi + 1e-9, 1.01 * hi, 1.3 * hi]
    return np.concatenate([inside, [muscle.rest_length_m], outside])


def probe_pressures(muscle: Muscle) -> list[float]:
    below_deadband = [0.0, 0.5 * muscle.deadband_Pa, muscle.deadband_Pa]
    paper = [p * PSI for p in (15, 30, 45, 60, 75)]
    return [-5e4, *below_deadband, *paper, 1e6]


# ------------------------------------------------------------------------- reference agreement
@pytest.mark.parametrize("case", sorted(MUSCLES))
def test_plugin_force_equals_python_reference(case):
    muscle = MUSCLES[case]
    model, data = compile_muscle(muscle)
    lengths = probe_lengths(muscle)
    assert lengths.min() < muscle.min_length_m and lengths.max() > muscle.max_length_m
    worst = 0.0
    strains_seen = set()
    for pressure in probe_pressures(muscle):
        for target in lengths:
            force, length = force_at(model, data, muscle, pressure, target)
            reference = muscle.push(pressure, length)
            assert math.isfinite(force)
            error = abs(force - reference) / max(1.0, abs(reference))
            worst = max(worst, error)
            assert error <= 1e-9, (case, pressure, length, force, reference)
            strains_seen.add(np.sign(length - muscle.rest_length_m))
    assert {-1.0, 1.0} <= strains_seen  # both signs of strain were probed
    print(f"{case}: max relative error {worst:.3g}")


def test_tension_only_muscle_never_pushes():
    muscle = MUSCLES["contractile-tension_only"]
    model, data = compile_muscle(muscle)
    forces = [force_at(model, data, muscle, 3e5, L)[0] for L in probe_lengths(muscle)]
    assert max(forces) <= 0.0  # MuJoCo sign: pull is negative
    assert min(forces) < 0.0


def test_force_at_rest_length_is_gaylord_blocked_force():
    """Eq. 9: at the resting length with a linear law the strains vanish, so the plugin gives
    Gaylord's blocked force with the dead band, F = (P - P_db) pi D^2/4 (3 sin^2 - 1)/cos^2."""
    muscle = load_muscle("FAM1", law="linear")
    model, data = compile_muscle(muscle)
    theta = math.radians(muscle.theta_rest_deg)
    area = math.pi * muscle.rest_diameter_m**2 / 4
    for psi in (15, 30, 45, 60, 75):
        pressure = psi * PSI
        force, _ = force_at(model, data, muscle, pressure, muscle.rest_length_m)
        gaylord = (
            (pressure - muscle.deadband_Pa) * area * (3 * math.sin(theta) ** 2 - 1) / math.cos(theta) ** 2
        )
        # extensile: Eq. 9 is negative (it pushes), so the MuJoCo force is positive
        assert force > 0
        assert force == pytest.approx(-gaylord, rel=1e-6)


def test_one_instance_drives_several_actuators():
    muscle = load_muscle("FAM2")
    xml = f"""
<mujoco>
  <extension><plugin plugin="efam.muscle">{instance_xml("fam2", muscle)}</plugin></extension>
  <worldbody>
    <site name="o1" pos="0 0 0"/><site name="o2" pos="1 0 0"/>
    <body pos="0 0 0.17"><joint type="slide" axis="0 0 1"/><geom size="0.01"/><site name="e1"/></body>
    <body pos="1 0 0.21"><joint type="slide" axis="0 0 1"/><geom size="0.01"/><site name="e2"/></body>
  </worldbody>
  <tendon>
    <spatial name="t1"><site site="o1"/><site site="e1"/></spatial>
    <spatial name="t2"><site site="o2"/><site site="e2"/></spatial>
  </tendon>
  <actuator>
    <plugin instance="fam2" tendon="t1"/>
    <plugin instance="fam2" tendon="t2"/>
  </actuator>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.ctrl[:] = [2e5, 4e5]
    mujoco.mj_forward(model, data)
    expected = [muscle.push(p, L) for p, L in zip(data.ctrl, data.actuator_length)]
    np.testing.assert_allclose(data.actuator_force, expected, rtol=1e-12)
    assert data.actuator_force[0] != data.actuator_force[1]


def _instance_only_xml(muscle_instance: str) -> str:
    return f"""<mujoco><extension><plugin plugin="efam.muscle">{muscle_instance}</plugin></extension>
  <worldbody><body><joint type="slide"/><geom size="0.01"/></body></worldbody></mujoco>"""


def test_declared_instance_without_actuators_compiles_but_is_validated():
    mujoco.MjModel.from_xml_string(_instance_only_xml(instance_xml("spare", load_muscle("FAM1"))))
    bad = instance_xml("spare", load_muscle("FAM1")).replace('key="E4" value="', 'key="E4" value="-')
    with pytest.raises(ValueError, match="instance 'spare'.*'E4'"):
        mujoco.MjModel.from_xml_string(_instance_only_xml(bad))


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("bad_ctrl", [math.nan, math.inf, -math.inf])
def test_non_finite_control_gives_finite_zero_force(bad_ctrl):
    muscle = load_muscle("FAM1")
    model, data = compile_muscle(muscle)
    force, _ = force_at(model, data, muscle, bad_ctrl, 0.9 * muscle.rest_length_m)
    assert force == 0.0  # the documented rule: a non-finite input gives zero force
    mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qacc))


def test_lengths_far_outside_the_admissible_range_give_finite_lock_out_forces():
    muscle = load_muscle("FAM1")
    model, data = compile_muscle(muscle)
    for length in (1e-4, 0.2 * muscle.min_length_m, 3 * muscle.max_length_m, 50.0):
        force, actual = force_at(model, data, muscle, 5e5, length)
        assert math.isfinite(force)
        # beyond the bound the lock-out spring pushes back toward the admissible range
        if actual < muscle.min_length_m:
            assert force > muscle.push(5e5, muscle.min_length_m)
        else:
            assert force < muscle.push(5e5, muscle.max_length_m)


def test_overflowing_stress_law_never_hands_mujoco_inf_or_nan():
    # a legal but extreme exponential-decay law: exp(-E4 eps) overflows in compression
    muscle = load_muscle("FAM1").with_stress(StressLaw("exponential_decay", (1.5e6, 2.0, 1e5, 2000.0)))
    with np.errstate(over="ignore", invalid="ignore"):
        assert not np.isfinite(muscle.push(3e5, muscle.min_length_m))  # the Python model overflows
    model, data = compile_muscle(muscle)
    for length in probe_lengths(muscle):
        force, _ = force_at(model, data, muscle, 3e5, length)
        assert math.isfinite(force)


def test_control_is_clamped_to_ctrlrange():
    muscle = load_muscle("FAM1")
    model, data = compile_muscle(muscle, 'ctrllimited="true" ctrlrange="0 700000"')
    force, length = force_at(model, data, muscle, 2e6, muscle.rest_length_m)
    assert force == pytest.approx(muscle.push(7e5, length), rel=1e-12)


def _set(config: dict[str, str], **changes) -> dict[str, str]:
    out = dict(config)
    for key, value in changes.items():
        if value is None:
            out.pop(key, None)
        else:
            out[key] = value
    return out


def _volume_filling_sleeve_at_rest(muscle: Muscle) -> float:
    """The bladder volume that exactly fills the sleeve at the resting length (Eq. 10, 11)."""
    L, B, N = muscle.rest_length_m, muscle.thread_length_m, muscle.turns
    return L * (B * B - L * L) / (4 * math.pi * N * N)


FAM1 = load_muscle("FAM1")  # exponential_decay: E1_Pa, E2, E3_Pa, E4
GOOD = plugin_config(FAM1)
POLY = plugin_config(load_muscle("FAM1", law="polynomial"))
EXPONENT = plugin_config(load_muscle("FAM1", law="exponent"))

BAD_CONFIGS = {
    "missing rest_length_m": (_set(GOOD, rest_length_m=None), "rest_length_m"),
    "missing bladder_volume_m3": (_set(GOOD, bladder_volume_m3=None), "bladder_volume_m3"),
    "missing deadband_Pa": (_set(GOOD, deadband_Pa=None), "deadband_Pa"),
    "missing law": (_set(GOOD, law=None), "'law'"),
    "missing coefficient": (_set(GOOD, E4=None), "'E4'"),
    "non-numeric": (_set(GOOD, rest_diameter_m="2.87cm"), "rest_diameter_m"),
    "nan value": (_set(GOOD, theta_rest_deg="nan"), "theta_rest_deg"),
    "negative length": (_set(GOOD, rest_length_m="-0.17"), "rest_length_m"),
    "zero diameter": (_set(GOOD, rest_diameter_m="0"), "rest_diameter_m"),
    "theta zero": (_set(GOOD, theta_rest_deg="0"), "theta_rest_deg"),
    "theta 90": (_set(GOOD, theta_rest_deg="90"), "theta_rest_deg"),
    "negative deadband": (_set(GOOD, deadband_Pa="-1"), "deadband_Pa"),
    "negative lock stiffness": (_set(GOOD, lock_stiffness_N_per_m="-5"), "lock_stiffness_N_per_m"),
    "bad tension_only": (_set(GOOD, tension_only="yes"), "tension_only"),
    "unknown law": (_set(GOOD, law="hyperelastic"), r"law.*hyperelastic.*known: linear, polynomial"),
    "E1 zero": (_set(GOOD, E1_Pa="0"), "E1_Pa"),
    "E2 negative": (_set(GOOD, E2="-0.5"), "E2"),
    "E4 not positive": (_set(GOOD, E4="0"), "E4"),
    "E3 negative (exp decay)": (_set(GOOD, E3_Pa="-1"), "E3_Pa"),
    "exponent E3 above 1": (_set(EXPONENT, E3="1.5"), "E3"),
    "exponent E4 below 1": (_set(EXPONENT, E4="0.9"), "E4"),
    "coefficient of another law": (_set(POLY, E4="2.0"), "'E4' is not a coefficient"),
    "Drucker-unstable polynomial": (_set(POLY, E3_Pa="-2e7", E4_Pa="0"), "Drucker.*E3_Pa"),
    "bladder too big for the sleeve": (_set(GOOD, bladder_volume_m3="1e-3"), "bladder_volume_m3"),
    # values each finite and signed right, that no muscle could have (the muscle-file reader refuses
    # them too): 170 m (mm written as m), a braid angle of 1 deg, a dead band of 1e30 Pa, E1 1e300
    "rest length in mm": (_set(GOOD, rest_length_m="170.18"), r"rest_length_m.*was it in mm"),
    "braid angle 1 deg": (_set(GOOD, theta_rest_deg="1"), r"theta_rest_deg.*2 \.\. 88 deg"),
    "braid angle 89 deg": (_set(GOOD, theta_rest_deg="89"), r"theta_rest_deg.*2 \.\. 88 deg"),
    "dead band 1e30 Pa": (_set(GOOD, deadband_Pa="1e30"), r"deadband_Pa.*never inflates"),
    "E1 1e300": (_set(GOOD, E1_Pa="1e300"), r"E1_Pa.*beyond 1e12"),
    "hexadecimal length": (_set(GOOD, rest_length_m="0x1p-3"), r"rest_length_m.*decimal number"),
    # as the muscle-file reader: an MPa modulus written as Pa, a lock stiffness beyond 1e9 N/m
    "E1 in MPa": (_set(GOOD, E1_Pa="1.479"), r"E1_Pa.*1e4 \.\. 5e7 Pa \(was it in MPa\?\)"),
    "lock stiffness 1e300": (
        _set(GOOD, lock_stiffness_N_per_m="1e300"),
        r"lock_stiffness_N_per_m.*0 \.\. 1e9",
    ),
    "bladder wall thinner than any": (_set(GOOD, bladder_volume_m3="1e-11"), r"bladder_volume_m3.*wall"),
    # 33.62 kPa written as Pa, and the exponent law's stiffening exponent of 700 (the paper's 1.35)
    "dead band in kPa written as Pa": (
        _set(GOOD, deadband_Pa="33.62"),
        r"'deadband_Pa' = 33\.62 is invalid: a dead band below 100 Pa.*was it in kPa\? Write 0",
    ),
    "exponent E4 700": (_set(EXPONENT, E4="700"), r"'E4' = 700 is invalid: cannot be physical.*1 \.\. 10"),
    "bladder misfit at rest": (
        _set(GOOD, bladder_volume_m3=repr(1.05 * _volume_filling_sleeve_at_rest(FAM1))),
        "bladder_volume_m3.*resting length",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_CONFIGS))
def test_bad_config_fails_compilation_naming_the_key(case):
    config, key_pattern = BAD_CONFIGS[case]
    with pytest.raises(ValueError, match=key_pattern):
        mujoco.MjModel.from_xml_string(model_xml(FAM1, config=config))


def test_plugin_bounds_are_the_muscle_files():
    """The plugin refuses what a muscle file refuses, at the same thresholds: just inside compiles,
    just outside does not (rest length, braid angle, dead band, stress coefficient)."""
    from efam_mujoco import musclefile

    lo, hi = musclefile.BRAID_ANGLE_DEG
    inside = {"theta_rest_deg": (lo, hi), "deadband_Pa": (0.0, 0.999 * musclefile.MAX_DEADBAND_PA)}
    outside = {"theta_rest_deg": (0.99 * lo, 1.001 * hi), "deadband_Pa": (musclefile.MAX_DEADBAND_PA,)}
    for key, values in inside.items():
        for value in values:
            config = _set(GOOD, **{key: repr(value)})
            if key == "theta_rest_deg":  # a braid angle moves the sleeve: keep the bladder inside it
                config = _set(config, bladder_volume_m3=repr(1e-6))
            mujoco.MjModel.from_xml_string(model_xml(FAM1, config=config))  # compiles
    for key, values in outside.items():
        for value in values:
            with pytest.raises(ValueError, match=key):
                mujoco.MjModel.from_xml_string(model_xml(FAM1, config=_set(GOOD, **{key: repr(value)})))
    assert musclefile.MAX_COEFFICIENT == 1e12 and musclefile.MIN_WALL_M == 1e-5  # the C constants' values


def test_python_model_rejects_the_same_unstable_polynomial():
    # the C check mirrors StressLaw.check_stable over Muscle.strain_range
    with pytest.raises(ValueError, match="Drucker"):
        load_muscle("FAM1").with_stress(StressLaw("polynomial", (2.367e6, 1.97, -2e7, 0.0)))


def test_polynomial_stable_over_strain_range_compiles():
    # an E3 that FAM1's E1 (2.4 MPa) cannot hold is stable again under a stiffer E1 (50 MPa, the
    # top of a bladder's plausible moduli): the check is a real threshold, not a blanket ban
    with pytest.raises(ValueError, match="Drucker"):
        mujoco.MjModel.from_xml_string(model_xml(FAM1, config=_set(POLY, E3_Pa="-6e6", E4_Pa="0")))
    muscle = load_muscle("FAM1").with_stress(StressLaw("polynomial", (5e7, 1.97, -6e6, 0.0)))
    mujoco.MjModel.from_xml_string(model_xml(muscle))


def test_unknown_config_key_is_rejected():
    with pytest.raises(ValueError, match="colour"):
        mujoco.MjModel.from_xml_string(model_xml(FAM1, config=_set(GOOD, colour="red")))


@pytest.mark.parametrize(
    "attrs, expected",
    [('dyntype="filterexact" dynprm="0.05" actdim="2"', "actdim"), ('dyntype="muscle"', "dyntype")],
)
def test_wrong_activation_setup_is_rejected(attrs, expected):
    with pytest.raises(ValueError, match=expected):
        mujoco.MjModel.from_xml_string(model_xml(FAM1, attrs))


@pytest.mark.parametrize("dyntype", ["filter", "filterexact"])
@pytest.mark.parametrize("tau", ["1e30", "61", "-0.05"])
def test_pressure_lag_beyond_any_valve_is_rejected(dyntype, tau):
    """A pressure lag's time constant (dynprm) of 1e30 s compiled: the muscle never filled."""
    with pytest.raises(
        ValueError,
        match=r"actuator 0: dynprm\[0\] = .* s, the pressure lag's time constant, must be in 0 \.\. 60 s",
    ):
        mujoco.MjModel.from_xml_string(model_xml(FAM1, f'dyntype="{dyntype}" dynprm="{tau}" actdim="1"'))
    mujoco.MjModel.from_xml_string(model_xml(FAM1, f'dyntype="{dyntype}" dynprm="60" actdim="1"'))  # compiles


def test_dead_band_below_100_Pa_is_refused_in_a_model_and_written_as_zero_from_a_fit():
    """0 (none) and a fit's numerical zero (below 1 Pa) compile; 1 .. 100 Pa typed in a model is
    a kPa value in Pa. The Python writer takes a muscle a fit built (diagnose's re-fit is bounded
    at 0 only): a dead band under 100 Pa, none a bench tells from 0, is written as 0 and compiles."""
    from dataclasses import replace

    for value in ("0", "0.5", "100"):
        mujoco.MjModel.from_xml_string(model_xml(FAM1, config=_set(GOOD, deadband_Pa=value)))
    for value in ("1", "99.9"):
        with pytest.raises(ValueError, match=r"deadband_Pa.*below 100 Pa"):
            mujoco.MjModel.from_xml_string(model_xml(FAM1, config=_set(GOOD, deadband_Pa=value)))
    config = plugin_config(replace(FAM1, deadband_Pa=33.62))
    assert float(config["deadband_Pa"]) == 0.0
    mujoco.MjModel.from_xml_string(model_xml(FAM1, config=_set(GOOD, deadband_Pa=config["deadband_Pa"])))
    assert float(plugin_config(replace(FAM1, deadband_Pa=150.0))["deadband_Pa"]) == 150.0


# ----------------------------------------------------------------------- threads and copies
def _rollout_setup(nbatch: int = 6, nstep: int = 300):
    muscle = load_muscle("FAM1")
    model, data = compile_muscle(muscle, 'dyntype="filterexact" dynprm="0.02" actdim="1"')
    rng = np.random.default_rng(7)
    state_size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    initial = np.zeros((nbatch, state_size))
    for i in range(nbatch):
        data.qpos[0] = rng.uniform(-0.03, 0.05)
        mujoco.mj_getState(model, data, initial[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    control = rng.uniform(0, 6e5, size=(nbatch, nstep, model.nu))
    return model, initial, control


def test_rollout_with_two_threads_equals_single_thread():
    model, initial, control = _rollout_setup()
    serial, _ = rollout.rollout(model, mujoco.MjData(model), initial, control)
    threaded, _ = rollout.rollout(model, [mujoco.MjData(model) for _ in range(2)], initial, control)
    assert np.all(np.isfinite(serial))
    assert np.ptp(serial[:, -1, 1]) > 0  # the muscles really moved the plates (qpos differs)
    np.testing.assert_array_equal(threaded, serial)


def test_python_threads_stepping_separate_data_agree():
    model, initial, control = _rollout_setup(nbatch=2, nstep=200)
    results = {}

    def run(i):
        data = mujoco.MjData(model)
        mujoco.mj_setState(model, data, initial[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        for u in control[i]:
            data.ctrl[:] = u
            mujoco.mj_step(model, data)
        results[i] = data.qpos.copy()

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in range(2):
        run_serial = mujoco.MjData(model)
        mujoco.mj_setState(model, run_serial, initial[i], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        for u in control[i]:
            run_serial.ctrl[:] = u
            mujoco.mj_step(model, run_serial)
        np.testing.assert_array_equal(results[i], run_serial.qpos)


def test_copied_data_outlives_its_source():
    muscle = load_muscle("FAM2")
    model, source = compile_muscle(muscle, 'dyntype="filterexact" dynprm="0.05" actdim="1"')
    source.ctrl[0] = 4e5
    for _ in range(50):
        mujoco.mj_step(model, source)
    target = mujoco.MjData(model)
    mujoco.mj_copyData(target, model, source)
    clone = copy.copy(source)
    del source
    gc.collect()
    for data in (target, clone):
        for _ in range(50):
            mujoco.mj_step(model, data)
    np.testing.assert_array_equal(target.qpos, clone.qpos)
    mujoco.mj_forward(model, target)
    assert target.actuator_force[0] == muscle.push(target.act[0], target.actuator_length[0])


def test_dm_control_physics():
    from dm_control import mujoco as dm_mujoco

    muscle = load_muscle("FAM1", law="polynomial")
    physics = dm_mujoco.Physics.from_xml_string(model_xml(muscle))
    physics.data.ctrl[:] = 3e5
    physics.step()
    physics.forward()
    length = physics.data.actuator_length[0]
    assert physics.data.actuator_force[0] == pytest.approx(muscle.push(3e5, length), rel=1e-12)
    twin = physics.copy(share_model=True)
    twin.step()
    assert np.isfinite(twin.data.qpos).all()


# --------------------------------------------------------------------------- pressure lag
@pytest.mark.parametrize("actearly", [False, True])
def test_filterexact_pressure_step_response(actearly):
    """A pressure step through dyntype=filterexact: P(t) = P_cmd (1 - exp(-t / tau))."""
    tau, command = 0.05, 5e5
    muscle = load_muscle("FAM1")
    attrs = f'dyntype="filterexact" dynprm="{tau}" actdim="1" actearly="{str(actearly).lower()}"'
    model, data = compile_muscle(muscle, attrs)
    data.qpos[0] = 0.02  # away from rest so both pressure and stress terms act
    data.ctrl[0] = command
    h = model.opt.timestep
    scale = abs(muscle.push(command, muscle.max_length_m))
    for step in range(1, 301):
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        t = data.time + (h if actearly else 0.0)  # actearly: the force uses the end-of-step pressure
        analytic = command * (1 - math.exp(-t / tau))
        assert data.act[0] == pytest.approx(command * (1 - math.exp(-data.time / tau)), rel=1e-9, abs=1e-6)
        expected = muscle.push(analytic, data.actuator_length[0])
        assert abs(data.actuator_force[0] - expected) <= 1e-6 * max(1.0, scale), step
    assert data.act[0] > 0.99 * command  # after 6 tau the pressure has arrived


# ------------------------------------------------------------------------------- the loader
def test_load_is_idempotent_and_thread_safe():
    paths = []
    threads = [threading.Thread(target=lambda: paths.append(efam_plugin.load())) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(set(paths)) == 1 and paths[0] == efam_plugin.library_path()
    assert efam_plugin.is_loaded() and efam_mujoco.plugin.is_loaded()


def test_plugin_config_round_trips_every_double():
    muscle = load_muscle("FAM2", law="exponent")
    config = plugin_config(muscle)
    assert float(config["rest_length_m"]) == muscle.rest_length_m
    assert float(config["theta_rest_deg"]) == muscle.theta_rest_deg  # derived, not a short decimal
    assert float(config["bladder_volume_m3"]) == muscle.bladder_volume_m3
    for key, value in muscle.stress.to_dict().items():
        assert float(config[key]) == value
    assert config["law"] == "exponent" and config["tension_only"] == "0"
    assert '<config key="E3" value=' in config_xml(muscle)


def test_missing_library_gives_a_clear_error(monkeypatch):
    monkeypatch.setattr(efam_plugin, "LIBRARY_FILE", "libefam_muscle_missing.so")
    with pytest.raises(PluginLoadError, match="pip install"):
        efam_plugin.library_path()
