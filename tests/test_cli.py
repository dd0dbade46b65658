"""The efam command line: efam muscle, efam demo, and clear errors on bad input."""

import json

import pytest

from efam_mujoco.cli import main


def test_muscle_json_keys(tmp_path, capsys):
    out = tmp_path / "fam1.json"
    assert (
        main(
            ["muscle", "FAM1", "--stress", "linear", "--pressures-kPa", "103.4", "517.1", "--json", str(out)]
        )
        == 0
    )
    doc = json.loads(out.read_text())
    for key in ("theta_rest_deg", "turns", "thread_length_m", "bladder_volume_m3", "rows"):
        assert key in doc
    assert doc["theta_rest_deg"] == pytest.approx(12.54, abs=0.005)
    row = doc["rows"][1]
    assert row["pressure_kPa"] == pytest.approx(517.1)
    # blocked force positive = push; MuJoCo beside the analytic value
    assert row["blocked_force_N"]["analytic"] == pytest.approx(281.8, abs=0.5)
    assert row["blocked_force_N"]["mujoco"] == pytest.approx(row["blocked_force_N"]["analytic"], rel=0.005)
    assert row["free_extension"]["mujoco"] == pytest.approx(row["free_extension"]["analytic"], rel=0.005)
    assert "517.1" in capsys.readouterr().out


def test_demo_writes_figure_and_table(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    figure = tmp_path / "force_stroke_fam1.png"
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(json.loads((tmp_path / "demo.json").read_text())["rows"]) == 5


@pytest.mark.parametrize(
    "argv, message",
    [
        (["muscle", "FAM9"], "neither a preset"),
        (["muscle", "FAM1", "--pressures-kPa", "-5"], "--pressures-kPa"),
        (["muscle", "FAM1", "--stress", "sigmoid"], "no coefficients for stress law 'sigmoid'"),
    ],
)
def test_bad_input_is_one_clear_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_arm_tip_mujoco_beside_statics(tmp_path, capsys):
    out, xml = tmp_path / "arm.json", tmp_path / "arm.xml"
    argv = ["arm", "--no-gravity", "--pressure-lag-s", "0", "--pressures-kPa", "400", "250", "250"]
    assert main([*argv, "--json", str(out), "--xml", str(xml)]) == 0
    doc = json.loads(out.read_text())
    assert doc["settled"] and doc["difference_pct_of_rest_length"] < 2.0
    assert doc["tip_mujoco_m"][0] < 0  # the higher-pressure muscle at 0 deg pushes the tip to -x
    assert "efam.muscle" in xml.read_text()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["arm", "--pressures-kPa", "100", "200"], "need 3 finite pressures"),
        (["arm", "--muscles-per-section", "2", "--xml", "x.xml"], "--muscles-per-section"),
        (["arm", "--muscle", "FAM1", "FAM2", "--xml", "x.xml"], "--muscle: give 1 muscle or one per muscle"),
        (["arm"], None),
    ],
)
def test_arm_bad_input(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert (message or "nothing to do") in err and "Traceback" not in err
