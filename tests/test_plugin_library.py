"""The plugin as MuJoCo expects a plugin library: loaded from MuJoCo's plugin directory by a
process that never imports efam_mujoco (plain mujoco, dm_control), registered once when both
paths run, and ``efam install-plugin``.

MuJoCo's plugin directory is the ``plugin`` folder of the ``mujoco`` package. The tests do not
touch the installed one: they build a private copy of the package (symlinks to every file, and a
``plugin`` folder of their own) and put it first on ``PYTHONPATH`` of a fresh interpreter.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from efam_mujoco import plugin as efam_plugin
from efam_mujoco.cli import main

REPO = Path(__file__).resolve().parents[1]
ARM = REPO / "models" / "arm_3x3.xml"
STEPS = 200


def mujoco_with_plugin_dir(root: Path, library: Path | None) -> Path:
    """A copy of the installed mujoco package under ``root`` whose plugin directory holds MuJoCo's
    bundled plugins and ``library``; returns the directory to put on PYTHONPATH."""
    source = Path(mujoco.__file__).resolve().parent
    package = root / "mujoco"
    package.mkdir(parents=True)
    for entry in source.iterdir():
        if entry.name not in ("plugin", "__pycache__"):
            (package / entry.name).symlink_to(entry)
    plugins = package / "plugin"
    plugins.mkdir()
    for entry in (source / "plugin").iterdir():
        (plugins / entry.name).symlink_to(entry)
    if library is not None:
        shutil.copyfile(library, plugins / library.name)
    return root


def run_python(code: str, pythonpath: Path) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter with ``pythonpath`` first (efam_mujoco stays importable,
    so a test can check the code did not import it)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(pythonpath), str(REPO)]))
    env.pop("EFAM_PROGRESS", None)
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=REPO, timeout=300
    )


# Steps the arm with unequal pressures (the arm bends) and prints qpos as JSON; also the number of
# registered plugins named efam.muscle (read from MuJoCo's registry through libmujoco).
STEP_ARM = f"""
import ctypes, glob, json, os, sys
import mujoco
assert mujoco.__file__.startswith(os.environ["PYTHONPATH"].split(os.pathsep)[0]), mujoco.__file__
{{extra}}
model = mujoco.MjModel.from_xml_path({str(ARM)!r})
data = mujoco.MjData(model)
data.ctrl[:] = [200e3 * (k + 1) / model.nu for k in range(model.nu)]
for _ in range({STEPS}):
    mujoco.mj_step(model, data)
lib = ctypes.CDLL(glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so.*"))[0])
lib.mjp_getPluginAtSlot.restype = ctypes.POINTER(ctypes.c_char_p)
names = [lib.mjp_getPluginAtSlot(i)[0].decode() for i in range(lib.mjp_pluginCount())]
print(json.dumps({{"qpos": data.qpos.tolist(), "registered": names.count("efam.muscle"),
                  "efam_imported": "efam_mujoco" in sys.modules}}))
"""


def arm_reference_qpos() -> np.ndarray:
    """The same steps in this process, where ``import efam_mujoco`` registered the plugin."""
    model = efam_plugin.load_model(ARM)
    data = mujoco.MjData(model)
    data.ctrl[:] = [200e3 * (k + 1) / model.nu for k in range(model.nu)]
    for _ in range(STEPS):
        mujoco.mj_step(model, data)
    return data.qpos.copy()


def result(process: subprocess.CompletedProcess) -> dict:
    assert process.returncode == 0, process.stderr
    return json.loads(process.stdout.strip().splitlines()[-1])


def test_plain_mujoco_loads_the_plugin_from_its_plugin_directory(tmp_path):
    library = Path(efam_plugin.library_path())
    root = mujoco_with_plugin_dir(tmp_path, library)
    out = result(run_python(STEP_ARM.replace("{extra}", ""), root))
    assert out["efam_imported"] is False
    assert out["registered"] == 1
    reference = arm_reference_qpos()
    assert np.max(np.abs(reference)) > 1e-3  # the arm moved: a real comparison
    np.testing.assert_array_equal(out["qpos"], reference)  # same code, same libmujoco: bit-identical


def test_dm_control_loads_the_plugin_from_mujocos_plugin_directory(tmp_path):
    root = mujoco_with_plugin_dir(tmp_path, Path(efam_plugin.library_path()))
    code = (
        "import sys\nfrom dm_control import mujoco as dm\n"
        f"physics = dm.Physics.from_xml_path({str(ARM)!r})\n"
        "physics.data.ctrl[:] = 100e3\nphysics.step()\n"
        "print(physics.model.nu, 'efam_mujoco' in sys.modules)"
    )
    process = run_python(code, root)
    assert process.returncode == 0, process.stderr
    assert process.stdout.split()[-2:] == ["9", "False"]


def test_installed_copy_and_import_efam_mujoco_register_once(tmp_path):
    root = mujoco_with_plugin_dir(tmp_path, Path(efam_plugin.library_path()))
    extra = "import warnings; warnings.simplefilter('error'); import efam_mujoco"
    out = result(run_python(STEP_ARM.replace("{extra}", extra), root))
    assert out["registered"] == 1 and out["efam_imported"] is True
    np.testing.assert_array_equal(out["qpos"], arm_reference_qpos())


def test_a_stale_installed_copy_is_reported_on_import(tmp_path):
    stale = tmp_path / "stale" / efam_plugin.LIBRARY_FILE
    stale.parent.mkdir()
    stale.write_bytes(Path(efam_plugin.library_path()).read_bytes() + b"another build")
    root = mujoco_with_plugin_dir(tmp_path / "site", stale)
    process = run_python("import efam_mujoco", root)
    assert process.returncode == 0, process.stderr
    assert "is not this efam_mujoco's build" in process.stderr
    assert "efam install-plugin" in process.stderr


def test_without_the_plugin_the_error_says_how_to_fix_it(tmp_path):
    root = mujoco_with_plugin_dir(tmp_path, None)
    code = f"import mujoco\ntry:\n    mujoco.MjModel.from_xml_path({str(ARM)!r})\nexcept ValueError as err:\n    print(err)"
    process = run_python(code, root)
    assert process.returncode == 0, process.stderr
    message = process.stdout
    assert "efam.muscle not found" in message  # MuJoCo's own words, which the hint recognises
    assert efam_plugin.is_missing_plugin_error(ValueError(message))
    with pytest.raises(ValueError, match="efam install-plugin") as caught:
        with efam_plugin.missing_plugin_hint():
            raise ValueError(message)
    assert "import efam_mujoco" in str(caught.value) and "not found" in str(caught.value)
    with pytest.raises(ValueError, match="^other$"):  # other errors pass through unchanged
        with efam_plugin.missing_plugin_hint():
            raise ValueError("other")


def test_install_plugin_command_copies_prints_and_removes(tmp_path, capsys):
    target = tmp_path / "mujoco_plugin"
    assert main(["install-plugin", "--dir", str(target)]) == 0
    installed = target / efam_plugin.LIBRARY_FILE
    assert installed.read_bytes() == Path(efam_plugin.library_path()).read_bytes()
    assert str(installed) in capsys.readouterr().out
    assert [p.name for p in target.iterdir()] == [efam_plugin.LIBRARY_FILE]  # no partial files left
    assert main(["install-plugin", "--print-path"]) == 0
    assert capsys.readouterr().out.strip() == efam_plugin.library_path()
    assert main(["install-plugin", "--remove", "--dir", str(target)]) == 0
    assert not installed.exists() and "removed" in capsys.readouterr().out
    assert main(["install-plugin", "--remove", "--dir", str(target)]) == 0
    assert "nothing removed" in capsys.readouterr().out


def test_install_plugin_replaces_and_removes_only_its_own_builds(tmp_path, capsys):
    """A file that only has the library's name is the user's: never overwritten, never removed;
    an earlier build (another build's bytes, same entry point) is replaced."""
    mine = tmp_path / "user"
    mine.mkdir()
    theirs = mine / efam_plugin.LIBRARY_FILE
    theirs.write_text("MY DATA")
    assert main(["install-plugin", "--dir", str(mine)]) == 2
    assert "is not an efam.muscle plugin library: not replaced" in capsys.readouterr().err
    assert main(["install-plugin", "--remove", "--dir", str(mine)]) == 0
    assert "not an efam.muscle build" in capsys.readouterr().out
    assert theirs.read_text() == "MY DATA"
    older = tmp_path / "older"
    older.mkdir()
    build = Path(efam_plugin.library_path()).read_bytes()
    (older / efam_plugin.LIBRARY_FILE).write_bytes(build + b"another build")
    assert main(["install-plugin", "--dir", str(older)]) == 0
    assert (older / efam_plugin.LIBRARY_FILE).read_bytes() == build
    assert "mj_loadPluginLibrary" in capsys.readouterr().out  # not "plain import mujoco now loads it"


def test_install_plugin_never_removes_the_packages_own_library(tmp_path, monkeypatch, capsys):
    from efam_mujoco.plugin import install as installer

    package = tmp_path / "package"  # a stand-in for the package's plugin folder
    package.mkdir()
    own = package / efam_plugin.LIBRARY_FILE
    own.write_bytes(Path(efam_plugin.library_path()).read_bytes())
    monkeypatch.setattr(installer, "library_path", lambda: str(own))
    assert main(["install-plugin", "--remove", "--dir", str(package)]) == 0
    assert own.exists() and "the package's own library" in capsys.readouterr().out
    # installing there copies nothing, and says so (before: "installed ...")
    assert main(["install-plugin", "--dir", str(package)]) == 0
    out = capsys.readouterr().out
    assert "this build's own library: nothing to install there" in out and "installed" not in out


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--dir", ""], "--dir is empty"),
        (["--dir", "{file}"], "exists and is not a folder"),
        (["--dir", "{tmp}/new/" + efam_plugin.LIBRARY_FILE], "give the folder, not the library's own path"),
        (["--print-path", "--remove"], "takes no --remove or --dir"),
    ],
)
def test_install_plugin_bad_arguments_are_named(tmp_path, capsys, argv, words):
    (tmp_path / "a_file").write_text("x")
    argv = [a.replace("{file}", str(tmp_path / "a_file")).replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["install-plugin", *argv]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err
    assert not (tmp_path / "new").exists()  # nothing created
