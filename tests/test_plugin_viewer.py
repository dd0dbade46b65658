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
    path = write_model(tmp_path, config_xml(load_muscle("FAM2"), "      "))
    assert main(["view", path]) == 0
    assert isinstance(opened["model"], mujoco.MjModel) and opened["model"].nu == 3
    assert isinstance(opened["data"], mujoco.MjData)
