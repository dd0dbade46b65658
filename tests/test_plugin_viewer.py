"""``efam view``: compiles a model with the efam.muscle plugin loaded (headless via --check)."""

from __future__ import annotations

import pytest

from efam_mujoco import load_muscle
from efam_mujoco.cli import main
from efam_mujoco.plugin import config_xml

MODEL = """<mujoco model="two_muscles">
  <extension><plugin plugin="efam.muscle"/></extension>
  <worldbody>
    <site name="o1"/><site name="o2" pos="0.2 0 0"/>
    <body pos="0 0 0.17"><joint type="slide" axis="0 0 1"/><geom size="0.01"/><site name="e1"/></body>
    <body pos="0.2 0 0.17"><joint type="slide" axis="0 0 1"/><geom size="0.01"/><site name="e2"/></body>
  </worldbody>
  <tendon>
    <spatial name="t1"><site site="o1"/><site site="e1"/></spatial>
    <spatial name="t2"><site site="o2"/><site site="e2"/></spatial>
  </tendon>
  <actuator>
    <plugin name="m1" plugin="efam.muscle" tendon="t1" dyntype="filterexact" dynprm="0.05" actdim="1">
{config}
    </plugin>
    <plugin name="m2" plugin="efam.muscle" tendon="t2">
{config}
    </plugin>
    <motor name="plain" tendon="t1"/>
  </actuator>
</mujoco>
"""


def write_model(tmp_path, config: str) -> str:
    path = tmp_path / "model.xml"
    path.write_text(MODEL.format(config=config))
    return str(path)


def test_view_check_compiles_and_summarises(tmp_path, capsys):
    path = write_model(tmp_path, config_xml(load_muscle("FAM1"), "      "))
    assert main(["view", "--check", path]) == 0
    line = capsys.readouterr().out.strip()
    assert "\n" not in line
    assert line.startswith(f"{path}: ok")
    assert "3 actuators (2 efam.muscle)" in line and "1 activations" in line and "2 tendons" in line


def test_view_reports_a_bad_config_naming_file_and_key(tmp_path, capsys):
    config = config_xml(load_muscle("FAM1"), "      ").replace(
        'key="law" value="exponential_decay"', 'key="law" value="neo"'
    )
    path = write_model(tmp_path, config)
    assert main(["view", "--check", path]) == 2
    err = capsys.readouterr().err
    assert path in err and "'law'" in err and "neo" in err
    assert err.count("\n") == 1  # one line


@pytest.mark.parametrize("text", [None, "<mujoco><worldbody>"])
def test_view_reports_missing_or_broken_file(tmp_path, capsys, text):
    path = tmp_path / "broken.xml"
    if text is not None:
        path.write_text(text)
    assert main(["view", "--check", str(path)]) == 2
    assert str(path) in capsys.readouterr().err


def test_view_opens_the_viewer_with_the_compiled_model(tmp_path, monkeypatch):
    import mujoco.viewer

    opened = {}
    monkeypatch.setattr(mujoco.viewer, "launch", lambda model, data: opened.update(model=model, data=data))
    monkeypatch.setenv("DISPLAY", ":0")  # efam view refuses to open a window without a display
    monkeypatch.setattr("efam_mujoco.viewer._display_problem", lambda: "")  # ... or one GLFW cannot open
    path = write_model(tmp_path, config_xml(load_muscle("FAM2"), "      "))
    assert main(["view", path]) == 0
    assert isinstance(opened["model"], mujoco.MjModel) and opened["model"].nu == 3
    assert isinstance(opened["data"], mujoco.MjData)


@pytest.mark.parametrize(
    "edit, words",
    [
        # a 0.5 m muscle on a 0.17 m tendon: compiles, and swung hundreds of metres at 1e5 m/s
        (
            lambda xml: xml.replace('key="rest_length_m" value="0.17018"', 'key="rest_length_m" value="0.5"'),
            r"largest control, actuator 'm1' has length [0-9.]+ m .* outside its muscle's admissible",
        ),
        # an extensile muscle written tension-only: the plugin takes it (it tests the clamp) and
        # the muscle stays slack at every pressure, 0 N where it pushes 155 N at 300 kPa
        (
            lambda xml: xml.replace('key="tension_only" value="0"', 'key="tension_only" value="true"', 1),
            r"efam\.muscle 'm1' sets tension_only, but the muscle is extensile",
        ),
        # a zero gear makes the muscle's length 0 (a constant 5.7 MN from the lock spring)
        (lambda xml: xml.replace('tendon="t2">', 'tendon="t2" gear="0">'), r"actuator 'm2' has length 0 m"),
        # kPa typed into the control range of a Pa control: the muscle never leaves its dead band
        (
            lambda xml: xml.replace('tendon="t2">', 'tendon="t2" ctrlrange="0 500" ctrllimited="true">'),
            r"actuator 'm2': its control range tops out at 500 Pa.*was ctrlrange written in kPa",
        ),
        # a negative pressure lag: MuJoCo fills instantly without a word (the plugin now refuses it
        # at compile time, before the viewer's own check, as it refuses one beyond 60 s)
        (
            lambda xml: xml.replace(
                'tendon="t2">', 'tendon="t2" dyntype="filterexact" dynprm="-0.05" actdim="1">'
            ),
            r"actuator 'm2'.*dynprm\[0\] = -0.05 s, the pressure lag's time constant, must be in 0 \.\. 60 s",
        ),
    ],
)
def test_view_check_refuses_a_model_whose_muscles_cannot_be_what_it_says(tmp_path, capsys, edit, words):
    """The plugin compiles each of these and the simulation stays finite, so finiteness alone
    reported them ok; the check compares every muscle actuator with its muscle."""
    import re

    path = write_model(tmp_path, config_xml(load_muscle("FAM1"), "      "))
    text = edit(open(path).read())
    assert text != open(path).read()
    open(path, "w").write(text)
    assert main(["view", "--check", path]) == 2
    err = capsys.readouterr().err
    assert re.search(words, err), err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_view_check_refuses_inline_config_beside_an_instance(tmp_path, capsys):
    """An actuator naming an instance takes that instance's config; MuJoCo ignores keys written on
    the actuator too (here a 0.5 m rest length on a 0.17 m tendon) and the check passed it."""
    config = config_xml(load_muscle("FAM1"), "        ")
    text = MODEL.format(config="").replace(
        '<extension><plugin plugin="efam.muscle"/></extension>',
        f'<extension><plugin plugin="efam.muscle"><instance name="fam1">\n{config}\n</instance></plugin></extension>',
    )
    text = text.replace(
        '<plugin name="m2" plugin="efam.muscle" tendon="t2">',
        '<plugin name="m2" instance="fam1" tendon="t2"><config key="rest_length_m" value="0.5"/>',
    ).replace(
        '<plugin name="m1" plugin="efam.muscle" tendon="t1"', '<plugin name="m1" instance="fam1" tendon="t1"'
    )
    path = tmp_path / "model.xml"
    path.write_text(text)
    assert main(["view", "--check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "actuator 'm2' uses efam.muscle instance 'fam1'" in err and "rest_length_m" in err, err
    assert err.count("\n") == 1 and "Traceback" not in err
    # the same model without the actuator's own keys is fine
    path.write_text(text.replace('<config key="rest_length_m" value="0.5"/>', ""))
    assert main(["view", "--check", str(path)]) == 0, capsys.readouterr().err


def test_view_check_passes_the_shipped_arm_models(capsys):
    from pathlib import Path

    for model in ("arm_1x3.xml", "arm_3x3.xml", "rig_stroke_fam1.xml"):
        path = Path(__file__).parent.parent / "models" / model
        assert main(["view", "--check", str(path)]) == 0, capsys.readouterr().err


def test_view_with_a_display_that_cannot_be_opened_says_so(tmp_path):
    """A stale DISPLAY (ssh): one line naming the problem and exit 2, not GLFW's warnings, exit 1
    and a MUJOCO_LOG.TXT in the working folder."""
    import os
    import subprocess
    import sys

    path = write_model(tmp_path, config_xml(load_muscle("FAM1"), "      "))
    env = {**os.environ, "DISPLAY": ":987"}
    env.pop("WAYLAND_DISPLAY", None)
    run = subprocess.run([sys.executable, "-m", "efam_mujoco.cli", "view", path], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert run.returncode == 2, run.stderr
    assert "cannot open a window" in run.stderr and "Failed to open display" in run.stderr
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_view_names_a_folder_or_a_pipe_given_as_the_model(tmp_path, capsys):
    import os

    os.mkfifo(tmp_path / "pipe.xml")
    (tmp_path / "folder.xml").mkdir()
    for name, words in (
        ("folder.xml", "is a folder, not a model file"),
        ("pipe.xml", "is not a regular file"),
    ):
        assert main(["view", "--check", str(tmp_path / name)]) == 2
        assert words in capsys.readouterr().err  # was "no such model file"
