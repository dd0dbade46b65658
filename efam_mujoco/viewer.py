"""``efam view FILE.xml``: MuJoCo's interactive viewer with the efam.muscle plugin loaded.

Plain ``python -m mujoco.viewer`` cannot open a model that uses ``efam.muscle``: the plugin is
registered by ``import efam_mujoco``, which that command never does. ``--check`` compiles the
model, runs one ``mj_forward`` and prints a one-line summary instead of opening a window.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco

from .plugin import PLUGIN_NAME, load, plugin_slot


def compile_model(path: str | Path) -> mujoco.MjModel:
    """Compile an MJCF file with the plugin loaded; errors name the file."""
    load()
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such model file")
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as err:
        message = " ".join(str(err).split())  # MuJoCo's message spans lines; the CLI prints one
        raise ValueError(f"{path}: the model does not compile: {message}") from err


def muscle_actuators(model: mujoco.MjModel) -> int:
    """How many actuators an efam.muscle plugin instance drives."""
    slot = plugin_slot()
    return sum(1 for instance in model.actuator_plugin if instance >= 0 and model.plugin[instance] == slot)


def summary(path: str | Path, model: mujoco.MjModel, data: mujoco.MjData) -> str:
    return (
        f"{path}: ok: {model.nbody - 1} bodies, {model.njnt} joints, {model.ntendon} tendons, "
        f"{model.nu} actuators ({muscle_actuators(model)} {PLUGIN_NAME}), {model.na} activations, "
        f"timestep {model.opt.timestep:g} s"
    )


def check(path: str | Path) -> str:
    """Compile, evaluate once, and return the summary line; raises on any failure."""
    model = compile_model(path)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    bad = [name for name in ("qacc", "actuator_force") if not all(map(math.isfinite, getattr(data, name)))]
    if bad:
        raise ValueError(f"{path}: mj_forward at the initial state gives non-finite {', '.join(bad)}")
    return summary(path, model, data)


def run_view(args) -> int:
    if args.check:
        print(check(args.file))
        return 0
    model = compile_model(args.file)
    data = mujoco.MjData(model)
    from mujoco import viewer as mujoco_viewer  # needs a display; imported only to open a window

    mujoco_viewer.launch(model, data)
    return 0


def register_cli(sub) -> None:
    p = sub.add_parser(
        "view",
        help="open a model in MuJoCo's viewer with the efam.muscle plugin loaded",
        description="Open an MJCF model in MuJoCo's interactive viewer with the efam.muscle plugin "
        "registered (python -m mujoco.viewer would not find it).",
    )
    p.add_argument("file", help="MJCF model file (.xml)")
    p.add_argument(
        "--check",
        action="store_true",
        help="compile the model, run one mj_forward and print a one-line summary; no window",
    )
    p.set_defaults(run=run_view)
