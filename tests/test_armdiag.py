"""efam diagnose-arm: file formats, replay against plain MuJoCo stepping, and blind diagnoses."""

from __future__ import annotations

import json
from dataclasses import fields, replace

import mujoco
import numpy as np
import pytest

from efam_mujoco import arm
from efam_mujoco.armdiag import (
    ArmModelError,
    ArmRecording,
    ArmRecordingError,
    diagnose_arm,
    load_arm_model,
    read_csv,
    save_spec,
    write_csv,
)
from efam_mujoco.armdiag.replay import Replayer, with_values
from efam_mujoco.armdiag.report import write_model
from efam_mujoco.armdiag.specfile import spec_from_dict, spec_to_dict
from efam_mujoco.armdiag.synth import Truth, make_recording
from efam_mujoco.cli import main as efam

DT = 4e-3  # stable for the 2-disk arm at its nominal damping (the segments' axial mode ~2600 rad/s)
DISKS = 2  # few disks keep the tests fast (the physics needs no more: the diagnosis is self-consistent)


def small_arm(**kw) -> arm.ArmSpec:
    return arm.ArmSpec(sections=(arm.paper_section(disks=DISKS),), timestep_s=DT, name="arm_1x3", **kw)


@pytest.fixture(scope="module")
def spec():
    return arm.build_spec(small_arm())


def test_spec_json_round_trip_and_errors(tmp_path):
    two = arm.ArmSpec(sections=(arm.paper_section(disks=2, muscle="FAM2"),) * 2, orientation="hanging")
    back = spec_from_dict(json.loads(json.dumps(spec_to_dict(two))))
    assert replace(back, sections=two.sections) == two
    for a, b in zip(back.sections, two.sections):
        assert replace(a, muscles=b.muscles) == b
        for ma, mb in zip(a.muscles, b.muscles):  # muscle files store derived constants: last-bit rounding
            for f in fields(mb):
                va, vb = getattr(ma, f.name), getattr(mb, f.name)
                assert va == (pytest.approx(vb, rel=1e-12) if isinstance(vb, float) else vb), f.name
    path = save_spec(tmp_path / "arm.json", two)
    assert len(load_arm_model(path).actuators) == 6
    doc = spec_to_dict(two)
    doc["payload_kilo"] = 1
    with pytest.raises(ArmModelError, match="payload_kilo"):
        spec_from_dict(doc)
    doc = spec_to_dict(two)
    doc["sections"][1]["radius_m"] = -1
    with pytest.raises(ArmModelError, match=r"sections\[1\].*radius_m"):
        spec_from_dict(doc)
    (tmp_path / "bad.json").write_text('{"format": "efam_mujoco.arm_spec/1",\n "sections": [}')
    with pytest.raises(ArmModelError, match="line 2, column"):
        load_arm_model(tmp_path / "bad.json")


def _csv(tmp_path, text):
    path = tmp_path / "rec.csv"
    path.write_text(text)
    return path


MUSCLES = ["s1m1", "s1m2", "s1m3"]
HEAD = "time_s,p_s1m1_kPa,p_s1m2_kPa,p_s1m3_kPa,tip_x_mm,tip_y_mm,tip_z_mm\n"


def test_reader_units_dropouts_and_round_trip(tmp_path):
    rec = read_csv(
        _csv(tmp_path, HEAD + "0,100,100,100,1,2,200\n0.01,1,2,3,,,\n0.02,0.5,0,0,1,2,201\n"), MUSCLES
    )
    assert rec.command_Pa[0, 0] == pytest.approx(1e5) and rec.tip_m[2, 2] == pytest.approx(0.201)
    assert (
        np.isnan(rec.tip_m[1]).all() and rec.meta["dropouts"] == 1 and list(rec.valid) == [True, False, True]
    )
    again = read_csv(write_csv(tmp_path / "out.csv", rec), MUSCLES)
    np.testing.assert_allclose(again.command_Pa, rec.command_Pa)
    np.testing.assert_allclose(again.tip_m, rec.tip_m)


@pytest.mark.parametrize(
    "text, message",
    [
        (
            HEAD.replace("p_s1m3_kPa", "p_s1m9_kPa") + "0,1,1,1,0,0,0\n",
            r"line 1, column 4 \('p_s1m9_kPa'\): no muscle",
        ),
        (HEAD.replace(",p_s1m3_kPa", "") + "0,1,1,0,0,0\n", "missing column.*p_s1m3_kPa"),
        (
            HEAD.replace("tip_z_mm", "tip_z_furlong") + "0,1,1,1,0,0,0\n",
            "column 7.*unknown length unit 'furlong'",
        ),
        (HEAD + "0,1,1,1,0,0,0\n0.1,1,x,1,0,0,0\n", r"line 3, column 3 \('p_s1m2_kPa'\): not a number"),
        (HEAD + "0,1,1,1,0,0,0\n0.1,1,-5,1,0,0,0\n", "line 3, column 3.*negative gauge pressure"),
        (HEAD + "0,1,1,1,0,0,0\n0,1,1,1,0,0,0\n", "line 3, column 1.*time not increasing"),
        (HEAD + "0,1,1,1,0,0,0\n0.1,1,1,0,0,0\n", "line 3: 6 fields"),
        (HEAD + "0,1,1,1,0,0,0\n0.1,1,,1,0,0,0\n", "line 3, column 3.*empty value"),
        ("time_s,foo_m\n", "unknown column"),
        (
            HEAD.rstrip("\n") + ",p_s1m1_psi\n0,1,1,1,0,0,0,1\n",
            r"line 1, columns 2 \('p_s1m1_kPa'\) and 8 \('p_s1m1_psi'\) give the same quantity; keep one",
        ),
        (
            HEAD + "0,0,0,0,0,0,200\n0.1,0,0.0,0e3,1,0,201\n",
            r"every command column \(p_s1m1_kPa, p_s1m2_kPa, p_s1m3_kPa\) is 0 in every row: nothing drives",
        ),
    ],
)
def test_reader_names_file_line_and_column(tmp_path, text, message):
    with pytest.raises(ArmRecordingError, match=message) as err:
        read_csv(_csv(tmp_path, text), MUSCLES)
    assert "rec.csv" in str(err.value)


def test_reader_shows_a_file_name_with_control_characters_escaped(tmp_path):
    path = tmp_path / "arm\x1b]0;title\x07.csv"
    path.write_text(HEAD + "0,1,1,1,0,0,0\n")
    with pytest.raises(ArmRecordingError, match=r"arm\\x1b\]0;title\\x07\.csv: fewer than 2") as err:
        read_csv(path, MUSCLES)
    assert "\x1b" not in str(err.value) and "\x07" not in str(err.value)


def test_replay_matches_plain_stepping(spec):
    """The batched replay (rollout, command map, settle) equals mj_step by hand on the builder's model."""
    t = np.arange(0, 2.0, 0.02)
    cmd = np.column_stack([150e3 + 100e3 * np.sin(2 * np.pi * 0.7 * t + ph) for ph in (0, 2, 4)])
    replayer = Replayer(spec, t, cmd)
    tip = replayer.tips([replayer.nominal])[0]
    model = arm.build_model(small_arm())
    data = mujoco.MjData(model)
    data.act[:] = cmd[0]
    ref = []
    n_settle = int(round(replayer.settle_s / DT))
    for k in range(-n_settle, int(round(t[-1] / DT)) + 1):
        data.ctrl[:] = cmd[max(0, np.searchsorted(t, k * DT + 1e-9, side="right") - 1)]
        mujoco.mj_forward(model, data)
        if k >= 0 and np.isclose(k * DT, t, atol=1e-9).any():
            ref.append(data.site("tip").xpos.copy())
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(tip, np.array(ref), atol=1e-9)


def test_payload_knob_matches_the_builders_payload(spec):
    """Static tip under the library's payload edit = the builder's own payload_kg option (equal
    pressures: the arm stays straight, so where along the axis the mass sits does not matter)."""
    t = np.arange(0, 6.0, 0.05)
    cmd = np.tile([250e3, 250e3, 250e3], (len(t), 1))
    replayer = Replayer(spec, t, cmd)
    tip = replayer.tips([with_values(replayer.nominal, payload_kg=0.2)])[0][-1]
    model = arm.build_model(small_arm(payload_kg=0.2))
    data = mujoco.MjData(model)
    arm.settle(model, data, cmd[0], t_max_s=12.0)
    free = Replayer(spec, t, cmd).tips([replayer.nominal])[0][-1]
    assert free[2] - tip[2] > 5e-4  # the payload compresses the arm (0.8 mm)....
    assert np.linalg.norm(tip - data.site("tip").xpos) < 2e-5  # ...as the builder's payload does


@pytest.fixture(scope="module")
def weak_case(spec):
    rng = np.random.default_rng(5)
    truth = Truth("weak_muscle", {"leak_sqrt_Pa": 130.0}, "s1m2")  # an orifice leak, ~25 % at mid-range
    rec = make_recording(spec, truth, "steps", rng, duration_s=12.0, rate_Hz=60.0, noise_m=5e-4)
    return rec, diagnose_arm(spec, rec, threads=1)


def test_blind_weak_muscle_named_with_its_muscle(weak_case):
    rec, d = weak_case
    assert d.verdict["answer"] == "weak_muscle" and d.effects[0]["muscle"] == "s1m2"
    assert d.heldout_rms_after_m < 0.5 * d.heldout_rms_nominal_m
    keys = {"effects", "rms_before_m", "heldout_rms_before_m", "heldout_rms_after_m", "noise_m", "located",
            "candidates", "decisions", "refit", "probabilities", "verdict", "next_experiment"}  # fmt: skip
    assert keys <= set(d.to_json()) and "muscle" in d.to_json()["effects"][0]
    json.dumps(d.to_json())


def test_identified_mjcf_reproduces_the_diagnosis(tmp_path, spec, weak_case):
    rec, d = weak_case
    path = write_model(tmp_path / "identified.xml", spec, d)
    replayer = Replayer(mujoco.MjSpec.from_file(str(path)), rec.time_s, rec.command_Pa)
    # MJCF stores ~7 significant digits (the builder's masses and damping): micrometres, << noise
    np.testing.assert_allclose(replayer.tips([replayer.nominal])[0], d.tip_after, atol=2e-5)


def test_clean_recording_is_no_alarm(spec):
    rng = np.random.default_rng(8)
    rec = make_recording(spec, Truth("none"), "sinusoids", rng, duration_s=10.0, rate_Hz=50.0, noise_m=5e-4)
    d = diagnose_arm(spec, rec, threads=1, effects=("payload", "mount_tilt", "weak_muscle"))
    assert d.verdict["answer"] == "none" and not d.effects


def test_cli_diagnose_arm(tmp_path, capsys):
    model = save_spec(tmp_path / "arm.json", small_arm())
    spec = load_arm_model(model)
    rng = np.random.default_rng(3)
    rec = make_recording(spec, Truth("none"), "ramps", rng, duration_s=6.0, rate_Hz=40.0, noise_m=5e-4)
    csv = write_csv(tmp_path / "rec.csv", ArmRecording(rec.time_s, rec.muscles, rec.command_Pa, rec.tip_m))
    assert efam(["diagnose-arm", str(csv), "--model", str(model), "--report", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert doc["verdict"]["answer"] in doc["probabilities"]
    assert (tmp_path / "out" / "arm_identified.xml").exists()
    bad = tmp_path / "bad.csv"
    bad.write_text(csv.read_text().replace("p_s1m1_kPa", "p_s1m1_kPaa"))
    assert efam(["diagnose-arm", str(bad), "--model", str(model)]) == 2
    assert "line 1, column 2" in capsys.readouterr().err


def test_written_model_keeps_every_term(tmp_path, spec):
    """Each library term written into an MJCF and read back replays exactly as the in-memory variant."""
    t = np.arange(0, 3.0, 0.02)
    cmd = np.column_stack([150e3 + 100e3 * np.sin(2 * np.pi * 0.7 * t + ph) for ph in (0, 2, 4)])
    replayer = Replayer(spec, t, cmd)
    k = with_values(
        replayer.nominal, payload_kg=0.08, tilt_rad=(0.05, -0.03), mount_stiffness_N_m_per_rad=80.0,
        mount_damping_N_m_s_per_rad=0.4, friction_N=3.0, cross_talk=0.2, gain=[1.0, 0.8, 1.0],
        offset_Pa=[0.0, 5e3, 0.0], damping_bend=2.0, lag_s=[0.05, 0.2, 0.05], coupling=((1, 2, 0.3),),
        medium_viscosity_Pa_s=0.5,
    )  # fmt: skip
    path = tmp_path / "all.xml"
    written = replayer.model_with(k)
    written.compile()
    path.write_text(written.to_xml())
    again = Replayer(mujoco.MjSpec.from_file(str(path)), t, cmd)
    np.testing.assert_allclose(again.tips([again.nominal])[0], replayer.tips([k])[0], atol=1e-6)


def test_muscle_friction_on_the_muscle_tendons(spec):
    """Segmented muscles refuse plugin effect terms, so muscle friction f0 becomes the dry friction
    of each muscle's whole-length tendon (whose joint coefficients are the muscle's length
    Jacobian: 1 per extension slide, -x_i/2, y_i/2 per bend); friction holds back part of a small
    step down (the stick-slip band 2 f0); an unsegmented (pcc) arm keeps the plugin's friction keys."""
    t = np.arange(0, 3.0, 0.02)
    cmd = np.tile([250e3, 250e3, 250e3], (len(t), 1))
    replayer = Replayer(spec, t, cmd)
    f0 = 4.0
    edited = replayer.edited_spec(with_values(replayer.nominal, friction_N=f0)).compile()
    section = small_arm().sections[0]
    x, y = section.radius_m * np.cos(section.angles_rad), section.radius_m * np.sin(section.angles_rad)
    for i, name in enumerate(MUSCLES):
        t_id = edited.tendon(name).id
        assert edited.tendon_frictionloss[t_id] == pytest.approx(f0)
        coefficients = {}
        first = edited.tendon_adr[t_id]
        for w in range(first, first + edited.tendon_num[t_id]):
            joint = edited.joint(edited.wrap_objid[w]).name.split("_", 1)[1]
            coefficients.setdefault(joint, []).append(edited.wrap_prm[w])
        assert sorted(coefficients) == ["bend_x", "bend_y", "ext_a", "ext_b"]
        # two segments (a, b) per link each take half the link's bend at the muscle's offset
        assert coefficients["ext_a"] == pytest.approx([1.0] * DISKS)
        assert coefficients["bend_x"] == pytest.approx([y[i]] * DISKS)
        assert coefficients["bend_y"] == pytest.approx([-x[i]] * DISKS)
    assert not np.any(edited.dof_frictionloss)
    for p in replayer.edited_spec(with_values(replayer.nominal, friction_N=f0)).plugins:
        assert not any(key.startswith("friction.") for key in dict(p.config))
    # quasi-static stick-slip: the arm extends under the first command and sticks with an
    # unbalanced muscle force u somewhere in [-f0, f0]; a step down that lowers each muscle's force
    # by dF moves it by (dF - f0 - u) / k when positive: between (dF - 2 f0) / k and dF / k, and
    # not at all once 2 f0 far exceeds dF
    model = replayer.spec.compile()
    data = mujoco.MjData(model)
    forces = []
    for pressure in (250e3, 235e3):
        data.ctrl[:] = data.act[:] = pressure
        mujoco.mj_forward(model, data)
        forces.append(data.actuator_force[0])
    dF = forces[0] - forces[1]
    down = np.full_like(cmd, 250e3)
    down[len(t) // 2 :] = 235e3
    replayer = Replayer(spec, t, down)
    small, large = 0.25 * dF, 3.0 * dF  # 2 f0 below dF, and far above it
    tips = replayer.tips(
        [replayer.nominal] + [with_values(replayer.nominal, friction_N=f) for f in (small, large)]
    )
    step = [tip[-1, 2] - tip[len(t) // 2 - 1, 2] for tip in tips]
    assert step[0] < -1e-3
    # (bounds with slack: the muscles' stiffness is not constant over the step, the stop is dynamic)
    assert 1 - 2 * small / dF - 0.25 < step[1] / step[0] < 0.95
    assert abs(step[2]) < 0.05 * abs(step[0])
    pcc = Replayer(arm.build_spec(small_arm(mode="pcc")), t, cmd)
    assert not pcc.segmented
    config = dict(pcc.edited_spec(with_values(pcc.nominal, friction_N=f0)).plugins[0].config)
    assert float(config["friction.f0_N"]) == pytest.approx(f0)
    assert np.isfinite(pcc.tips([with_values(pcc.nominal, friction_N=f0)])).all()


def test_one_way_cross_talk_command_map(spec):
    """Muscle 0 receives from muscle 2: P_0 = P_0 + c (P_2 - P_0); the others are untouched."""
    t = np.arange(0, 1.0, 0.02)
    cmd = np.column_stack([100e3 + 0 * t, 200e3 + 50e3 * np.sin(t), 300e3 + 0 * t])
    replayer = Replayer(spec, t, cmd)
    k = with_values(replayer.nominal, coupling=((0, 2, 0.25),))
    ctrl = replayer.controls(k, cmd)
    np.testing.assert_allclose(ctrl[:, 0], cmd[:, 0] + 0.25 * (cmd[:, 2] - cmd[:, 0]))
    np.testing.assert_allclose(ctrl[:, 1:], cmd[:, 1:])


def test_unstable_variant_fails_quietly(spec, capfd):
    """A variant that diverges (the light links with almost no joint damping at a 4 ms step) is given a
    tip far away, counted, and MuJoCo's warning is not printed."""
    t = np.arange(0, 1.0, 0.02)
    cmd = np.tile([150e3, 250e3, 350e3], (len(t), 1))
    replayer = Replayer(spec, t, cmd)
    bad = with_values(replayer.nominal, damping_axial=1e-6, damping_bend=1e-6, lag_s=[1e-4] * 3)
    tips = replayer.tips([replayer.nominal, bad])
    assert np.all(np.abs(tips[0]) < 1.0)
    assert replayer.unstable == 1 and np.all(tips[1] == 1e3)
    out = capfd.readouterr()
    assert "unstable" not in out.out + out.err


def _smooth_errors(rng, n, corr_rows, scale):
    """Tip errors (n, 3) of a model that is wrong in a smooth way: AR(1) with a correlation
    length of about ``corr_rows`` rows, its size varying along the recording by ``scale``."""
    phi = 1 - 2 / (corr_rows + 1)  # 1 + 2 sum phi^k = (1 + phi) / (1 - phi) = corr_rows
    e = np.zeros((n, 3))
    kick = rng.normal(size=(n, 3)) * np.sqrt(1 - phi**2)
    for i in range(1, n):
        e[i] = phi * e[i - 1] + kick[i]
    return e * scale[:, None]


def test_paired_comparison_holds_its_level_on_autocorrelated_errors():
    """Two equally good hypotheses whose errors are smooth (correlated over ~40 rows) and vary
    tenfold in size along the recording: b is called worse in about 5 % of recordings (the
    one-sided level), not more; rows treated as independent would call it in far more."""
    from efam_mujoco.armdiag.diagnosis import PAIRED_LEVEL, paired_comparison

    rng = np.random.default_rng(11)
    n = 800
    scale = 1e-3 * (1 + 9 * (np.sin(np.linspace(0, 6 * np.pi, n)) > 0.5))
    held = np.ones(n, bool)
    measured = np.zeros((n, 3))
    calls = []
    for _ in range(300):
        a = _smooth_errors(rng, n, 40, scale)
        b = _smooth_errors(rng, n, 40, scale)
        p = paired_comparison(a, b, measured, held)
        calls.append(p["t"] > p["critical_t"])
    assert np.mean(calls) < (1 - PAIRED_LEVEL) + 0.04  # 5 % plus ~2.5 binomial standard errors


def test_paired_comparison_finds_a_consistently_worse_hypothesis():
    """b's error is 1.3 x a's everywhere (a model a little off in every segment), while the error
    size varies tenfold: the log-ratio segments tell them apart in nearly every recording; the
    comparison is symmetric (a is never called worse than b)."""
    from efam_mujoco.armdiag.diagnosis import paired_comparison

    rng = np.random.default_rng(12)
    n = 800
    scale = 1e-3 * (1 + 9 * (np.sin(np.linspace(0, 6 * np.pi, n)) > 0.5))
    held, measured = np.ones(n, bool), np.zeros((n, 3))
    found, reverse = [], []
    for _ in range(40):
        a = _smooth_errors(rng, n, 20, scale)
        b = 1.3 * _smooth_errors(rng, n, 20, scale)
        p = paired_comparison(a, b, measured, held)
        q = paired_comparison(b, a, measured, held)
        found.append(p["t"] > p["critical_t"])
        reverse.append(q["t"] > q["critical_t"])
    assert np.mean(found) >= 0.9 and not any(reverse)


def test_choice_follows_the_paired_test_against_none():
    """The parameter penalty ranks ``none`` first, yet the runner-up's held-out error is 0.8 x
    none's in every segment: the data have separated them, so the effect is the answer (not
    confident: its probability is unchanged), not ``none`` and not an ambiguous pair. With the
    two equally good, ``none`` stays the answer and is not called ambiguous; an effect answer
    against an equally good runner-up is."""
    from efam_mujoco.armdiag.diagnosis import choose

    rng = np.random.default_rng(14)
    n = 800
    scale = np.full(n, 1e-3)
    held, measured = np.ones(n, bool), np.zeros((n, 3))
    better = _smooth_errors(rng, n, 20, scale)
    worse = 1.25 * _smooth_errors(rng, n, 20, scale)
    prob = {"none": 0.6, "payload": 0.4}
    first, second, paired, ambiguous, overruled = choose(
        prob, {"none": worse, "payload": better}, measured, held, at_floor=False
    )
    assert (first, second, ambiguous, overruled) == ("payload", "none", False, True)
    assert paired["t"] > paired["critical_t"]
    # at the noise floor that question has been asked already: none stays
    first, _, _, ambiguous, overruled = choose(prob, {"none": worse, "payload": better}, measured, held, True)
    assert (first, ambiguous, overruled) == ("none", False, False)
    equal = {"none": better, "payload": better + 1e-9 * rng.normal(size=(n, 3))}
    first, _, _, ambiguous, _ = choose(prob, equal, measured, held, False)
    assert (first, ambiguous) == ("none", False)
    first, _, _, ambiguous, _ = choose({"payload": 0.6, "none": 0.4}, equal, measured, held, False)
    assert (first, ambiguous) == ("payload", True)


def test_head_replay_is_the_start_of_the_full_replay(spec):
    """The screen's short replay is the same simulation cut short: its tips equal the full
    replay's first rows exactly (same settling, same steps)."""
    rng = np.random.default_rng(3)
    rec = make_recording(spec, Truth("none"), "random", rng, duration_s=6.0, rate_Hz=50.0, noise_m=5e-4)
    full = Replayer(spec, rec.time_s, rec.command_Pa)
    head = full.head(2.5)
    assert len(head.time_s) < len(rec.time_s) and full.head(60.0) is full
    knobs = with_values(full.nominal, gain=(0.9, 1.0, 1.05), lag_s=(0.05, 0.1, 0.2))
    np.testing.assert_array_equal(head.tips([knobs])[0], full.tips([knobs])[0][: len(head.time_s)])
    # built once; its rollouts count in the whole replayer's cost too
    assert full.head(2.5) is head
    assert head.rollouts == 1 and full.rollouts == 2
    assert full.simulated_s > head.simulated_s > 0


def test_paired_comparison_never_separates_identical_predictions():
    """Two hypotheses that replay the same tip (an effect fitted to nothing) are not told apart,
    whatever the data: t = 0, never a sure difference."""
    from efam_mujoco.armdiag.diagnosis import paired_comparison

    rng = np.random.default_rng(13)
    n = 300
    tip = rng.normal(size=(n, 3)) * 1e-3
    p = paired_comparison(tip, tip.copy(), np.zeros((n, 3)), np.ones(n, bool))
    assert p["t"] == 0.0 and p["t"] < p["critical_t"]


def test_search_window_rule():
    """The search window is the shortest head of whole blocks (a sixth of the recording each;
    the second and fifth held out) with 10 s of training time: the first 10 s block of a 60 s
    recording, the first three 5 s blocks of a 30 s one (blocks 1 and 3 train); none for
    recordings with 10 s of training time or less (up to 15 s: searched whole)."""
    from efam_mujoco.armdiag.diagnosis import search_window_s

    assert search_window_s(np.arange(0, 60, 0.01)) == pytest.approx(10.0, abs=0.01)
    assert search_window_s(np.arange(0, 30, 0.01)) == pytest.approx(15.0, abs=0.01)
    assert search_window_s(np.arange(0, 120, 0.01)) == pytest.approx(20.0, abs=0.02)
    for seconds in (6.0, 12.0, 15.0):
        assert search_window_s(np.arange(0, seconds, 0.01)) is None


def test_window_fitted_weak_muscle_equals_the_whole_fit(spec):
    """A weak muscle (the library's form, pressure factor 0.8 on s1m2) in a 24 s recording: the
    factor fitted on the search window (the first 16 s: blocks 1-4 of 4 s, 12 s of training rows) equals
    the fit on every training row, and the concealed value, within the noise's scatter."""
    from efam_mujoco.armdiag.diagnosis import WINDOW_TRAIN_S, _maker, folds, search_window_s
    from efam_mujoco.armdiag.effects import get, refit_params
    from efam_mujoco.armdiag.fit import fit

    t = np.arange(0, 24.0, 1 / 30)
    rng = np.random.default_rng(21)
    knots = np.arange(0, 26, 1.5)
    cmd = np.column_stack([np.interp(t, knots, rng.uniform(60e3, 420e3, len(knots))) for _ in range(3)])
    whole = Replayer(spec, t, cmd)
    measured = whole.tips([with_values(whole.nominal, gain=(1.0, 0.8, 1.0))])[0]
    measured += rng.normal(0, 5e-4, measured.shape)
    train, _ = folds(t, np.ones(len(t), bool))
    window_s = search_window_s(t)
    assert WINDOW_TRAIN_S == 10.0 and window_s == pytest.approx(16.0, abs=0.05)  # blocks of 4 s
    head = whole.head(window_s)
    n = len(head.time_s)
    assert n < len(t)
    factor = get("weak_muscle").params[:1]  # the factor alone (no drop): one well-posed number
    make = _maker(get("weak_muscle"), whole.nominal, 1)
    fixed = {p.key: p.start for p in refit_params(3)} | {"drop_Pa": 0.0}
    found = {
        name: fit(r, factor, lambda v: make(fixed | v), measured[: len(r.time_s)], train[: len(r.time_s)],
                  iterations=3).values["pressure_factor"]
        for name, r in (("window", head), ("whole", whole))
    }  # fmt: skip
    assert found["window"] == pytest.approx(0.8, abs=0.01)
    assert found["whole"] == pytest.approx(0.8, abs=0.01)
    assert found["window"] == pytest.approx(found["whole"], abs=0.005)


def test_long_recording_is_searched_on_its_window_and_judged_whole(spec):
    """A 24 s recording (a weak s1m2, orifice leak) is searched on its first 16 s only, yet the
    diagnosis reports whole-recording replays: every tip row, held-out errors from the rows
    beyond the window too, and names the muscle."""
    rng = np.random.default_rng(6)
    truth = Truth("weak_muscle", {"leak_sqrt_Pa": 130.0}, "s1m2")
    rec = make_recording(spec, truth, "steps", rng, duration_s=24.0, rate_Hz=30.0, noise_m=5e-4)
    d = diagnose_arm(spec, rec, threads=1, effects=("payload", "weak_muscle"))
    assert d.decisions["search_window_s"] == pytest.approx(16.0, abs=0.1)
    assert d.verdict["answer"] == "weak_muscle" and d.effects[0]["muscle"] == "s1m2"
    late = rec.time_s > d.decisions["search_window_s"]
    for tip in (d.tip_nominal, d.tip_before, d.tip_after):
        assert tip.shape == rec.tip_m.shape and np.all(np.isfinite(tip))
    # the identified model follows the recording beyond the window as well as inside it
    err = np.linalg.norm(d.tip_after - rec.tip_m, axis=1)
    inside, beyond = np.nanmean(err[~late & rec.valid]), np.nanmean(err[late & rec.valid])
    assert beyond < 2 * inside + 1e-3 and d.heldout_rms_after_m < 0.5 * d.heldout_rms_nominal_m


@pytest.mark.parametrize("pattern", ["all equal", "vented first", "one muscle never used"])
def test_location_bins_a_test_never_visits_are_left_out_not_nan(pattern):
    # valid arm tests leave some location bins empty: every muscle commanded alike (no muscle
    # ever dominant, and the pressure thirds cut through equal values), the low third all vented,
    # a muscle never commanded. Such a bin was NaN, and the JSON writer refused the finished
    # diagnosis ("$.located.by_dominant_muscle_m.s1m2 is nan")
    from efam_mujoco.armdiag.locate import locate

    rng = np.random.default_rng(0)
    n, muscles = 600, ["s1m1", "s1m2", "s1m3"]
    t = np.linspace(0.0, 12.0, n)
    ramp = 200e3 * (1 - np.cos(2 * np.pi * t / 6.0)) / 2
    command = np.column_stack([ramp, ramp, ramp])
    if pattern == "vented first":
        command[: int(0.4 * n)] = 0.0
        command[:, 1] *= 0.5
    elif pattern == "one muscle never used":
        command[:, 1] = ramp[::-1]
        command[:, 2] = 0.0
    residual = rng.normal(0.0, 5e-4, (n, 3))
    valid = np.ones(n, dtype=bool)
    directions = {f"{m}:gain": rng.normal(0.0, 1e-3, (n, 3)) for m in muscles}
    out = locate(t, command, muscles, [[0, 1, 2]], residual, valid, 5e-4, directions)
    text = json.dumps(out, allow_nan=False)  # raises on any NaN
    assert "nan" not in " ".join(out["summary"]).lower()
    if pattern == "all equal":
        assert all(v is None for v in out["by_dominant_muscle_m"].values())
    if pattern == "one muscle never used":
        assert out["by_dominant_muscle_m"]["s1m3"] is None
        assert out["by_dominant_muscle_m"]["s1m1"] is not None
    assert "by mean pressure" in text
