"""Bad input found by the blind bad-input review (D1, D3, D8, D9, D11 and the spec file's time
step) in ``efam diagnose-arm``'s arm spec and recording readers and in the sizing catalogue: each
refused with a message naming the file, the key or column and the unit that fits, never a
traceback, never accepted in silence; legitimate input beside each still accepted."""

from __future__ import annotations

import json
import re
import tracemalloc

import numpy as np
import pytest
from _robust import run_bad

from efam_mujoco import arm
from efam_mujoco.armdiag import ArmRecording, load_arm_model, read_csv, save_spec
from efam_mujoco.armdiag.recording import ArmRecordingError, check_against_model
from efam_mujoco.armdiag.specfile import ArmModelError, load_spec, model_limits, spec_to_dict
from efam_mujoco.size.catalogue import CatalogueError, load_catalogue

DT = 4e-3  # the 2-disk arm of tests/test_armdiag.py: fast to build
MUSCLES = ["s1m1", "s1m2", "s1m3"]
HEAD = "time_s,p_s1m1_kPa,p_s1m2_kPa,p_s1m3_kPa,tip_x_m,tip_y_m,tip_z_m"


def _spec_doc() -> dict:
    return spec_to_dict(arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT))


def _write(path, doc):
    path.write_text(json.dumps(doc))
    return path


# ------------------------------------------------------------------ D1: a muscle entry of another type


@pytest.mark.parametrize(
    "entry", [[1], [], None, True, 1.5, 0], ids=["list", "empty", "null", "bool", "float", "int"]
)
def test_an_arm_spec_muscle_that_is_not_a_name_nor_a_document_is_named(tmp_path, entry):
    """Before: a list was an 'internal error' (AttributeError); null, booleans and numbers gave
    Python's own "'NoneType' object is not iterable"."""
    doc = _spec_doc()
    doc["sections"][0]["muscles"][1] = entry
    path = _write(tmp_path / "arm.json", doc)
    with pytest.raises(ArmModelError) as err:
        load_spec(path)
    assert str(err.value) == (
        f"{path}: sections[0].muscles[1]: must be a preset name, a muscle-file path or a muscle document "
        f"(a JSON object), got {json.dumps(entry)}"
    )


def test_diagnose_arm_names_a_muscle_entry_that_is_a_list(tmp_path, capsys):
    doc = _spec_doc()
    doc["sections"][0]["muscles"][0] = [1]
    _write(tmp_path / "arm.json", doc)
    (tmp_path / "rec.csv").write_text(HEAD + "\n0,100,100,100,0,0,0.2\n0.1,100,100,100,0,0,0.2\n")
    run_bad(["diagnose-arm", "--model", "arm.json", "--threads", "1", "rec.csv"], tmp_path, capsys,
            r"arm\.json: sections\[0\]\.muscles\[0\]: must be a preset name, a muscle-file path or a muscle "
            r"document \(a JSON object\), got \[1\]")  # fmt: skip


def test_an_arm_spec_muscle_given_as_preset_name_is_still_read(tmp_path):
    doc = _spec_doc()
    doc["sections"][0]["muscles"] = ["FAM1", "FAM1", "FAM1"]
    assert len(load_spec(_write(tmp_path / "arm.json", doc)).sections[0].muscles) == 3


# ------------------------------------------------------------------ D8: the arm's name in the MJCF


@pytest.mark.parametrize(
    "escaped, code", [(r"a\u001b[2Jb", "U+001B"), (r"a\ud800b", "U+D800"), (r"a\nb", "U+000A")]
)
def test_an_arm_name_that_is_not_text_is_refused_as_in_a_muscle_file(tmp_path, escaped, code):
    """Before: a control character in the arm's name went verbatim into the MJCF's model="...",
    which XML tools then refused as not well-formed; a muscle file's name is refused for it."""
    text = json.dumps(_spec_doc()).replace('"name": "efam_arm"', f'"name": "{escaped}"', 1)
    assert escaped in text
    path = tmp_path / "arm.json"
    path.write_text(text)
    with pytest.raises(ArmModelError) as err:
        load_spec(path)
    assert str(err.value) == (
        f"{path}: key 'name' holds the character {code}, which is not text (a control character or half a "
        "surrogate pair)"
    )


def test_an_arm_name_with_xml_special_characters_is_still_accepted(tmp_path):
    doc = _spec_doc()
    doc["name"] = 'arm "<1> & 2"'
    assert load_spec(_write(tmp_path / "arm.json", doc)).name == 'arm "<1> & 2"'


# ------------------------------------------------------------------ the spec file's time step


def test_an_unstable_time_step_names_the_spec_file(tmp_path, capsys):
    """Before: 'arm: timestep_s = 4 ms is unstable for this arm', naming no file."""
    doc = _spec_doc()
    doc["sections"][0]["plate_mass_kg"] = 50  # grams written as kg: the fixed 4 ms step diverges
    path = _write(tmp_path / "heavy.json", doc)
    with pytest.raises(
        ArmModelError, match=r"heavy\.json: timestep_s = 4 ms is unstable for this arm"
    ) as err:
        load_arm_model(path)
    assert "arm: timestep_s" not in str(err.value)
    # ... saying which test failed: the limit it quotes (9.11 ms) is above 4 ms, each mode alone
    assert re.search(
        r"each mode alone allows up to [\d.]+ ms, but the step map of the modes together", str(err.value)
    )
    (tmp_path / "rec.csv").write_text(HEAD + "\n0,100,100,100,0,0,0.2\n0.1,100,100,100,0,0,0.2\n")
    run_bad(["diagnose-arm", "--model", "heavy.json", "--threads", "1", "rec.csv"], tmp_path, capsys,
            r"error: heavy\.json: timestep_s = 4 ms is unstable")  # fmt: skip


# ------------------------------------------------------------------ D3: one command column in bar or MPa

MAX_PA = 517106.8  # the paper arm's rated pressure (each muscle's control range)
BASE = np.zeros(3)
REACH = 0.2


def _recording(commands_kPa: np.ndarray, source="rec.csv") -> ArmRecording:
    """A 6 s recording at 40 Hz whose tip moves about 0.2 m from the base (every reach check
    passes), commands as written under 'kPa' headers."""
    n = len(commands_kPa)
    t = np.arange(n) / 40.0
    tip = np.column_stack([0.02 * np.sin(t), 0.02 * np.cos(t), 0.2 + 0.01 * np.sin(2 * t)])
    return ArmRecording(t, MUSCLES, commands_kPa * 1e3, tip,
                        meta={"source": source, "command_columns": [f"p_{m}_kPa" for m in MUSCLES]})  # fmt: skip


def _commands(n=240) -> np.ndarray:
    """Ramps between 50 and 450 kPa, one phase per muscle (the usual test)."""
    t = np.arange(n) / 40.0
    return np.column_stack([250 + 200 * np.sin(0.7 * t + k) for k in range(3)])


@pytest.mark.parametrize("unit, divisor", [("bar", 100.0), ("MPa", 1000.0)])
def test_one_command_column_in_bar_or_mpa_under_a_kpa_header_is_refused(unit, divisor):
    """Before: only the largest command of all muscles was held to MIN_COMMAND_SHARE, so one
    column in bar passed, and the diagnosis named a wrong cause (muscle friction)."""
    commands = _commands()
    commands[:, 1] /= divisor
    with pytest.raises(ArmRecordingError) as err:
        check_against_model(_recording(commands), [MAX_PA] * 3, BASE, REACH)
    text = str(err.value)
    assert text.startswith("rec.csv: column 'p_s1m2_kPa': muscle s1m2's largest command is "), text
    assert "under 5% of the model's highest pressure 517.107 kPa" in text
    assert text.endswith(f"was it {unit}? the numbers fit 'p_s1m2_{unit}'"), text


def test_diagnose_arm_refuses_one_command_column_in_bar(tmp_path, capsys):
    model = save_spec(
        tmp_path / "arm.json", arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT)
    )
    limits = model_limits(load_arm_model(model))
    commands = _commands()
    commands[:, 0] /= 100.0
    t = np.arange(len(commands)) / 40.0
    tip = limits["base_m"] + [0.0, 0.0, limits["rest_reach_m"]] + 0.01 * np.sin(t)[:, None]
    rows = [",".join(f"{v:.6g}" for v in row) for row in np.column_stack([t, commands, tip])]
    (tmp_path / "bar.csv").write_text(HEAD + "\n" + "\n".join(rows) + "\n")
    run_bad(["diagnose-arm", "--model", "arm.json", "--threads", "1", "bar.csv"], tmp_path, capsys,
            r"bar\.csv: column 'p_s1m1_kPa': muscle s1m1's largest command is 4\.\d+ kPa",
            r"was it bar\? the numbers fit 'p_s1m1_bar'")  # fmt: skip


@pytest.mark.parametrize(
    "column",
    [
        np.zeros(240),  # an idle muscle
        np.full(240, 5.0),  # a held bias pressure below the dead band
        10 + 10 * np.sin(np.arange(240) / 10),  # a muscle driven little (0 .. 20 kPa): no decade fits
        (250 + 200 * np.sin(np.arange(240) / 10)) / 6.894757,  # psi: 6.9 x, left to the replay
        # an idle muscle whose pressure is logged as its command: a regulator's 0-4 kPa jitter,
        # which read in bar (0-400 kPa) would sit among the others' 50-450 kPa
        np.abs(np.random.default_rng(3).normal(0.0, 1.2, 240)),
    ],
    ids=["idle", "bias", "little", "psi", "jitter"],
)
def test_a_little_used_muscle_is_not_taken_for_a_unit_mix_up(column):
    commands = _commands()
    commands[:, 2] = column
    assert check_against_model(_recording(commands), [MAX_PA] * 3, BASE, REACH) == []


def test_a_column_in_bar_with_a_transducers_noise_is_still_refused():
    """The jitter test reads noise about zero, not a signal in bar with a little noise on it."""
    commands = _commands()
    commands[:, 1] = commands[:, 1] / 100.0 + np.random.default_rng(4).normal(0.0, 0.02, 240)
    with pytest.raises(ArmRecordingError, match=r"column 'p_s1m2_kPa'.*was it bar\?"):
        check_against_model(_recording(commands), [MAX_PA] * 3, BASE, REACH)


def test_an_arm_model_whose_tip_is_held_is_refused(tmp_path):
    """Before: a spec with hold_tip true (a blocked-force fixture) was replayed with its tip
    welded in place, and a tip that moved 120 mm came back 'none ... UNEXPLAINED'."""
    held = arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT, hold_tip=True)
    model = save_spec(tmp_path / "arm.json", held)
    with pytest.raises(ArmModelError, match=r"arm\.json: body '\w+' is welded to 'base' \(equality 'hold_tip'\): "
                       r"a held tip cannot follow a recording"):  # fmt: skip
        load_arm_model(model)


@pytest.mark.parametrize("name", ["arm.csv", "arm.yaml", "arm"])
def test_an_arm_model_of_another_kind_is_named_as_such(tmp_path, name):
    """Before: MuJoCo's parser said 'not a usable MJCF: could not find decoder for resource'."""
    (tmp_path / name).write_text("time_s,p_s1m1_kPa\n0,0\n")
    with pytest.raises(
        ArmModelError, match=r"an arm model is a spec file \(\.json.* or an MJCF \(\.xml\), not a"
    ):
        load_arm_model(tmp_path / name)


def test_diagnose_arm_refuses_a_spec_whose_top_pressure_is_within_the_dead_band(tmp_path, capsys):
    """Before: max_pressure_Pa 517.1 (kPa written as Pa) was only warned of; the recording's
    commands were then blamed ('was it Pa?'), and renamed to Pa they replayed as an arm at rest."""
    doc = spec_to_dict(arm.ArmSpec(sections=(arm.paper_section(disks=2),), timestep_s=DT))
    doc["max_pressure_Pa"] = 517.1
    (tmp_path / "arm.json").write_text(json.dumps(doc))
    t = np.arange(40) / 40.0
    rows = [f"{x:.4g},{100 * x:.4g},0,0,0,0,0.2" for x in t]
    (tmp_path / "rec.csv").write_text(HEAD + "\n" + "\n".join(rows) + "\n")
    run_bad(["diagnose-arm", "--model", "arm.json", "--threads", "1", "rec.csv"], tmp_path, capsys,
            r"arm\.json: arm: max_pressure_Pa = 517\.1 Pa is within every muscle's dead band",
            r"is it in kPa\? \(the key is in Pa\)")  # fmt: skip


def test_every_column_in_mpa_still_gets_the_whole_recording_message():
    with pytest.raises(
        ArmRecordingError, match=r"the largest command of any muscle is 0\.\d+ kPa.*'p_s1m\d_MPa'"
    ):
        check_against_model(_recording(_commands() / 1000.0), [MAX_PA] * 3, BASE, REACH)


# ------------------------------------------------------------------ D11: the arm reader streams


def _long_csv(path, rows: int):
    t = np.arange(rows) / 100.0
    commands = _commands(rows)
    tip = np.column_stack([0.01 * np.sin(t), 0.01 * np.cos(t), 0.2 + 0.005 * np.sin(t)])
    with path.open("w") as out:
        out.write(HEAD + "\n")
        for row in np.column_stack([t, commands, tip]):
            out.write(",".join(f"{v:.6g}" for v in row) + "\n")
    return path


def test_the_arm_reader_streams_a_long_recording(tmp_path):
    """Before: every row was kept as a list of strings (about 800 bytes a row) before any check,
    so a multi-GB log could run out of memory before its duration was refused."""
    rows = 20_000
    path = _long_csv(tmp_path / "long.csv", rows)
    read_csv(path, MUSCLES)  # warm: the first read imports and caches
    tracemalloc.start()
    try:
        rec = read_csv(path, MUSCLES)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(rec) == rows and rec.meta["lines"][-1] == rows + 1
    assert peak / rows < 200, f"{peak / rows:.0f} bytes a row"


def test_the_streaming_arm_reader_keeps_its_messages_and_line_numbers(tmp_path):
    def read(text):
        path = tmp_path / "rec.csv"
        path.write_text(text)
        return read_csv(path, MUSCLES)

    # comments and blank lines count: the bad row's file line is named
    with pytest.raises(
        ArmRecordingError, match=r"rec\.csv: line 5, column 1 \('time_s'\): time not increasing"
    ):
        read(f"# a test\n{HEAD}\n\n0,1,1,1,0,0,0.2\n0,1,1,1,0,0,0.2\n0.2,1,1,1,0,0,0.2\n")
    # a bad cell after a time going backwards: the cell is named first, as before
    with pytest.raises(ArmRecordingError, match=r"line 4, column 3 \('p_s1m2_kPa'\): not a number"):
        read(f"{HEAD}\n0.1,1,1,1,0,0,0.2\n0,1,1,1,0,0,0.2\n0.2,1,x,1,0,0,0.2\n")
    # one data row, even a bad one, is too few
    with pytest.raises(ArmRecordingError, match=r"rec\.csv: fewer than 2 data rows"):
        read(f"{HEAD}\n0,1,x,1,0,0,0.2\n")
    with pytest.raises(ArmRecordingError, match=r"line 2, column 3 \('p_s1m2_kPa'\): not a number"):
        read(f"{HEAD}\n0,1,x,1,0,0,0.2\n0.1,1,1,1,0,0,0.2\n")
    with pytest.raises(ArmRecordingError, match=r"rec\.csv: no header line"):
        read("# only a comment\n\n")
    rec = read(f"{HEAD}\n# mid\n0,1,1,1,,,\n\n0.1,1,2,3,0,0,0.2\n")
    assert list(rec.meta["lines"]) == [3, 5] and np.isnan(rec.tip_m[0]).all()
    assert rec.command_Pa[1].tolist() == [1e3, 2e3, 3e3]


# ------------------------------------------------------------------ D9: a sleeve's reference diameter


def _catalogue_doc() -> dict:
    from importlib import resources

    return json.loads(resources.files("efam_mujoco.size").joinpath("catalogue.json").read_text())


@pytest.mark.parametrize("factor", [4.0, 1 / 4.0])
def test_a_sleeve_reference_diameter_outside_its_range_is_refused(tmp_path, capsys, factor):
    """Before: a reference diameter 4 x the sleeve's largest diameter was sized with."""
    doc = _catalogue_doc()
    sleeve = doc["sleeves"][0]
    sleeve["reference_diameter_in"] = (
        sleeve["max_diameter_in"] if factor > 1 else sleeve["min_diameter_in"]
    ) * factor
    path = _write(tmp_path / "cat.json", doc)
    pattern = (
        r"cat\.json: sleeves\[0\] \('PET expandable 1/8 in'\): key 'reference_diameter_in' = .* lies outside the "
        r"sleeve's diameter range 'min_diameter_in' \.\. 'max_diameter_in' \(1\.5875 \.\. 6\.35 mm"
    )
    with pytest.raises(CatalogueError, match=pattern):
        load_catalogue(path)
    run_bad(["size", "--stroke", "0.5", "--force", "20", "--pressure", "300", "--top", "1", "--catalogue",
             "cat.json"], tmp_path, capsys, pattern)  # fmt: skip


def test_the_built_in_catalogue_still_loads():
    # the paper's Kevlar sleeve: D_45 1.905 cm by the project's convention, drawn tight on 2.22 cm
    kevlar = [s for s in load_catalogue().sleeves if "Kevlar" in s.name]
    assert kevlar and kevlar[0].reference_diameter_m < kevlar[0].min_diameter_m


@pytest.mark.parametrize("threads", ["0", "100000", "-2", "1.5"])
def test_threads_are_bounded(tmp_path, capsys, threads):
    """100000 rollout threads were taken without a word (each holds a copy of MuJoCo's data)."""
    run_bad(["diagnose-arm", "--model", "arm.json", "--threads", threads, "rec.csv"], tmp_path, capsys,
            r"argument --threads: ")  # fmt: skip


# ------------------------------------------- the spec's pressure key in any unit; angles in one turn
@pytest.mark.parametrize(
    "key, value", [("max_pressure_Pa", 517106.8), ("max_pressure_kPa", 517.1068), ("max_pressure_psi", 75.0),
                   ("max_pressure_bar", 5.171068), ("max_pressure_MPa", 0.5171068)],
)  # fmt: skip
def test_an_arm_spec_takes_its_top_pressure_in_any_pressure_unit(tmp_path, key, value):
    """`max_pressure_kPa` was 'unknown key(s)' while a muscle file takes any pressure unit in a key's
    name."""
    doc = _spec_doc()
    del doc["max_pressure_Pa"]
    doc[key] = value
    spec = load_spec(_write(tmp_path / "arm.json", doc))
    assert spec.max_pressure_Pa == pytest.approx(517106.8, rel=1e-6)


@pytest.mark.parametrize(
    "extra, words",
    [
        ({"max_pressure_kpa": 500}, r"key 'max_pressure_kpa': unknown pressure unit 'kpa' \(known: .*kPa.*\); "
                                    r"units are case-sensitive: did you mean 'kPa'\?"),
        ({"max_pressure_atm": 5}, r"key 'max_pressure_atm': unknown pressure unit 'atm'"),
        ({"max_pressure": 500}, r"key 'max_pressure' has no unit; write e\.g\. 'max_pressure_Pa'"),
        ({"max_pressure_kPa": 500, "max_pressure_psi": 75}, r"max_pressure given twice"),
        ({"max_pressure_kPa": "500"}, r"key 'max_pressure_kPa' must be a finite number, got \"500\""),
        ({"max_pressure_kPa": 20000}, r"key 'max_pressure_kPa' = 20000 is outside 1e-12 \.\. 10000 kPa"),
        ({"max_pressure_psi": 2}, r"key 'max_pressure_psi' = 2 psi is within every muscle's dead band "
                                  r"\(the lowest, FAM1's, ends at 4\.876 psi\)"),
    ],
)  # fmt: skip
def test_an_arm_spec_pressure_key_is_read_as_strictly_as_a_muscle_files(tmp_path, extra, words):
    doc = _spec_doc()
    del doc["max_pressure_Pa"]
    doc.update(extra)
    path = _write(tmp_path / "arm.json", doc)
    with pytest.raises(ArmModelError, match=rf"^{re.escape(str(path))}: {words}"):
        load_spec(path)


def test_diagnose_arm_names_an_unknown_pressure_unit_in_the_spec(tmp_path, capsys):
    doc = _spec_doc()
    doc["max_pressure_KPA"] = doc.pop("max_pressure_Pa") / 1e3
    _write(tmp_path / "arm.json", doc)
    (tmp_path / "rec.csv").write_text(HEAD + "\n0,100,100,100,0,0,0.2\n0.1,100,100,100,0,0,0.2\n")
    run_bad(["diagnose-arm", "--model", "arm.json", "--threads", "1", "rec.csv"], tmp_path, capsys,
            r"arm\.json: key 'max_pressure_KPA': unknown pressure unit 'KPA'.*did you mean 'kPa'\?")  # fmt: skip


@pytest.mark.parametrize("angle", [1e308, -1e308, 360.5, -720.0])
def test_an_arm_spec_angle_beyond_one_turn_is_refused_when_read(tmp_path, angle):
    """`angles_deg` [0, 1e308, 240] was read and failed later on 'muscles 0 and 1 overlap'."""
    doc = _spec_doc()
    doc["sections"][0]["angles_deg"] = [0.0, angle, 240.0]
    path = _write(tmp_path / "arm.json", doc)
    with pytest.raises(ArmModelError) as err:
        load_spec(path)
    assert str(err.value) == (
        f"{path}: sections[0]: section: angles_deg[1] = {angle!r} is outside -360 .. 360 deg (a muscle's "
        "angular position around the section's axis)"
    )
    with pytest.raises(ValueError, match=r"angles_deg\[1\] = .* is outside -360 \.\. 360 deg"):
        arm.paper_section(disks=2, angles_deg=(0.0, angle, 240.0))


def test_an_arm_spec_angle_within_one_turn_either_way_is_still_read(tmp_path):
    doc = _spec_doc()
    doc["sections"][0]["angles_deg"] = [-360.0, -240.0, 360.0 - 120.0]
    assert load_spec(_write(tmp_path / "arm.json", doc)).sections[0].angles_deg == (-360.0, -240.0, 240.0)
