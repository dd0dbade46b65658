"""Muscle files: presets load, round trips keep the physics, bad files say what is wrong."""

import json

import pytest

from efam_mujoco import MuscleFileError, load_muscle, save_muscle
from efam_mujoco.musclefile import available_laws


def test_presets_carry_all_four_table4_laws():
    for name in ("FAM1", "fam2"):
        assert set(available_laws(name)) == {"linear", "polynomial", "exponential_decay", "exponent"}


def test_round_trip_keeps_forces(tmp_path):
    muscle = load_muscle("fam2", "exponent")
    path = save_muscle(tmp_path / "m.json", muscle)
    again = load_muscle(path)
    assert again.stress == muscle.stress
    assert again.tension(3e5, 0.25) == pytest.approx(muscle.tension(3e5, 0.25), rel=1e-14)


def _write(tmp_path, doc):
    path = tmp_path / "muscle.json"
    path.write_text(json.dumps(doc))
    return path


def _base():
    return {
        "format": "efam_mujoco.muscle/1",
        "constants": {
            "rest_length_m": 0.17,
            "rest_diameter_cm": 2.87,
            "theta_rest_deg": 12.5,
            "bladder_volume_L": 0.017,
        },
        "deadband_kPa": 33.6,
        "stress": {"default": "linear", "laws": {"linear": {"E1_Pa": 1.7e6, "E2": 1.5}}},
    }


def test_one_law_needs_no_default(tmp_path):
    doc = _base()
    doc["stress"].pop("default")
    assert load_muscle(_write(tmp_path, doc)).stress.name == "linear"


def test_units_in_keys_are_converted(tmp_path):
    muscle = load_muscle(_write(tmp_path, _base()))
    assert muscle.rest_diameter_m == pytest.approx(0.0287)
    assert muscle.bladder_volume_m3 == pytest.approx(1.7e-5)
    assert muscle.deadband_Pa == pytest.approx(33.6e3)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: d["constants"].pop("rest_length_m"), "rest_length"),
        (lambda d: d.pop("deadband_kPa"), "deadband_<unit>"),
        (lambda d: d.update(deadband=30), "'deadband' has no unit"),
        (
            lambda d: d["constants"].update(rest_length_furlong=d["constants"].pop("rest_length_m")),
            "unknown length unit",
        ),
        (lambda d: d["constants"].update(rest_length_m=-0.17), "rest_length_m"),
        (lambda d: d["stress"].update(default="ogden"), "no coefficients for stress law 'ogden'"),
        (lambda d: d["stress"]["laws"]["linear"].pop("E2"), "missing coefficient key 'E2'"),
        (
            # two laws and none named: the first one written is not a choice the file made
            lambda d: (
                d["stress"].pop("default")
                and d["stress"]["laws"].update(
                    polynomial={"E1_Pa": 2.4e6, "E2": 2.0, "E3_Pa": -1.8e6, "E4_Pa": 1.2e6}
                )
            ),
            r"2 laws \(linear, polynomial\) and no 'default'",
        ),
        (lambda d: d.update(format="other"), "'format'"),
        (lambda d: d["constants"].update(theta_rest_deg="twelve"), "theta_rest_deg"),
    ],
)
def test_bad_files_name_the_problem(tmp_path, edit, message):
    doc = _base()
    edit(doc)
    with pytest.raises(MuscleFileError, match=message):
        load_muscle(_write(tmp_path, doc))


def test_not_json_and_missing_file(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text("{not json")
    with pytest.raises(MuscleFileError, match="not valid JSON"):
        load_muscle(path)
    with pytest.raises(MuscleFileError, match="neither a preset"):
        load_muscle(tmp_path / "absent.json")


@pytest.mark.parametrize("thickness_m, ok", [(0.0, True), (5e-5, True), (0.0001524, True), (5e-6, False)])
def test_thread_thickness_from_a_fine_filament_up(tmp_path, thickness_m, ok):
    """0 (no thickness modelled) passed while a real 50 um thread was refused by the 0.1 mm
    floor of the other sizes; a thread is now plausible from 10 um up."""
    from efam_mujoco.musclefile import read_document

    doc, _ = read_document("FAM1")
    doc["geometry"]["thread_thickness_m"] = thickness_m
    if ok:
        assert load_muscle(_write(tmp_path, doc)).thread_length_m > 0
    else:
        with pytest.raises(MuscleFileError, match=r"thread_thickness_m.*cannot be physical.*expected 1e-05"):
            load_muscle(_write(tmp_path, doc))


@pytest.mark.parametrize(
    "edit, shown",
    [
        (lambda d: d.update(deadband_kPa=None), r"key 'deadband_kPa' must be a finite number, got null"),
        (lambda d: d.update(deadband_kPa="33"), r"key 'deadband_kPa' must be a finite number, got \"33\""),
        (lambda d: d.pop("format"), r"key 'format' must be 'efam_mujoco.muscle/1', got null"),
    ],
)
def test_values_are_shown_as_the_file_wrote_them(tmp_path, edit, shown):
    """JSON's null was shown as Python's None, a string with Python's quotes."""
    doc = _base()
    edit(doc)
    with pytest.raises(MuscleFileError, match=shown):
        load_muscle(_write(tmp_path, doc))
