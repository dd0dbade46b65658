"""Bad inputs an outside review of the CLI found handled wrongly (each case failed before its fix):
a compressed or binary recording blamed on line endings, a two-row file called a dead load cell,
a copy saved again accepted as a second test, a unit mix-up followed by findings whose hints point
at good columns, a pressure-stiffening coefficient that no rubber has, and a geometry that makes
the rig unsettleable reported without the file or the cause."""

from __future__ import annotations

import gzip
import json

import numpy as np
import pytest
from _robust import csv_text, run_bad
from test_robust_recordings import HEADER, good_rows

from efam_mujoco.musclefile import load_muscle, read_document
from efam_mujoco.recordings import Recording, RecordingError, check_plausibility, refuse_copies


def _write(folder, name: str, content) -> str:
    (folder / name).write_bytes(content.encode() if isinstance(content, str) else content)
    return name


# ------------------------------------------------------------------ not a text recording
def test_a_compressed_recording_is_named_compressed_not_old_mac_line_endings(tmp_path, capsys):
    packed = gzip.compress(csv_text(good_rows(), HEADER).encode(), mtime=0)
    assert b"\r" in packed.split(b"\n")[0]  # the stray CR that was read as a line ending
    for name in ("rec.csv", "rec.csv.gz"):
        name = _write(tmp_path, name, packed)
        err = run_bad(
            ["diagnose", name, "--muscle", "FAM1"], tmp_path, capsys, rf"{name}: a gzip-compressed file"
        )
        assert "carriage return" not in err


def test_a_binary_recording_names_its_first_byte_that_is_not_text(tmp_path, capsys):
    # bytes that are not UTF-8 with a CR among them (no NUL): the byte is named, not the line ending
    name = _write(tmp_path, "rec.csv", b"time_s,length_m\xff\xfe\r,pressure_kPa,force_N\n1,2,3,4\n")
    err = run_bad(
        ["diagnose", name, "--muscle", "FAM1"], tmp_path, capsys, r"line 1, column 16: byte 0xff is not UTF-8"
    )
    assert "carriage return" not in err
    name = _write(tmp_path, "nul.csv", b"time_s,length_m,pressure_kPa,force_N\n0,0.17\x00,100,5\n")
    run_bad(
        ["diagnose", name, "--muscle", "FAM1"], tmp_path, capsys, r"nul\.csv: line 2, column 7: a NUL byte"
    )


# ---------------------------------------------------------------------------- too short
def test_a_two_row_recording_is_too_short_not_a_dead_load_cell(tmp_path, capsys):
    # any two rows hold at most two force values: the 'dead load cell' test read that as dead
    name = _write(tmp_path, "rec.csv", csv_text(good_rows()[[0, 20]], HEADER))
    err = run_bad(
        ["diagnose", name, "--muscle", "FAM1"],
        tmp_path,
        capsys,
        r"rec\.csv: too few samples to diagnose \(2\)",
    )
    assert "force-dead" not in err


# ------------------------------------------------------------------------ the same test twice
def _recording(rows, source) -> Recording:
    return Recording(rows[:, 0], rows[:, 1], rows[:, 2] * 1e3, rows[:, 3], meta={"source": source})


@pytest.mark.parametrize(
    "how",
    ["six significant digits", "clock shifted by 1000 s", "as a displacement in mm"],
)
def test_a_copy_saved_again_is_refused_as_a_second_recording(tmp_path, capsys, how):
    rows = good_rows()
    _write(tmp_path, "a.csv", csv_text(rows, HEADER))
    rest = load_muscle("FAM1").rest_length_m
    if how == "six significant digits":
        copy = "\n".join([HEADER] + [",".join(f"{v:.6g}" for v in r) for r in rows]) + "\n"
    elif how == "clock shifted by 1000 s":
        copy = csv_text(rows + np.array([1000.0, 0, 0, 0]), HEADER)
    else:
        shifted = rows.copy()
        shifted[:, 1] = (rows[:, 1] - rest) * 1e3
        copy = csv_text(shifted, "time_s,displacement_mm,pressure_kPa,force_N")
    _write(tmp_path, "b.csv", copy)
    run_bad(["diagnose", "a.csv", "b.csv", "--muscle", "FAM1"], tmp_path, capsys,
            r"b\.csv: the same samples as a\.csv to within", r"count twice")  # fmt: skip


def test_two_recordings_of_one_protocol_that_differ_by_their_noise_are_two_tests():
    rows = good_rows()
    noise = np.random.default_rng(3).normal(0.0, 0.05, len(rows))  # 0.05 N: a quiet load cell
    second = rows.copy()
    second[:, 3] += noise
    refuse_copies([_recording(rows, "a.csv"), _recording(second, "b.csv")])  # no error
    with pytest.raises(RecordingError, match="the same samples"):
        refuse_copies([_recording(rows, "a.csv"), _recording(rows + np.array([5.0, 0, 0, 0]), "b.csv")])


# ------------------------------------------------------------ one unit mix-up, one finding
def _findings(tmp_path, rows, header=HEADER):
    from efam_mujoco.recordings import read_csv

    path = tmp_path / "rec.csv"
    path.write_text(csv_text(rows, header))
    return check_plausibility([read_csv(path)], load_muscle("FAM1"))


def test_pressures_in_pa_under_a_kpa_header_give_one_finding_and_no_blame_on_the_load_cell(tmp_path):
    rows = good_rows().copy()
    rows[:, 2] *= 1e3
    # before: also 'force-unit' (the numbers fit force_kN) and 'force-dead' against a good load cell
    assert [f.check for f in _findings(tmp_path, rows)] == ["pressure-range"]


def test_one_pressure_spike_is_not_offered_a_unit(tmp_path):
    rows = good_rows().copy()
    rows[100, 2] = 9e5
    found = _findings(tmp_path, rows)
    assert [f.check for f in found] == ["pressure-range"]
    assert "the numbers fit" not in found[0].message and "1 of" in found[0].message


def test_lengths_in_mm_under_a_metre_header_give_no_clock_or_sign_findings(tmp_path):
    rows = good_rows().copy()
    rows[:, 1] *= 1e3
    # before: also 'time-unit' (stroked at 5 m/s: the numbers fit time_min) and 'force-sign'
    assert [f.check for f in _findings(tmp_path, rows)] == ["length-unit"]


# ------------------------------------------------------------------------- muscle files
def _fam1_with(tmp_path, edit) -> str:
    doc, _ = read_document("FAM1")
    doc = json.loads(json.dumps(doc))
    edit(doc)
    (tmp_path / "m.json").write_text(json.dumps(doc))
    return "m.json"


@pytest.mark.parametrize("e2", [1000.0, 1e6, 1e10])
def test_a_pressure_stiffening_no_rubber_has_is_refused_naming_the_key(tmp_path, capsys, e2):
    name = _fam1_with(tmp_path, lambda d: d["stress"]["laws"]["linear"].update(E2=e2))
    run_bad(["muscle", name, "--pressures-kPa", "100"], tmp_path, capsys,
            r"m\.json: stress law 'linear': coefficient 'E2'", r"cannot be physical", r"dimensionless")  # fmt: skip


def test_a_plausible_pressure_stiffening_is_accepted(tmp_path):
    from efam_mujoco.musclefile import load_muscle as load

    name = _fam1_with(tmp_path, lambda d: d["stress"]["laws"]["linear"].update(E2=20.0))
    assert load(tmp_path / name, "linear").stress.coefficients[1] == 20.0  # (E1_Pa, E2)


def test_a_geometry_the_rig_cannot_settle_names_the_file_the_cause_and_kilopascals(tmp_path, capsys):
    # a braid angle at rest of 74 deg given as a constant: a contractile muscle the rig cannot settle
    def contractile(doc):
        del doc["geometry"]
        doc["constants"] = {"rest_length_m": 0.17018, "rest_diameter_m": 0.03014, "theta_rest_deg": 74.0,
                            "bladder_volume_m3": 1.8858e-05}  # fmt: skip

    name = _fam1_with(tmp_path, contractile)
    run_bad(["muscle", name, "--pressures-kPa", "300"], tmp_path, capsys,
            r"m\.json: muscle 'FAM1': the rig did not settle", r"at 300 kPa", r"braid angle at rest is 74\.\d deg",
            r"contracts under pressure")  # fmt: skip


def test_a_sleeve_typed_ten_times_too_wide_is_refused_before_the_rig(tmp_path, capsys):
    # a sleeve of 30 cm typed for 3 cm (it made a 74 deg braid the rig could not settle): no
    # fluidic muscle is that wide, and the file is refused naming the key, the range and the unit
    name = _fam1_with(tmp_path, lambda d: d["geometry"].update(sleeve_diameter_ref_m=0.3))
    run_bad(["muscle", name, "--pressures-kPa", "300"], tmp_path, capsys,
            r"m\.json: geometry: key 'sleeve_diameter_ref_m' = 0\.3 cannot be physical", r"0\.0001 \.\. 0\.2 m",
            r"was it in cm")  # fmt: skip
