"""Effect terms switched on inside the efam.muscle plugin (efam_effects.h) and the rig replay.

The reference is ``EffectModel.push_stepwise`` (itself held to the vectorised terms and to
analytic solutions in test_diagnose_effects.py); here MuJoCo replays synthetic bench recordings
(``diagnose.synth``: strokes out and back, holds, pressure steps, sensor noise) through the
stroke rig and must give the same load-cell force, sample by sample. Then: the state advances
once per mj_step (copies, extra mj_forward calls, RK4 stages, resets), the relaxation and
stick of the terms in MuJoCo against their analytic forms, bad configs rejected naming the key,
and the end to end case: diagnose a recording with a concealed effect, switch the named effects
on in the rig, and the MuJoCo replay reproduces the recording.
"""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest
from test_diagnose_effects import VALUES  # mid-range parameters of every effect

from efam_mujoco import load_muscle, rig
from efam_mujoco.diagnose import diagnose, synth
from efam_mujoco.diagnose import effects as E
from efam_mujoco.diagnose.report import effects_for_recording, rig_with_effects
from efam_mujoco.diagnose.report import plugin_config as diagnosis_config
from efam_mujoco.plugin import actuator_dynamics, instance_xml, plugin_config
from efam_mujoco.recordings import Recording

FORCE_EFFECTS = tuple(n for n in E.EFFECT_NAMES if n != "force_offset")

# mid-range values: each term moves the force by newtons on these recordings
SHORT = synth.Protocol(
    pressures_kPa=(103.4, 310.3), cycles=("slow",), repeat_first=False, settle_s=3.0, start_s=2.0, hold_s=2.0
)


@pytest.fixture(scope="module")
def bench():
    """A short bench recording (~4500 samples) of a randomised FAM1 and that truth muscle."""
    recording, truth = synth.synthesize(7, "none", SHORT, base="FAM1")
    rate = np.diff(recording.length_m) / np.diff(recording.time_s)
    # the premise: loading, unloading, holds and pressure steps are all in it
    assert np.sum(rate > 2e-3) > 200 and np.sum(rate < -2e-3) > 200 and np.sum(np.abs(rate) < 1e-3) > 500
    assert np.ptp(recording.pressure_Pa) > 250e3
    return recording, truth.muscle


def assert_same_force(simulated, reference):
    """1e-9 relative, with an absolute floor of 1e-9 of the largest force (near zero crossings)."""
    np.testing.assert_allclose(simulated, reference, rtol=1e-9, atol=1e-9 * np.max(np.abs(reference)))


def stepwise(muscle, effects, recording):
    model = E.EffectModel(muscle, effects)
    return model.push_stepwise(recording.time_s, recording.length_m, recording.pressure_Pa)


# ----------------------------------------------------------------- MuJoCo = push_stepwise
@pytest.mark.parametrize("name", E.EFFECT_NAMES)
def test_replay_in_mujoco_equals_the_per_sample_reference(bench, name):
    recording, muscle = bench
    effects = [(name, VALUES[name])]
    simulated = rig.replay(recording, muscle, effects)
    reference = stepwise(muscle, effects, recording)
    base = muscle.push(recording.pressure_Pa, recording.length_m)
    assert np.max(np.abs(reference - base)) > 0.5  # the term does something here (N)
    assert np.max(np.abs(rig.replay(recording, muscle) - base)) < 1e-9 * np.max(np.abs(base))
    assert_same_force(simulated, reference)


def test_a_transport_delay_rides_on_mujocos_ctrl_delay(bench):
    # pressure_lag with a line delay: MuJoCo's own ctrl delay (interp linear, history filled with
    # the first sample) and filterexact lag in the rig; the plugin equals the per-sample reference
    # and the vectorised one, alone and with another effect reading the transducer's pressure
    recording, muscle = bench
    lag = {"tau_s": 0.06, "delay_s": 0.045}
    for effects in ([("pressure_lag", lag)], [("pressure_lag", lag), ("friction", VALUES["friction"])]):
        reference = stepwise(muscle, effects, recording)
        vectorised = E.EffectModel(muscle, effects).push_recording(recording)
        without_delay = stepwise(muscle, [("pressure_lag", {"tau_s": 0.06})] + effects[1:], recording)
        assert np.max(np.abs(reference - without_delay)) > 1.0  # the delay does something here (N)
        assert_same_force(rig.replay(recording, muscle, effects), reference)
        assert_same_force(vectorised, reference)


def test_a_delayed_lag_of_a_pressure_step_starts_after_the_delay():
    # at constant length (no gas-volume term) the internal pressure after a step at t0 is the
    # supply's delayed by d, then a first-order fill: flat until t0 + d, then
    # 1 - exp(-(t - t0 - d) / tau) of the step (the sample grid holds t0 + d exactly)
    t = np.arange(0.0, 2.0, 0.002)
    L = np.full(len(t), FAM1.rest_length_m)
    P = np.where(t >= 0.5 - 1e-9, 300e3, 100e3)
    tau, d = 0.1, 0.08
    model = E.EffectModel(FAM1, [("pressure_lag", {"tau_s": tau, "delay_s": d})])
    force = model.push(t, L, P)
    k0 = int(np.flatnonzero(t >= 0.5 + d - 1e-9)[0])  # the first sample the line has the step
    after = np.arange(k0, len(t))
    P_i = 300e3 - 200e3 * np.exp(-(t[after] - t[k0] + 0.002) / tau)  # the lag includes its sample
    np.testing.assert_allclose(force[after], FAM1.push(P_i, L[after]), rtol=1e-9)
    before = t < 0.5 + d - 1e-9
    np.testing.assert_allclose(force[before], FAM1.push(100e3, L[before]), rtol=1e-12)
    assert_same_force(rig.replay(Recording(t, L, P, force), FAM1, model.effects), force)


def test_a_delay_the_actuator_does_not_have_is_refused_and_old_files_load():
    lag = {"tau_s": 0.2, "delay_s": 0.05}
    config = plugin_config(FAM1, [("pressure_lag", lag)])
    with pytest.raises(
        ValueError, match=r"'pressure_lag.delay_s' = 0.05 needs the actuator's own ctrl delay"
    ):
        mujoco.MjModel.from_xml_string(one_muscle(config, LAG))  # filterexact without the delay
    mujoco.MjModel.from_xml_string(one_muscle(config, actuator_dynamics([("pressure_lag", lag)])))
    # a file written before the keys existed: no delay and the whole gas-volume term, the same
    # model as before
    old = {k: v for k, v in config.items() if k not in ("pressure_lag.delay_s", "pressure_lag.volume_gain")}
    old["pressure_lag.tau_s"] = "0.2"
    mujoco.MjModel.from_xml_string(one_muscle(old, LAG))
    assert E.check_values("pressure_lag", {"tau_s": 0.2}) == {
        "tau_s": 0.2,
        "delay_s": 0.0,
        "volume_gain": 1.0,
    }


def test_all_effects_at_once_on_a_tension_only_muscle(bench):
    # a tension-only muscle carries no effect force while the model calls it slack; with
    # pressure_lag on, "slack" is judged at the measured pressure, as in effects.py
    recording, muscle = bench
    muscle = replace(muscle, tension_only=True)
    effects = list(VALUES.items())
    reference = stepwise(muscle, effects, recording)
    base = muscle.push(recording.pressure_Pa, recording.length_m)
    assert 0.1 < np.mean(base == 0) < 0.9  # both slack and taut samples
    assert np.max(np.abs(reference - base)) > 1.0
    assert_same_force(rig.replay(recording, muscle, effects), reference)


def test_irregular_sampling_steps_by_each_interval():
    # each mj_step lasts the interval since the previous sample: the plugin's states and MuJoCo's
    # filterexact lag integrate over the same dt as the reference
    muscle = load_muscle("FAM1")
    rng = np.random.default_rng(3)
    n = 700
    t = np.cumsum(rng.uniform(0.02, 0.08, n))
    L = muscle.rest_length_m * (1 + 0.6 * np.clip(np.sin(np.linspace(-0.6, 2 * np.pi, n)), 0, None))
    P = np.minimum(t / 3.0, 1.0) * 300e3 + 5e3 * np.sin(7 * t)
    recording = Recording(t, L, P, np.zeros(n))
    effects = [(k, VALUES[k]) for k in ("viscoelasticity", "drift", "pressure_lag")]
    assert_same_force(rig.replay(recording, muscle, effects), stepwise(muscle, effects, recording))


def shared_instance_xml(muscle, effects, n):
    """n muscles on mocap plates side by side, all driven by one plugin instance (batched)."""
    L0 = muscle.rest_length_m
    world = "".join(
        f'<site name="base{j}" pos="{0.1 * j} 0 0"/><body name="plate{j}" mocap="true" pos="{0.1 * j} 0 {L0!r}">'
        f'<site name="end{j}"/></body>'
        for j in range(n)
    )
    tendons = "".join(
        f'<spatial name="t{j}"><site site="base{j}"/><site site="end{j}"/></spatial>' for j in range(n)
    )
    dynamics = actuator_dynamics(effects)
    actuators = "".join(
        f'<plugin instance="fx" tendon="t{j}" ctrllimited="true" ctrlrange="-101325 1e6"{dynamics}/>'
        for j in range(n)
    )
    return f"""<mujoco><option integrator="implicitfast"/>
  <extension><plugin plugin="efam.muscle">{instance_xml("fx", muscle, effects=effects)}</plugin></extension>
  <worldbody>{world}</worldbody><tendon>{tendons}</tendon><actuator>{actuators}</actuator></mujoco>"""


def test_one_instance_driving_several_actuators_keeps_a_state_per_actuator(bench):
    # 5 actuators: the plugin's batched path; each sees a different part of the recording
    recording, muscle = bench
    n, count = 5, 1500
    effects = [(k, VALUES[k]) for k in ("friction", "viscoelasticity", "softening", "pressure_lag")]
    model = mujoco.MjModel.from_xml_string(shared_instance_xml(muscle, effects, n))
    data = mujoco.MjData(model)
    t = recording.time_s[:count] - recording.time_s[0]
    parts = [np.roll(np.arange(len(recording)), -600 * j)[:count] for j in range(n)]
    L = np.array([recording.length_m[p] for p in parts])
    P = np.array([recording.pressure_Pa[p] for p in parts])
    data.act[:] = P[:, 0]
    forces = np.empty((n, count))
    for k in range(count):
        if k:
            model.opt.timestep = t[k] - t[k - 1]
        data.time = t[k]
        data.mocap_pos[:, 2] = L[:, k]
        data.ctrl[:] = P[:, k]
        mujoco.mj_step(model, data)
        forces[:, k] = data.actuator_force
    for j in range(n):
        reference = E.EffectModel(muscle, effects).push_stepwise(t, L[j], P[j])
        assert_same_force(forces[j], reference)


# ------------------------------------------------------------ the terms' physics in MuJoCo
def test_maxwell_branch_relaxes_exponentially_and_friction_sticks_during_a_hold():
    # stretch at constant pressure, then hold: the viscoelastic force decays as exp(-t/tau), the
    # friction force stays at -(f0 + f1 P) (it opposes the lengthening that came before), or
    # decays as exp(-r t) where the contact relaxes at rate r
    muscle = load_muscle("FAM1")
    t = np.arange(0.0, 12.0, 0.01)
    L = muscle.rest_length_m * (1 + np.minimum(t, 2.0) * 0.1)
    P = np.full(len(t), 200e3)
    recording = Recording(t, L, P, np.zeros(len(t)))
    base = muscle.push(P, L)
    visco = dict(k0_N=300.0, k1_N_per_MPa=0.0, tau_s=1.5)
    dF = rig.replay(recording, muscle, [("viscoelasticity", visco)]) - base
    hold = np.flatnonzero(t >= 2.0)
    ratio = dF[hold] / dF[hold[0]]
    np.testing.assert_allclose(ratio, np.exp(-(t[hold] - t[hold[0]]) / 1.5), rtol=1e-9)
    friction = dict(VALUES["friction"], relax_per_s=0.0)
    dF = rig.replay(recording, muscle, [("friction", friction)]) - base
    expected = -(friction["f0_N"] + friction["f1_N_per_MPa"] * 0.2)
    np.testing.assert_allclose(dF[hold], expected, rtol=1e-9)
    relaxing = dict(friction, relax_per_s=0.3)
    dF = rig.replay(recording, muscle, [("friction", relaxing)]) - base
    np.testing.assert_allclose(dF[hold], expected * np.exp(-0.3 * (t[hold] - t[hold[0]])), rtol=1e-9)


def test_bladder_branches_relax_a_pressure_step_at_a_fixed_length():
    # isometric: the strain branch sees nothing, the bladder branches take g and g_slow of the
    # change of the bladder's share of Eq. 2 (the tension less its pressure term, written out
    # here from the paper) and let them decay as a two-term Prony series, exp(-t/tau) and
    # exp(-t/(20 tau))
    muscle = load_muscle("FAM1")
    t = np.arange(0.0, 10.0, 0.01)
    L = np.full(len(t), 1.3 * muscle.rest_length_m)
    P = np.where(t < 2.0, 150e3, 350e3)
    recording = Recording(t, L, P, np.zeros(len(t)))
    base = muscle.push(P, L)
    visco = dict(k0_N=300.0, k1_N_per_MPa=100.0, g_bladder=0.25, tau_s=1.5, g_slow_bladder=0.1)
    dF = rig.replay(recording, muscle, [("viscoelasticity", visco)]) - base

    def bladder_push(p):
        pressure_term = (
            (p - muscle.deadband_Pa)
            / (4 * math.pi * muscle.turns**2)
            * (3 * L[0] ** 2 - muscle.thread_length_m**2)
        )
        return -(float(muscle.tension(p, L[0])) - pressure_term)

    np.testing.assert_allclose(dF[t < 2.0], 0.0, atol=1e-9)
    hold = np.flatnonzero(t >= 2.0)
    change = bladder_push(350e3) - bladder_push(150e3)
    assert abs(change) > 4.0  # the step changes the bladder's force by newtons
    since = t[hold] - t[hold[0] - 1]
    expected = change * (0.25 * np.exp(-since / 1.5) + 0.1 * np.exp(-since / 30.0))
    np.testing.assert_allclose(dF[hold], expected, rtol=1e-9)


@pytest.mark.parametrize("clock, course", [(1.0, 1.0), (1.0, -1.0), (0.0, -1.0), (1.0, 0.0), (0.0, 0.0)])
def test_drift_on_every_clock_and_course_replays_as_the_reference(bench, clock, course):
    recording, muscle = bench
    effects = [("drift", dict(VALUES["drift"], clock=clock, course=course))]
    reference = stepwise(muscle, effects, recording)
    base = muscle.push(recording.pressure_Pa, recording.length_m)
    assert np.max(np.abs(reference - base)) > 0.05  # the term does something here (N)
    assert_same_force(rig.replay(recording, muscle, effects), reference)


def test_smooth_friction_replays_as_the_reference(bench):
    recording, muscle = bench
    for relax in (0.0, 0.05):
        effects = [("friction", dict(VALUES["friction"], relax_per_s=relax, smooth=1.0))]
        reference = stepwise(muscle, effects, recording)
        sharp = stepwise(muscle, [("friction", dict(effects[0][1], smooth=0.0))], recording)
        assert np.max(np.abs(reference - sharp)) > 0.05  # the rounded corner differs here (N)
        assert_same_force(rig.replay(recording, muscle, effects), reference)


# ------------------------------------------------------- the state advances once per step
STATEFUL = [(k, VALUES[k]) for k in ("friction", "viscoelasticity", "softening", "drift", "pressure_lag")]


def test_mj_copydata_mid_replay_continues_identically(bench):
    recording, muscle = bench
    half = len(recording) // 2
    model, data = rig.replay_rig(recording, muscle, STATEFUL)
    first = rig.drive(model, data, recording, range(half))
    copy = mujoco.MjData(model)
    mujoco.mj_copyData(copy, model, data)
    rest_original = rig.drive(model, data, recording, range(half, len(recording)))
    rest_copy = rig.drive(model, copy, recording, range(half, len(recording)))
    np.testing.assert_array_equal(rest_copy, rest_original)
    np.testing.assert_array_equal(np.r_[first, rest_original], rig.replay(recording, muscle, STATEFUL))


def test_extra_forward_calls_do_not_change_the_trajectory(bench):
    # a viewer or a sensor read calls mj_forward between steps, even with other inputs set
    recording, muscle = bench
    plain = rig.replay(recording, muscle, STATEFUL)
    model, data = rig.replay_rig(recording, muscle, STATEFUL)
    probed = np.empty(len(recording))
    for k in range(len(recording)):
        data.mocap_pos[0, 2] = 1.1 * recording.length_m[k]
        data.ctrl[0] = recording.pressure_Pa[k] + 5e4
        mujoco.mj_forward(model, data)
        committed = data.plugin_state[: (model.npluginstate - 2) // 2].copy()
        mujoco.mj_forward(model, data)
        assert np.array_equal(data.plugin_state[: len(committed)], committed)  # forward never commits
        probed[k] = rig.drive(model, data, recording, range(k, k + 1))[0]
    np.testing.assert_array_equal(probed, plain)


def test_rk4_stages_do_not_advance_the_state(bench):
    recording, muscle = bench
    effects = [e for e in STATEFUL if e[0] != "pressure_lag"]  # RK4 integrates a filter differently
    model, data = rig.replay_rig(recording, muscle, effects)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    np.testing.assert_array_equal(rig.drive(model, data, recording), rig.replay(recording, muscle, effects))


def test_reset_starts_the_effects_afresh(bench):
    recording, muscle = bench
    model, data = rig.replay_rig(recording, muscle, STATEFUL)
    first = rig.drive(model, data, recording)
    mujoco.mj_resetData(model, data)
    assert not np.any(data.plugin_state)
    data.act[:] = recording.pressure_Pa[0]
    np.testing.assert_array_equal(rig.drive(model, data, recording), first)


def test_no_effects_no_state():
    model, _ = rig.build_rig(load_muscle("FAM1"), rig.RigOptions(mode="stroke"))
    assert model.npluginstate == 0


# ------------------------------------------------------------------------------ bad configs
FAM1 = load_muscle("FAM1")


def one_muscle(config: dict[str, str], dynamics: str = "") -> str:
    lines = "".join(f'<config key="{k}" value="{v}"/>' for k, v in config.items())
    return f"""<mujoco><extension><plugin plugin="efam.muscle"/></extension>
  <worldbody><site name="a"/><body name="plate" mocap="true" pos="0 0 {FAM1.rest_length_m!r}"><site name="b"/></body>
  </worldbody><tendon><spatial name="t"><site site="a"/><site site="b"/></spatial></tendon>
  <actuator><plugin name="m1" plugin="efam.muscle" tendon="t"{dynamics}>{lines}</plugin></actuator></mujoco>"""


def with_effects(*names, **overrides) -> dict[str, str]:
    config = plugin_config(FAM1, [(n, VALUES[n]) for n in names])
    for key, value in overrides.items():
        key = key.replace("__", ".")
        if value is None:
            config.pop(key)
        else:
            config[key] = value
    return config


LAG = actuator_dynamics([("pressure_lag", VALUES["pressure_lag"])])
BAD = {
    "unknown effect": (with_effects("friction", effects="friction,stiction"), "'effects': unknown effect 'stiction'"),
    "force_offset is a sensor error": (with_effects("drift", effects="drift,force_offset"), "'force_offset' is a load-cell"),
    "named twice": (with_effects("drift", effects="drift, drift"), "'drift' is named twice"),
    "empty name": (with_effects("drift", effects="drift,,"), "'effects' = 'drift,,' has an empty name"),
    "missing parameter": (with_effects("viscoelasticity", viscoelasticity__tau_s=None), "missing config key 'viscoelasticity.tau_s'"),
    "not a number": (with_effects("friction", friction__f0_N="2 N"), "'friction.f0_N' must be a finite number"),
    "nan": (with_effects("softening", softening__a="nan"), "'softening.a' must be a finite number"),
    "parameter of an effect not on": (with_effects("friction", drift__tau_s="300"), "'drift.tau_s' is given but effect 'drift' is not"),
    "a mode between its values": (with_effects("drift", drift__clock="0.5"), "'drift.clock' = 0.5 is not one of 0, 1"),
    "a course between its modes": (with_effects("drift", drift__course="-0.5"), "'drift.course' = -0.5 is not one of -1, 0, 1"),
    "a corner between sharp and smooth": (with_effects("friction", friction__smooth="0.3"), "'friction.smooth' = 0.3 is not one of 0, 1"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_effect_config_fails_compilation_naming_the_key(case):
    config, message = BAD[case]
    with pytest.raises(ValueError, match=message):
        mujoco.MjModel.from_xml_string(one_muscle(config))


@pytest.mark.parametrize(
    "dynamics",
    ["", ' dyntype="filter" dynprm="0.2" actdim="1"', ' dyntype="filterexact" dynprm="0.3" actdim="1"'],
)
def test_pressure_lag_needs_the_actuators_own_lag_with_its_time_constant(dynamics):
    with pytest.raises(
        ValueError, match=r"'pressure_lag.tau_s' = 0.2 needs the actuator's own lag.*filterexact"
    ):
        mujoco.MjModel.from_xml_string(one_muscle(with_effects("pressure_lag"), dynamics))
    mujoco.MjModel.from_xml_string(one_muscle(with_effects("pressure_lag"), LAG))


@pytest.mark.parametrize("name", FORCE_EFFECTS)
def test_the_plugin_takes_exactly_the_librarys_parameters_and_bounds(name):
    # at each bound accepted, one double beyond it rejected naming the key: the C table is the
    # Python library's (keys and bounds)
    for p in E.get(name).params:
        key = f"{name}.{p.key}"
        for value, ok in (
            (p.lo, True),
            (p.hi, True),
            (np.nextafter(p.lo, -np.inf), False),
            (np.nextafter(p.hi, np.inf), False),
        ):
            config = with_effects(name, **{key.replace(".", "__"): repr(float(value))})
            # pressure_lag rides on the actuator's own lag and ctrl delay: written from the values
            values = dict(VALUES[name], **{p.key: float(value)})
            dynamics = actuator_dynamics([(name, values)]) if name == "pressure_lag" else ""
            xml = one_muscle(config, dynamics)
            if ok:
                mujoco.MjModel.from_xml_string(xml)
            else:
                with pytest.raises(ValueError, match=rf"config key '{key}' = .* is outside \["):
                    mujoco.MjModel.from_xml_string(xml)
            # and the Python side agrees
            if ok:
                plugin_config(FAM1, [(name, values)])
            else:
                with pytest.raises(ValueError, match=f"'{p.key}' = .* is outside"):
                    plugin_config(FAM1, [(name, values)])  # fmt: skip


def test_keys_round_trip_and_force_offset_stays_with_the_load_cell():
    effects = [
        ("friction", VALUES["friction"]),
        ("force_offset", dict(offset_N=2.5, offset_N_by_recording=[2.5])),
    ]
    config = plugin_config(FAM1, effects)
    assert config["effects"] == "friction"
    assert {k for k in config if k.startswith("friction.")} == {f"friction.{k}" for k in VALUES["friction"]}
    assert all(float(config[f"friction.{k}"]) == v for k, v in VALUES["friction"].items())
    assert not any("offset" in k for k in config)
    model, data = rig.build_rig(FAM1, rig.RigOptions(mode="stroke", effects=effects))
    data.ctrl[0] = 0.0
    mujoco.mj_forward(model, data)
    assert rig.load_cell_N(model, data) == pytest.approx(2.5 + float(data.actuator_force[0]), abs=1e-12)


def test_two_lags_on_one_actuator_are_refused():
    with pytest.raises(ValueError, match="one first-order lag"):
        rig.RigOptions(mode="stroke", pressure_lag_s=0.05, effects=[("pressure_lag", dict(tau_s=0.2))])


# ---------------------------------------------------------------------------- end to end
def test_diagnosed_effects_switched_on_make_the_mujoco_rig_reproduce_the_recording(tmp_path):
    # a recording with a concealed Dahl friction (not the library's play operator), diagnosed
    # blind; the named effects switched on in the rig; MuJoCo replays the recording
    protocol = synth.Protocol(pressures_kPa=(103.4, 310.3, 517.1), cycles=("slow", "fast"))
    recording, truth = synth.synthesize(11, "friction", protocol, base="FAM1")
    d = diagnose(recording, load_muscle("FAM1"))
    assert d.names[0] == "friction"
    effects = effects_for_recording(d, 0)
    rms = lambda r: float(np.sqrt(np.mean(r**2)))  # noqa: E731
    without = rms(recording.force_N - rig.replay(recording, d.muscle_before))
    switched_on = rig.replay(recording, d.muscle_after, effects)
    with_effects_rms = rms(recording.force_N - switched_on)
    # the replays are the diagnosis's own before/after models (2.09 N -> 0.75 N, noise 0.64 N)
    assert without == pytest.approx(d.rms_before_N, rel=1e-9)
    assert with_effects_rms == pytest.approx(d.rms_after_N, rel=1e-9)
    assert_same_force(switched_on, d.predicted_after)
    assert with_effects_rms < 0.45 * without
    assert with_effects_rms < 1.3 * truth.noise_N
    # the model file the report writes is that rig
    path = tmp_path / "rig_with_effects.xml"
    path.write_text(rig_with_effects(d))
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    data.act[:] = recording.pressure_Pa[0] if model.na else 0.0
    min_pressure = model.actuator_ctrlrange[0, 0]
    clipped = replace(recording, pressure_Pa=np.maximum(recording.pressure_Pa, min_pressure))
    np.testing.assert_allclose(
        rig.drive(model, data, clipped), rig.replay(clipped, d.muscle_after, effects), rtol=1e-12, atol=1e-9
    )
    assert diagnosis_config(d)["effects"] == ",".join(n for n in d.names if n != "force_offset")
