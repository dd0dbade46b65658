"""Bad input and runaway work in the arm commands (``efam diagnose-arm``, ``efam arm``) and the
continuum reference: unit mix-ups in an arm recording refused with the unit that fits,
saturation never silent, MuJoCo and continuum disagreeing loudly, sizes and loads that would run
for minutes bounded before or while they run."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from _robust import run_bad, run_cli

from efam_mujoco import arm
from efam_mujoco.arm import continuum
from efam_mujoco.armdiag import ArmRecording, diagnose_arm, load_arm_model, read_csv, save_spec, write_csv
from efam_mujoco.armdiag.recording import (
    ArmRecordingError,
    ArmRecordingWarning,
    check_against_model,
)
from efam_mujoco.armdiag.specfile import model_limits
from efam_mujoco.armdiag.synth import Truth, make_recording
from efam_mujoco.muscle import Muscle
from efam_mujoco.stress import StressLaw

DT = 4e-3  # the 2-disk arm of tests/test_armdiag.py: fast replays


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A 2-disk 1x3 arm's spec file and a clean 6 s recording of it (40 Hz, SI)."""
    folder = tmp_path_factory.mktemp("armlab")
    model = save_spec(folder / "arm.json", arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT))
    spec = load_arm_model(model)
    rng = np.random.default_rng(3)
    rec = make_recording(spec, Truth("none"), "ramps", rng, duration_s=6.0, rate_Hz=40.0, noise_m=5e-4)
    return folder, model, spec, ArmRecording(rec.time_s, rec.muscles, rec.command_Pa, rec.tip_m)


def _variant(lab, name, time_factor=1.0, command_factor=1.0, tip_factor=1.0):
    folder, _, _, rec = lab
    changed = ArmRecording(rec.time_s * time_factor, rec.muscles, rec.command_Pa * command_factor,
                           rec.tip_m * tip_factor)  # fmt: skip
    return write_csv(folder / name, changed)


# ------------------------------------------------------------------ efam diagnose-arm (1-3)


def test_arm_headers_read_the_quantity_in_any_case_and_the_unit_and_muscle_as_written(lab):
    # loggers write 'Time_s', 'P_s1m1_kPa', 'TIP_X_m': the same columns as the lower-case
    # format, read to the same numbers; a unit differing in case (mPa is not MPa) and a muscle
    # name in another case are still refused
    folder, _, _, rec = lab
    muscles = rec.muscles
    plain = write_csv(folder / "plain.csv", rec)
    lines = plain.read_text().splitlines()
    head = lines[0].split(",")
    shouted = [h.replace("time_", "Time_").replace("p_", "P_", 1).replace("tip_", "TIP_").replace("_x_", "_X_")
               for h in head]  # fmt: skip
    loud = folder / "loud.csv"
    loud.write_text("\n".join([",".join(shouted)] + lines[1:]) + "\n")
    a, b = read_csv(plain, muscles), read_csv(loud, muscles)
    assert np.array_equal(a.time_s, b.time_s) and np.array_equal(a.command_Pa, b.command_Pa)
    assert np.array_equal(a.tip_m, b.tip_m, equal_nan=True)
    m = muscles[0]
    for bad, says in (
        (f"p_{m}_KPA", "KPA"),
        (f"p_{m.upper()}_kPa" if m.upper() != m else f"p_{m.lower()}_kPa", "no muscle of that name"),
    ):
        wrong = folder / "wrong.csv"
        wrong.write_text("\n".join([lines[0].replace(f"p_{m}_kPa", bad)] + lines[1:]) + "\n")
        with pytest.raises(ArmRecordingError, match=says):
            read_csv(wrong, muscles)


def test_diagnose_arm_refuses_milliseconds_under_a_seconds_header(lab, capsys, monkeypatch):
    """Before: a 6 s test written in ms under 'time_s' was accepted and replayed as 6000 s
    (1.5 million steps a rollout, hundreds of rollouts: killed after 40 s, still running). Now
    refused before any rollout (checked as that, not as a wall-clock time on a shared machine)."""
    from efam_mujoco.armdiag import replay

    def no_rollout(*args, **kwargs):
        raise AssertionError("a rollout ran before the refusal")

    monkeypatch.setattr(replay.Replayer, "_rollout", no_rollout)
    folder, model = lab[0], lab[1]
    csv = _variant(lab, "in_ms.csv", time_factor=1e3)
    run_bad(["diagnose-arm", csv, "--model", model], folder, capsys,
            r"column 'time_s'", r"'time_ms'", r"limit of \d+")  # fmt: skip


def test_arm_reader_refuses_implausible_time_bases(lab, tmp_path):
    """The reader's own bounds (as the muscle-level reader's): 1 us .. 60 s between samples, at
    most 4 h long; the message names the column and the unit the numbers fit."""
    muscles = lab[3].muscles
    head = "time_s,p_s1m1_kPa,p_s1m2_kPa,p_s1m3_kPa,tip_x_m,tip_y_m,tip_z_m\n"
    rows = "".join(f"{50.0 * k:g},100,100,100,0,0,0.2\n" for k in range(400))  # 20 000 s
    (tmp_path / "long.csv").write_text(head + rows)
    with pytest.raises(ArmRecordingError, match=r"column 1 \('time_s'\).*longer than the 4 h.*'time_ms'"):
        read_csv(tmp_path / "long.csv", muscles)
    rows = "".join(f"{200.0 * k:g},100,100,100,0,0,0.2\n" for k in range(10))
    (tmp_path / "sparse.csv").write_text(head + rows)
    with pytest.raises(ArmRecordingError, match=r"'time_s'.*median sample interval is 200 s"):
        read_csv(tmp_path / "sparse.csv", muscles)


def test_diagnose_arm_refuses_pascals_under_a_kilopascal_header(lab, capsys):
    """Before: commands 1000 x too large were replayed at the 517 kPa ceiling without a word."""
    folder, model = lab[0], lab[1]
    csv = _variant(lab, "in_pa.csv", command_factor=1e3)
    run_bad(["diagnose-arm", csv, "--model", model], folder, capsys,
            r"line 2, column 'p_s1m1_kPa'", r"highest pressure 517\.1\d* kPa", "was it Pa")  # fmt: skip


def test_commands_a_little_above_the_rating_are_counted_in_a_warning(lab):
    """Moderate overshoot is replayed at the model's highest pressure, with a warning naming the
    column and counting the samples (before: silent)."""
    _, _, spec, rec = lab
    limits = model_limits(spec)
    command = rec.command_Pa.copy()
    command[:7, 1] = 1.1 * limits["max_command_Pa"][1]
    over = ArmRecording(rec.time_s, rec.muscles, command, rec.tip_m,
                        meta={"source": "over.csv", "command_columns": ["p_s1m1_kPa", "p_s1m2_kPa", "p_s1m3_kPa"]})  # fmt: skip
    notes = check_against_model(over, limits["max_command_Pa"], limits["base_m"], limits["rest_reach_m"])
    assert len(notes) == 1 and "column 'p_s1m2_kPa': 7 of 240 commands" in notes[0], notes
    assert "replayed at 517.1" in notes[0]
    with pytest.warns(ArmRecordingWarning, match="p_s1m2_kPa': 7 of 240"):
        diagnose_arm(spec, over, threads=1, effects=("payload",))


def test_diagnose_arm_refuses_millimetres_under_a_metre_header(lab, capsys):
    """Before: a tip 150 m from the base of a 0.17 m arm was accepted."""
    folder, model = lab[0], lab[1]
    csv = _variant(lab, "in_mm.csv", tip_factor=1e3)
    run_bad(["diagnose-arm", csv, "--model", model], folder, capsys,
            r"column 'tip_[xyz]_m'", r"rest length 0\.17", r"'tip_[xyz]_mm'")  # fmt: skip


def test_diagnose_arm_refuses_metres_under_a_millimetre_header(lab, capsys):
    """Before: tips in metres under 'tip_*_mm' (a tip that never left the base) were replayed
    and a muscle was named, the wrong one (a blind review)."""
    folder, model, _, rec = lab
    path = write_csv(folder / "m_as_mm.csv", rec)
    lines = path.read_text().splitlines()
    lines[0] = (
        lines[0].replace("tip_x_m", "tip_x_mm").replace("tip_y_m", "tip_y_mm").replace("tip_z_m", "tip_z_mm")
    )
    path.write_text("\n".join(lines) + "\n")
    run_bad(["diagnose-arm", str(path), "--model", model], folder, capsys,
            r"'tip_x_mm', 'tip_y_mm', 'tip_z_mm'", r"stays within .* of the arm's base", r"'tip_x_m'")  # fmt: skip


@pytest.mark.parametrize(
    "name, change, words",
    [
        # MPa (or bar) under a kPa header: no command passes the dead band; was diagnosed "none"
        (
            "mpa.csv",
            {"command_factor": 1e-3},
            [r"largest command of any muscle is 0\.\d+ kPa", r"'p_s1m\d_MPa'"],
        ),
        (
            "bar.csv",
            {"command_factor": 1e-2},
            [r"under 5% of the model's highest pressure", r"'p_s1m\d_bar'"],
        ),
        # psi under a kPa header: 75 psi read as 75 kPa hardly bends the arm; the replay read in
        # psi follows the tip (was diagnosed, the gains re-fitted at their bounds)
        (
            "psi.csv",
            {"command_factor": 1 / 6.894757},
            [r"follows the recorded tip .* if the commands were in psi", r"'p_s1m1_psi'"],
        ),
        # a tip in another unit that keeps it a sixth of the arm's length from the base (cm under
        # 'mm'): passed the old tenth, and a weak muscle was named
        ("near.csv", {"tip_factor": 0.15}, [r"stays within .* of the arm's base", r"at least 0\.3 x"]),
        # seconds under 'time_ms': a 6 s test read as 6 ms, was diagnosed
        (
            "short.csv",
            {"header": ("time_s", "time_ms")},
            [r"spans 0\.00\d+ s, shorter than the 0\.5 s", r"'time_s'"],
        ),
    ],
)
def test_diagnose_arm_refuses_commands_tips_and_times_in_another_unit(lab, capsys, name, change, words):
    folder, model = lab[0], lab[1]
    header = change.pop("header", None)
    csv = _variant(lab, name, **change)
    if header:
        text = Path(csv).read_text()
        Path(csv).write_text(text.replace(header[0], header[1], 1))
    run_bad(["diagnose-arm", csv, "--model", model], folder, capsys, *words)


def test_diagnose_arm_warns_of_psi_under_kilopascals_on_an_arm_far_from_its_model(lab, capsys):
    """Before: on a recording the nominal arm follows only to 59 mm (a leaking muscle), psi
    written under 'p_*_kPa' left 119 mm as read, not under 0.3 x, and was diagnosed without a
    word. A unit that halves the tip error is now said (the diagnosis runs, as read); the same
    file in kPa says nothing."""
    folder, model = lab[0], lab[1]
    spec = load_arm_model(model)
    truth = Truth("weak_muscle", {"leak_sqrt_Pa": 110.0}, muscle="s1m2")
    rec = make_recording(spec, truth, "steps", np.random.default_rng(1), duration_s=12.0, rate_Hz=50.0,
                         noise_m=5e-4)  # fmt: skip
    for name, factor, said in (("psi_far.csv", 1 / 6.894757, True), ("kpa_far.csv", 1.0, False)):
        csv = write_csv(
            folder / name, ArmRecording(rec.time_s, rec.muscles, rec.command_Pa * factor, rec.tip_m)
        )
        code, _, err = run_cli(["diagnose-arm", str(csv), "--model", model], folder, capsys)
        assert code == 0, err
        warned = re.search(r"warning: .*follows the recorded tip with \d+(\.\d+)? mm RMS if the commands were in "
                           r"psi .*'p_s1m1_psi' \(diagnosed as read\)", err)  # fmt: skip
        assert bool(warned) == said, err


def test_diagnose_arm_refuses_a_frozen_marker(lab, capsys):
    """A tip column that never changes while the commands do was diagnosed (a weak muscle named)."""
    folder, model, _, rec = lab
    frozen = np.broadcast_to(rec.tip_m[0], rec.tip_m.shape).copy()
    csv = write_csv(folder / "frozen.csv", ArmRecording(rec.time_s, rec.muscles, rec.command_Pa, frozen))
    run_bad(
        ["diagnose-arm", csv, "--model", model],
        folder,
        capsys,
        r"the tip never moves .* a frozen or lost marker",
    )


def test_diagnose_arm_refuses_a_tip_value_no_arm_can_have(lab, capsys):
    """Before: one tip of 1e300 m overflowed the distance to inf, which the reach check skipped;
    the diagnosis ran on it and printed 'residual RMS inf mm' with exit 0. The reader now refuses
    it as the muscle recordings' reader does (above 1e9 in SI), and the reach check counts an
    overflow as far."""
    folder, model, spec, rec = lab
    tip = rec.tip_m.copy()
    tip[1, 0] = 1e300
    csv = write_csv(folder / "huge.csv", ArmRecording(rec.time_s, rec.muscles, rec.command_Pa, tip))
    run_bad(["diagnose-arm", csv, "--model", model], folder, capsys,
            r"line 3, column 5 \('tip_x_m'\)", r"cannot be physical")  # fmt: skip
    limits = model_limits(spec)
    huge = ArmRecording(rec.time_s, rec.muscles, rec.command_Pa, tip, meta={"source": "huge.csv"})
    with pytest.raises(ArmRecordingError, match=r"column 'tip_x_m': the tip is inf m from the arm's base"):
        check_against_model(huge, limits["max_command_Pa"], limits["base_m"], limits["rest_reach_m"])


def test_arm_recordings_are_read_by_the_muscle_recordings_rules(lab, tmp_path):
    """Before: a UTF-8 byte-order mark (Excel's 'CSV UTF-8') was an unknown column, '0.0_2' was
    read as 0.02, a semicolon-separated file was 'unknown time unit', a bad byte was a codec's
    byte offset, a bare-CR file was read. Now the bench reader's rules, and its messages."""
    muscles = lab[3].muscles
    text = write_csv(tmp_path / "plain.csv", lab[3]).read_text()
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + text.encode())
    np.testing.assert_array_equal(
        read_csv(tmp_path / "bom.csv", muscles).tip_m, read_csv(tmp_path / "plain.csv", muscles).tip_m
    )
    lines = text.splitlines()
    cases = {
        "underscore.csv": ("\n".join(lines[:2] + [lines[2].replace(",", "_1,", 1)] + lines[3:]), r"line 3, column 1 \('time_s'\): not a number"),
        "semicolon.csv": (text.replace(",", ";"), r"'semicolon'-separated"),
        "cr.csv": (text.replace("\n", "\r"), r"bare carriage return"),
        "comma.csv": ("\n".join(lines[:2] + ['"0,02"' + lines[2][lines[2].index(","):]] + lines[3:]), r"decimal comma"),
    }  # fmt: skip
    for name, (body, words) in cases.items():
        (tmp_path / name).write_bytes(body.encode())
        with pytest.raises(ArmRecordingError, match=words):
            read_csv(tmp_path / name, muscles)
    (tmp_path / "latin.csv").write_bytes(text.replace("tip_z_m", "tip_z_m,T_\u00b0C", 1).encode("latin-1"))
    with pytest.raises(ArmRecordingError, match=r"line 1, column \d+: byte 0xb0 is not UTF-8"):
        read_csv(tmp_path / "latin.csv", muscles)


def test_diagnose_arm_refuses_a_recording_no_pressure_drives(lab, capsys):
    """Before: commands of 0 kPa in every row were replayed and 'diagnosed' (the arm only sags)."""
    folder, model, _, rec = lab
    idle = write_csv(
        folder / "idle.csv", ArmRecording(rec.time_s, rec.muscles, 0 * rec.command_Pa, rec.tip_m)
    )
    err = run_bad(["diagnose-arm", idle, "--model", model], folder, capsys,
                  r"idle\.csv: every command column", "nothing drives the arm")  # fmt: skip
    assert len(err.strip().splitlines()) <= 2, err  # the error line (and the time-step warning)


def test_arm_comment_rows_among_the_data_are_counted_and_reported(lab):
    """'#' rows of an arm recording were skipped without a word (the muscle recordings report
    them): a commented-out sample is counted in meta and named by the diagnosis; a preamble
    before the header is only counted."""
    folder, _, spec, rec = lab
    lines = write_csv(folder / "plain_for_comments.csv", rec).read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("time_"))
    lines[head + 4] = "#" + lines[head + 4]  # a sample commented out
    lines.insert(head + 9, "# valve swapped")  # a note among the data
    commented = folder / "commented.csv"
    commented.write_text("# arm 2, lab B\n" + "\n".join(lines) + "\n")
    got = read_csv(commented, rec.muscles)
    # file lines, 1-based, one preamble line before: the sample at index head + 4 and the note
    first, second = head + 4 + 2, head + 9 + 2
    preamble = 1 + sum(line.startswith("#") for line in lines[:head])  # ours and the writer's
    assert got.meta["comment_rows"] == preamble + 2
    assert got.meta["comment_lines_in_data"] == [first, second], got.meta["comment_lines_in_data"]
    assert len(got) == len(rec) - 1
    with pytest.warns(
        ArmRecordingWarning, match=rf"commented\.csv: skipped 2 comment row\(s\).*line\(s\) {first}, {second}"
    ):
        diagnose_arm(spec, got, threads=1, effects=("payload",))
    plain = read_csv(folder / "plain_for_comments.csv", rec.muscles)
    assert plain.meta["comment_lines_in_data"] == []


def test_diagnose_arm_shows_a_python_warning_as_one_line(lab, capsys):
    """The lab's 4 ms step draws the builder's TimestepWarning: one line in the error line's form,
    from ``efam diagnose-arm`` and from ``python -m efam_mujoco.armdiag.report`` (before: Python's
    ``/path/builder.py:133: TimestepWarning: ...`` plus the source line, or a traceback)."""
    from efam_mujoco.armdiag.report import main as module_main

    folder, model = lab[0], lab[1]
    bad = folder / "bad_column.csv"
    bad.write_text("time_s,p_s1m1_kPa,p_s1m2_kPa,p_s1m3_kPa,tip_x_m,tip_y_m,tip_zz_m\n0,1,1,1,0,0,0.2\n")
    from_efam = run_cli(["diagnose-arm", bad, "--model", model], folder, capsys)[2]
    assert module_main([str(bad), "--model", str(model)]) == 2
    for err in (from_efam, capsys.readouterr().err):
        lines = err.strip().splitlines()
        assert len(lines) == 2, err
        assert lines[0].startswith("efam diagnose-arm: warning: arm: timestep_s = 4 ms is stable only"), err
        assert lines[1].startswith("efam diagnose-arm: error: ") and "tip_zz_m" in lines[1], err
        assert ".py:" not in err and "TimestepWarning" not in err


# ------------------------------------------------------------------------------ efam arm (4-5)


def test_arm_says_when_mujoco_and_the_continuum_disagree(tmp_path, capsys, monkeypatch):
    """Before: 5 kg on the horizontal arm gave MuJoCo and continuum tips 113 % of the rest length
    apart (2 kg: 166 %), printed without a word. Now a disagreement beyond the tolerance is a
    warning with the figures and the likely reasons (the tolerance is lowered here so that a
    light, fast case shows it; the figures stay printed on standard output and in the JSON)."""
    from efam_mujoco.arm import cli as arm_cli

    monkeypatch.setattr(arm_cli, "AGREEMENT_PCT", 0.01)
    code, out, err = run_cli(["arm", "--orientation", "horizontal", "--payload-kg", "0.5", "--disks", "4",
                              "--pressures-kPa", "200", "200", "200", "--json", tmp_path / "eq.json"],
                             tmp_path, capsys)  # fmt: skip
    assert code == 0 and "continuum reference [" in out, out
    assert "efam arm: warning: the MuJoCo arm and the continuum reference disagree: their tips are" in err, (
        err
    )
    assert err.count("\n") == 1, err  # one line, prefixed like every command's warnings
    assert "% of the arm's rest length apart (they agree within 0.01 %" in err and "likely:" in err
    doc = json.loads((tmp_path / "eq.json").read_text())
    assert doc["agreement"]["agree"] is False and doc["agreement"]["reasons"], doc
    assert doc["difference_pct_of_rest_length"] > 0.01


def test_arm_disagreement_reasons_name_a_curled_reference():
    """The likely reasons name a continuum section curled past a half turn and a large
    deflection (the 5 kg horizontal case's figures, measured: continuum 268 deg, MuJoCo 90 deg)."""
    from types import SimpleNamespace

    from efam_mujoco.arm import cli as arm_cli

    spec = arm.ArmSpec(sections=(arm.paper_section(),), orientation="horizontal", payload_kg=5.0)
    state = SimpleNamespace(sections=[SimpleNamespace(muscle_lengths_m=np.full(3, 0.26))])
    result = {"section_bend_deg": [267.5], "bend_mujoco_deg": 90.0, "tip_mujoco_m": [0.256, 0.0, 0.0686],
              "settled": True}  # fmt: skip
    reasons = arm_cli._disagreement_reasons(spec, [[200e3] * 3], state, result)
    assert "curled past a half turn (section 1 bent 268 deg, MuJoCo's whole arm 90 deg)" in reasons[0]
    assert reasons[0].endswith("MuJoCo's arm settled into the stable one"), reasons[0]
    assert any(r.startswith("large deflection") for r in reasons), reasons
    # a coarse MuJoCo arm is named first, and the reference no longer blamed alone: with 2 disks
    # `efam arm --pressures-kPa 300 300 0` was 32.5 % off a reference 8 disks meet within 0.04 %
    coarse = arm.ArmSpec(sections=(arm.paper_section(disks=2),), orientation="horizontal", payload_kg=5.0)
    reasons = arm_cli._disagreement_reasons(coarse, [[200e3] * 3], state, result)
    assert reasons[0].startswith(
        "the MuJoCo arm is coarse (section 1 has 2 spacer disk(s), the default is 8)"
    )
    assert reasons[1].endswith("or the coarse MuJoCo arm cannot curl that far"), reasons


def test_arm_refuses_sizes_beyond_its_cost_limit(tmp_path, capsys, monkeypatch):
    """Before: 20 sections x 24 muscles x 40 disks ran for minutes, more than two of them inside
    MuJoCo's compiler (deaf to SIGTERM). Now refused up front (before any model is built),
    naming the limit and the override."""
    from efam_mujoco.arm import cli as arm_cli

    def no_build(*args, **kwargs):
        raise AssertionError("a model was built before the refusal")

    monkeypatch.setattr(arm_cli, "build_model", no_build)
    run_bad(["arm", "--sections", "20", "--muscles-per-section", "24", "--disks", "40",
             "--pressures-kPa", *["200"] * 480], tmp_path, capsys,
            "3200 degrees of freedom", "beyond the 480", "--allow-large")  # fmt: skip


def test_arm_shows_its_phases(tmp_path, capsys, monkeypatch):
    """A long ``efam arm`` shows which phase it is in (the progress bar, forced on here)."""
    monkeypatch.setenv("EFAM_PROGRESS", "1")
    code, _, err = run_cli(["arm", "--disks", "2", "--pressures-kPa", "200", "200", "200"], tmp_path, capsys)
    assert code == 0 and "efam arm" in err and "3/3" in err, err


# ------------------------------------------------------------------------- continuum bound (6)


def _counted_rods(monkeypatch) -> list:
    """Every continuum rod a solve builds, kept so that a test can read the work it did (its
    ``evaluations``) instead of a wall-clock time."""
    rods = []
    build = continuum._Rod.__init__

    def counted(self, *args, **kwargs):
        build(self, *args, **kwargs)
        rods.append(self)

    monkeypatch.setattr(continuum._Rod, "__init__", counted)
    return rods


def test_continuum_reference_with_the_sizers_heavy_payload_stops_promptly(monkeypatch):
    """``efam size --bundle 3 --payload 10``: three 25 mm muscles, horizontal, 10 kg at the tip.
    The load pushes the muscles into lock-out; the rod's integrations turn stiff (1700
    evaluations each, 20 s and a curled 245 deg answer before). Each integration and the whole
    solve are bounded in work: here it raises ContinuumError, saying it did not converge."""
    muscle = Muscle(
        rest_length_m=0.025459482797370408, rest_diameter_m=0.006143625, theta_rest_deg=8.138950832997454,
        bladder_volume_m3=2.410092235136048e-07, deadband_Pa=33620.0,
        stress=StressLaw(name="exponential_decay", coefficients=(1479000.0, 1.9771, 121646.0, 13.0762)),
        tension_only=False, lock_stiffness_N_per_m=20000.0, name="latex 1/8 x 1/32 in wall in PET 1/8 in",
    )  # fmt: skip
    from efam_mujoco.size.bundle import section_for

    loaded = arm.ArmSpec(sections=(section_for(muscle, 3),), pressure_tau_s=0.0, max_pressure_Pa=400e3,
                         orientation="horizontal", payload_kg=10.0)  # fmt: skip
    # the work, not the wall clock (a timed test fails on a shared machine: 10.4 s beside a
    # benchmark): every rod the solve builds stops within its evaluation bound
    rods = _counted_rods(monkeypatch)
    with pytest.raises(continuum.ContinuumError, match="did not converge|no rod equilibrium"):
        continuum.solve_arm_spec(loaded, [[400e3] * 3], max_evaluations=8000)
    assert rods and all(rod.evaluations <= rod.max_evaluations + 1 for rod in rods)
    assert sum(rod.evaluations for rod in rods) <= 8001 * len(rods)


def test_continuum_budget_is_an_error_not_a_hang(monkeypatch):
    """Any loaded solve stops at its evaluation bound with a clear ContinuumError (its work is
    counted, not timed)."""
    heavy = arm.ArmSpec(sections=(arm.paper_section(),), orientation="horizontal", payload_kg=5.0)
    rods = _counted_rods(monkeypatch)
    with pytest.raises(continuum.ContinuumBudgetError, match="did not converge within 500 constitutive"):
        continuum.solve_arm_spec(heavy, [[200e3] * 3], max_evaluations=500)
    assert rods and all(rod.evaluations <= 501 for rod in rods)


def test_diagnose_arm_report_into_a_users_folder_is_refused_before_the_work(lab, tmp_path, capsys):
    """diagnose-arm wrote report.txt over the user's own report.txt in a folder that was no efam
    report; it now builds its report beside and swaps it in, as efam diagnose does."""
    folder, model, spec, rec = lab
    recording = tmp_path / "rec.csv"
    write_csv(recording, rec)
    mine = tmp_path / "userdir"
    mine.mkdir()
    (mine / "report.txt").write_text("my precious report")
    code, _, err = run_cli(["diagnose-arm", str(recording), "--model", str(model), "--report", str(mine)],
                           tmp_path, capsys)  # fmt: skip
    assert code == 2 and "is not an efam report folder" in err
    assert (mine / "report.txt").read_text() == "my precious report"


@pytest.mark.parametrize("flag", ["--json", "--report"])
def test_diagnose_arm_never_writes_over_a_muscle_file_its_spec_names(lab, tmp_path, capsys, flag):
    """An arm spec may name its muscles by file path; ``--json`` that same path replaced the
    user's calibrated muscle file with the diagnosis (and ``--report`` a folder holding it)."""
    folder, model, spec, rec = lab
    recording = tmp_path / "rec.csv"
    write_csv(recording, rec)
    (tmp_path / "muscles").mkdir()
    muscle = tmp_path / "muscles" / "mine.json"
    muscle.write_text(_muscle_file_text())
    doc = json.loads(Path(model).read_text())
    doc["sections"][0]["muscles"] = ["muscles/mine.json"] * len(doc["sections"][0]["muscles"])
    spec_path = tmp_path / "arm_by_path.json"
    spec_path.write_text(json.dumps(doc))
    before = muscle.read_bytes()
    target = "muscles/mine.json" if flag == "--json" else "muscles"
    code, _, err = run_cli(
        ["diagnose-arm", "rec.csv", "--model", "arm_by_path.json", flag, target], tmp_path, capsys
    )
    assert code == 2, err
    assert "would overwrite the input --model arm_by_path.json: sections[0].muscles[0]" in err
    assert muscle.read_bytes() == before


def _muscle_file_text() -> str:
    from efam_mujoco.musclefile import load_muscle, muscle_document

    return json.dumps(muscle_document(load_muscle("FAM1")))


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda p: p.symlink_to("/dev/zero"), "not a regular file"),  # was read until memory ran out
        (lambda p: __import__("os").mkfifo(p), "not a regular file"),  # was a hang
        (lambda p: p.write_bytes(b"{" + b" " * 5_000_000), "bytes is not an arm spec file"),
        (
            lambda p: p.write_text('{"format": "efam_mujoco.arm_spec/1", "gravity": "no", "sections": []}'),
            "key 'gravity' must be a JSON boolean",
        ),  # 'no' was taken as true
        (lambda p: p.write_text('{"format": "x", "payload_kg": 0, "payload_kg": 5}'), "appears twice"),
        # was Python's bare "int too large to convert to float", naming neither file nor place
        (
            lambda p: p.write_text('{"format": "efam_mujoco.arm_spec/1",\n "payload_kg": ' + "9" * 400 + "}"),
            r"arm\.json: line 2, column 16: not valid JSON \(an integer of 400 digits cannot be a value here\)",
        ),
    ],
)
def test_arm_spec_files_are_read_as_strictly_as_muscle_files(tmp_path, make, words):
    from efam_mujoco.armdiag.specfile import ArmModelError, load_spec

    path = tmp_path / "arm.json"
    make(path)
    with pytest.raises(ArmModelError, match=words):
        load_spec(path)


def test_arm_spec_files_beyond_the_arm_commands_size_are_refused(tmp_path):
    """An arm JSON with 200 disks a section hung diagnose-arm, deaf to SIGTERM."""
    from efam_mujoco.armdiag.specfile import ArmModelError, load_spec

    path = save_spec(tmp_path / "arm.json", arm.ArmSpec(sections=(arm.paper_section(disks=2),)))
    doc = json.loads(path.read_text())
    doc["sections"][0]["disks"] = 200
    path.write_text(json.dumps(doc))
    with pytest.raises(ArmModelError, match="800 degrees of freedom"):
        load_spec(path)


def test_settle_refuses_pressures_mujoco_would_zero_or_clamp():
    model = arm.build_model(arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT))
    data = mujoco_data(model)
    for bad in ([np.nan, 1e5, 1e5], [1e9, 1e5, 1e5], [-1e6, 1e5, 1e5]):
        with pytest.raises(ValueError, match="pressures_Pa\\[0\\]"):
            arm.settle(model, data, bad)  # NaN was 'settled', the others clamped
    with pytest.raises(ValueError, match="one pressure per actuator"):
        arm.settle(model, data, [1e5, 1e5])


def test_settle_refuses_times_and_step_counts_it_cannot_run():
    """Before: a NaN or negative t_max_s returned 'not settled' without a step, inf ran until the
    step bound; max_steps 0 or -5 warned of 'stopped after 0 steps', 2.5 ran 100 steps."""
    model = arm.build_model(arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT))
    data = mujoco_data(model)
    pressures = [1e5, 1e5, 1e5]
    for bad in (-1.0, float("nan"), float("inf"), "6", None):
        with pytest.raises(ValueError, match=r"arm\.settle: t_max_s must be a finite simulated time >= 0 s"):
            arm.settle(model, data, pressures, t_max_s=bad)
    for bad in (0, -5, 2.5, float("nan"), True, "100"):
        with pytest.raises(
            ValueError, match=r"arm\.settle: max_steps must be a whole number of MuJoCo steps >= 1"
        ):
            arm.settle(model, data, pressures, max_steps=bad)
    assert data.time == 0.0  # refused before a step
    # 0 s (static_equilibrium's data.time + 0 s) and a numpy integer stay allowed
    assert arm.settle(model, data, pressures, t_max_s=0.0, max_steps=np.int64(100)) is False


def test_equilibrium_refuses_a_tip_force_that_is_not_three_finite_newtons(monkeypatch):
    """Before: (0, 0) ended in numpy's 'could not be broadcast', a NaN in scipy's 'y0 must be
    finite', both after the MuJoCo arm was built and settled. Now refused first, by name (the
    ``efam arm`` command has no tip-force flag: it always passes the default)."""
    from efam_mujoco.arm import cli as arm_cli

    def no_build(spec):
        raise AssertionError("the arm was built before tip_force_N was checked")

    monkeypatch.setattr(arm_cli, "build_model", no_build)
    spec = arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT)
    for bad in ((0, 0), (float("nan"), 0.0, 0.0), (0.0, 0.0, float("inf")), [[1.0, 2.0, 3.0]], "xyz", None):
        with pytest.raises(
            ValueError, match=r"equilibrium: tip_force_N must be 3 finite numbers \(x, y, z in N"
        ):
            arm_cli.equilibrium(spec, [[1e5, 1e5, 1e5]], tip_force_N=bad)


def mujoco_data(model):
    import mujoco

    return mujoco.MjData(model)


def test_marker_noise_is_estimated_with_every_other_sample_missing():
    """With no three marked samples in a row the noise floor was NaN ("marker noise nan mm");
    the marked samples in a row give it (white noise of 0.5 mm on a slow circle)."""
    from efam_mujoco.armdiag.locate import noise_floor

    rng = np.random.default_rng(5)
    t = np.arange(600) * 0.02
    tip = np.c_[0.1 * np.cos(0.3 * t), 0.1 * np.sin(0.3 * t), 0.17 + 0 * t] + rng.normal(0, 5e-4, (600, 3))
    full = noise_floor(t, tip)
    tip[1::2] = np.nan
    assert full == pytest.approx(5e-4, rel=0.15) and noise_floor(t, tip) == pytest.approx(5e-4, rel=0.15)


@pytest.mark.parametrize(
    "options, key",
    [
        ({"angles_deg": (0.0, float("nan"), 240.0)}, r"angles_deg\[1\]"),
        ({"angles_deg": (0.0, "120", 240.0)}, r"angles_deg\[1\]"),
        ({"radius_m": "0.02"}, "radius_m"),
        ({"radius_m": float("inf")}, "radius_m"),
        ({"disks": True}, "disks"),
        ({"end_mass_kg": "none"}, "end_mass_kg"),
        ({"disks": 10**400}, "disks"),
    ],
)
def test_a_section_names_the_argument_that_is_not_a_finite_number(options, key):
    # a NaN angle built an arm with a muscle nowhere; a text radius ended in a bare TypeError
    from efam_mujoco import load_muscle

    fam1 = load_muscle("FAM1")
    with pytest.raises(ValueError, match=rf"section: {key} must be"):
        arm.SectionSpec((fam1,) * 3, **options)


def test_a_section_takes_numbers_of_any_numeric_type():
    # numpy scalars, 0-d arrays and Decimals are numbers: stored as plain floats and ints
    from decimal import Decimal

    from efam_mujoco import load_muscle

    fam1 = load_muscle("FAM1")
    section = arm.SectionSpec((fam1,) * 3, radius_m=np.array(0.02), disks=np.int64(4),
                              angles_deg=np.array([0.0, 120.0, 240.0]), end_mass_kg=Decimal("0.01"))  # fmt: skip
    assert section.radius_m == 0.02 and type(section.radius_m) is float and section.disks == 4
    assert section.angles_deg == (0.0, 120.0, 240.0)


def test_arm_refuses_its_pressures_before_it_writes_the_xml(tmp_path, capsys):
    """``efam arm --xml FILE --pressures-kPa`` with the wrong count replaced the user's FILE and
    only then refused the pressures."""
    mine = tmp_path / "arm_prev.xml"
    mine.write_text("<mujoco>my edited arm</mujoco>")
    code, _, err = run_cli(["arm", "--sections", "2", "--disks", "2", "--xml", "arm_prev.xml",
                            "--pressures-kPa", "100", "100", "100"], tmp_path, capsys)  # fmt: skip
    assert code == 2 and "--pressures-kPa: need 6 finite pressures" in err
    assert mine.read_text() == "<mujoco>my edited arm</mujoco>"


def test_a_time_step_no_candidate_makes_stable_is_said_so(tmp_path, capsys):
    """A horizontal arm with 20 kg at its tip, linearised straight at rest (far from where the
    load puts it), is stable at no candidate step; the builder used the smallest and described it
    as "chosen: stable at 2 x itself"."""
    code, out, err = run_cli(["arm", "--orientation", "horizontal", "--payload-kg", "20", "--disks", "2",
                              "--xml", "h.xml"], tmp_path, capsys)  # fmt: skip
    assert code == 0, err
    assert "warning: arm: no candidate time step is stable at 2 x itself" in err
    assert "not stable even at 2 x it" in err and "chosen: stable at" not in err


@pytest.mark.parametrize(
    "key, value, what",
    [("payload_kg", -1.0, r"a mass >= 0 kg"), ("pressure_tau_s", -0.1, r"a time constant >= 0 s"),
     ("timestep_s", 0.0, r"a time step > 0 s"), ("axial_viscosity_N_s", math.nan, r"a damping >= 0 N s")],
)  # fmt: skip
def test_an_arm_key_out_of_range_says_what_it_must_be(key, value, what):
    """'arm: payload_kg is invalid: -1' said neither what nor in which unit it had to be."""
    with pytest.raises(ValueError, match=rf"arm: {key} must be {what} \(finite\), got (-?[0-9.]+|nan)"):
        arm.ArmSpec(sections=(arm.paper_section(),), **{key: value})


@pytest.mark.parametrize(
    "old, new, words",
    [
        # a known muscle written without its unit was 'no muscle of that name in the arm model'
        ("p_s1m1_kPa", "p_s1m1", r"column 2 \('p_s1m1'\): no unit; write e\.g\. 'p_s1m1_kPa'"),
        # a time column without its unit was told to write 'time_m' (metres)
        ("time_s", "Time", r"column 1 \('Time'\): no unit; write e\.g\. 'time_s'"),
        # 'timestamp_s' was read as a time in the unit 'tamp_s'
        ("time_s", "timestamp_s", r"column 1 \('timestamp_s'\): unknown column \(accepted: time_<unit>"),
    ],
)
def test_an_arm_header_without_its_unit_is_named_as_such(lab, tmp_path, old, new, words):
    text = write_csv(tmp_path / "plain.csv", lab[3]).read_text()
    (tmp_path / "bad.csv").write_text(text.replace(old, new, 1))
    with pytest.raises(ArmRecordingError, match=rf"bad\.csv: line 1, {words}"):
        read_csv(tmp_path / "bad.csv", lab[3].muscles)
