"""``efam view FILE.xml``: MuJoCo's interactive viewer with the efam.muscle plugin loaded.

Plain ``python -m mujoco.viewer`` cannot open a model that uses ``efam.muscle``: the plugin is
registered by ``import efam_mujoco``, which that command never does. ``--check`` compiles the
model, runs one ``mj_forward`` and prints a one-line summary instead of opening a window.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import mujoco

from .muscle import Muscle
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
    """One line: what the compiled model holds."""
    return (
        f"{path}: ok: {model.nbody - 1} bodies, {model.njnt} joints, {model.ntendon} tendons, "
        f"{model.nu} actuators ({muscle_actuators(model)} {PLUGIN_NAME}), {model.na} activations, "
        f"timestep {model.opt.timestep:g} s"
    )


#: Steps ``--check`` runs at the largest control of every actuator, watching MuJoCo's warnings.
CHECK_STEPS = 200


def check(path: str | Path) -> str:
    """Compile, evaluate once at the initial state, then run :data:`CHECK_STEPS` steps with every
    actuator at the top of its control range; return the summary line. Raises when anything is
    not finite or MuJoCo warns (a huge acceleration, NaN): a model that only looks fine at rest
    is not reported ok."""
    from .files import mujoco_warnings

    model = compile_model(path)
    check_muscle_laws(path)
    data = mujoco.MjData(model)
    with mujoco_warnings() as warned:
        mujoco.mj_forward(model, data)
        bad = [
            name for name in ("qacc", "actuator_force") if not all(map(math.isfinite, getattr(data, name)))
        ]
        if bad:
            raise ValueError(f"{path}: mj_forward at the initial state gives non-finite {', '.join(bad)}")
        for i in range(model.nu):
            low, high = model.actuator_ctrlrange[i]
            data.ctrl[i] = high if model.actuator_ctrllimited[i] else 0.0
        for _ in range(CHECK_STEPS):
            mujoco.mj_step(model, data)
            if warned:
                break
        bad = [n for n in ("qpos", "qvel", "actuator_force") if not all(map(math.isfinite, getattr(data, n)))]
    if warned or bad:
        what = "; ".join(warned[:2]) or f"non-finite {', '.join(bad)}"
        raise ValueError(
            f"{path}: unstable with every actuator at its largest control (within {CHECK_STEPS} steps "
            f"of {model.opt.timestep:g} s): {what}"
        )
    return summary(path, model, data)


def muscles_in_file(path: str | Path) -> dict[str, Muscle]:
    """The efam.muscle instances an MJCF file declares (``<extension><plugin plugin="efam.muscle">
    <instance name=...><config key= value=/>``), as Python muscles (instances whose config does
    not read as numbers are left to the compiler's message)."""
    import xml.etree.ElementTree as ET

    from .stress import LAWS, StressLaw

    out: dict[str, Muscle] = {}
    try:
        root = ET.parse(str(path)).getroot()
    except (ET.ParseError, OSError):
        return out
    for plugin in root.iter("plugin"):
        if plugin.get("plugin") != PLUGIN_NAME:
            continue
        for k, instance in enumerate(plugin.iter("instance")):
            config = {c.get("key"): c.get("value") for c in instance.iter("config")}
            try:
                law = config.get("law", "linear")
                coefficients = tuple(float(config[key]) for key in LAWS[law].params)
                out[instance.get("name") or f"instance {k}"] = Muscle(
                    rest_length_m=float(config["rest_length_m"]),
                    rest_diameter_m=float(config["rest_diameter_m"]),
                    theta_rest_deg=float(config["theta_rest_deg"]),
                    bladder_volume_m3=float(config["bladder_volume_m3"]),
                    deadband_Pa=float(config["deadband_Pa"]),
                    stress=StressLaw(law, coefficients),
                    tension_only=config.get("tension_only", "0").strip() in ("1", "true"),
                    name=instance.get("name") or "",
                )
            except (KeyError, TypeError, ValueError, ArithmeticError):
                continue
    return out


def check_muscle_laws(path: str | Path) -> None:
    """Every efam.muscle instance of the file gives a finite force at every admissible length
    (the plugin would hand MuJoCo 0 where the law overflows, Python NaN): else an error."""
    from .musclefile import check_finite_forces

    for name, muscle in muscles_in_file(path).items():
        check_finite_forces(muscle, f"{path}: efam.muscle instance '{name}'")


def run_view(args) -> int:
    """``efam view``: check the model, or open it in MuJoCo's viewer."""
    if args.check:
        print(check(args.file))
        return 0
    model = compile_model(args.file)
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise RuntimeError(
            f"{args.file}: no display to open a window on (DISPLAY is not set); "
            "'efam view --check FILE' checks a model without one"
        )
    data = mujoco.MjData(model)
    from mujoco import viewer as mujoco_viewer  # needs a display; imported only to open a window

    mujoco_viewer.launch(model, data)
    return 0


def register_cli(sub) -> None:
    """Add ``efam view`` to the ``efam`` command line."""
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
        help="compile the model, evaluate it at rest and for 200 steps at full control, print a one-line "
        "summary (an error if anything is unstable); no window",
    )
    p.set_defaults(run=run_view, file_inputs=("file",), file_outputs=())
