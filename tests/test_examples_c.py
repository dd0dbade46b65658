"""examples/c/step_model.c, compiled with the system C compiler against the mujoco wheel's
headers and libmujoco, loads the plugin with mj_loadPluginLibrary and steps models/arm_3x3.xml;
its result must equal the same steps taken in Python (same libmujoco, same plugin code)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import mujoco
import numpy as np
import pytest

from efam_mujoco import plugin as efam_plugin

REPO = Path(__file__).resolve().parents[1]
SOURCE = REPO / "examples" / "c" / "step_model.c"
ARM = REPO / "models" / "arm_3x3.xml"


@pytest.fixture(scope="module")
def binary(tmp_path_factory) -> Path:
    """The example, compiled once for this module."""
    tmp_path = tmp_path_factory.mktemp("c_example")
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    assert compiler, "no C compiler (cc) on PATH: the plugin build needs one too"
    mj = Path(mujoco.__file__).resolve().parent
    libmujoco = sorted(mj.glob("libmujoco.so.*"))[-1]
    binary = tmp_path / "step_model"
    command = [compiler, "-O2", "-Wall", "-Werror", "-o", str(binary), str(SOURCE), f"-I{mj / 'include'}",
               str(libmujoco), f"-Wl,-rpath,{mj}"]  # fmt: skip
    build = subprocess.run(command, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    return binary


def parse(output: str) -> dict:
    values: dict = {"qpos": {}, "force": {}}
    for line in output.splitlines():
        words = line.split()
        if words[0] in ("qpos", "force"):
            values[words[0]][int(words[1])] = float(words[2])
        elif words[0] == "time":
            values["time"] = float(words[1])
        elif words[0] == "efam.muscle":
            values["muscles"] = int(words[-1])
    return values


def test_c_program_steps_the_arm_through_mj_loadPluginLibrary(binary):
    pressure, steps = 200e3, 300
    run = subprocess.run(
        [str(binary), efam_plugin.library_path(), str(ARM), str(pressure), str(steps)],
        capture_output=True, text=True, timeout=120, env={**os.environ, "LD_PRELOAD": ""},
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    out = parse(run.stdout)

    model = efam_plugin.load_model(ARM)
    data = mujoco.MjData(model)
    data.ctrl[:] = [pressure * (k + 1) / model.nu for k in range(model.nu)]  # the example's pressures
    for _ in range(steps):
        mujoco.mj_step(model, data)

    assert out["muscles"] == model.nu == 9
    assert out["time"] == data.time
    qpos = np.array([out["qpos"][i] for i in range(model.nq)])
    assert np.max(np.abs(qpos)) > 1e-3  # the arm bent: not a trivial comparison
    np.testing.assert_allclose(qpos, data.qpos, rtol=0, atol=1e-12)
    forces = np.array([out["force"][i] for i in range(model.nu)])
    np.testing.assert_allclose(forces, data.actuator_force, rtol=1e-12, atol=1e-9)


def test_c_program_given_another_plugin_library_reports_the_missing_plugin(binary):
    other = Path(mujoco.__file__).resolve().parent / "plugin" / "libactuator.so"  # MuJoCo's own
    run = subprocess.run([str(binary), str(other), str(ARM)], capture_output=True, text=True)
    assert run.returncode == 1
    assert "did not register the efam.muscle plugin" in run.stderr
