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
from .rig import ADMISSIBLE_SLACK


def compile_model(path: str | Path) -> mujoco.MjModel:
    """Compile an MJCF file with the plugin loaded; errors name the file."""
    load()
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"{path}: is a folder, not a model file")
    if path.exists() and not path.is_file():
        raise ValueError(f"{path}: is not a regular file (a pipe or a device?), not a model file")
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
    if ignored := config_beside_instance(path):
        raise ValueError(f"{path}: {ignored[0]}")
    declared = muscles_in_file(path)
    check_muscle_laws(path, declared)
    from .musclefile import check_tension_only

    for name, muscle in declared.items():
        # the plugin takes it (a slack extensile muscle tests the clamp), a user's model is told:
        # tension-only, an extensile muscle carries no force until stretched past its free length
        check_tension_only(muscle, f"{path}: the efam.muscle '{name}' sets tension_only")
    muscles = actuator_muscles(model, declared)
    if problems := control_range_problems(model, muscles):
        raise ValueError(f"{path}: {problems[0]}")
    data = mujoco.MjData(model)
    with mujoco_warnings() as warned:
        mujoco.mj_forward(model, data)
        if at_rest := _outside_lengths(model, data, muscles):
            raise ValueError(f"{path}: at the initial state, {at_rest}")
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
            if step_index := _outside_lengths(model, data, muscles):
                raise ValueError(f"{path}: with every actuator at its largest control, {step_index}")
        bad = [n for n in ("qpos", "qvel", "actuator_force") if not all(map(math.isfinite, getattr(data, n)))]
    if warned or bad:
        what = "; ".join(warned[:2]) or f"non-finite {', '.join(bad)}"
        raise ValueError(
            f"{path}: unstable with every actuator at its largest control (within {CHECK_STEPS} steps "
            f"of {model.opt.timestep:g} s): {what}"
        )
    return summary(path, model, data)


def actuator_muscles(model: mujoco.MjModel, muscles: dict[str, Muscle]) -> dict[int, Muscle]:
    """Actuator index -> the muscle its efam.muscle instance declares (by the instance's name,
    or the actuator's own name for a plugin written inside the actuator)."""
    slot = plugin_slot()
    out = {}
    for i, instance in enumerate(model.actuator_plugin):
        if instance < 0 or model.plugin[instance] != slot:
            continue
        names = (
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_PLUGIN, int(instance)),
            mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i),
        )
        muscle = next((muscles[n] for n in names if n and n in muscles), None)
        if muscle is not None:
            out[i] = muscle
    return out


def _actuator_label(model: mujoco.MjModel, i: int) -> str:
    return f"actuator '{mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or i}'"


def control_range_problems(model: mujoco.MjModel, muscles: dict[int, Muscle]) -> list[str]:
    """Muscle actuators whose control range tops out below the muscle's dead band: the controls
    are pressures in Pa, and a range written in kPa (``ctrlrange="0 500"``) never inflates it."""
    out = []
    for i, muscle in muscles.items():
        high = float(model.actuator_ctrlrange[i][1])
        if model.actuator_ctrllimited[i] and high <= muscle.deadband_Pa:
            out.append(
                f"{_actuator_label(model, i)}: its control range tops out at {high:g} Pa, not above the "
                f"muscle's dead band ({muscle.deadband_Pa:g} Pa), so it never inflates; controls are "
                f"pressures in Pa (was ctrlrange written in kPa?)"
            )
        # a pressure lag (dynprm) outside 0 .. 60 s is not checked here: the plugin refuses it
        # when the model compiles, naming the actuator (efam_muscle.c), so no model reaches here with one
    return out


def _outside_lengths(model: mujoco.MjModel, data: mujoco.MjData, muscles: dict[int, Muscle]) -> str:
    """A description of the first muscle actuator whose length lies beyond its muscle's
    admissible lengths by more than ``ADMISSIBLE_SLACK`` of its resting length ('' when none)."""
    for i, muscle in muscles.items():
        length = float(data.actuator_length[i])
        slack = ADMISSIBLE_SLACK * muscle.rest_length_m
        if not muscle.min_length_m - slack <= length <= muscle.max_length_m + slack:
            return (
                f"{_actuator_label(model, i)} has length {length:.4g} m at t = {data.time:.3g} s, outside "
                f"its muscle's admissible {muscle.min_length_m:.4g} .. {muscle.max_length_m:.4g} m (resting "
                f"{muscle.rest_length_m:.4g} m): the model's geometry does not fit the muscle (its tendon, "
                f"gear or transmission, or the muscle's rest_length_m)"
            )
    return ""


def _mjcf_root(path: str | Path):
    """The MJCF file's XML root element, None when it does not parse (the compiler, which runs
    first, has then said why)."""
    import xml.etree.ElementTree as ET

    try:
        return ET.parse(str(path)).getroot()
    except (ET.ParseError, OSError):
        return None


def muscles_in_file(path: str | Path) -> dict[str, Muscle]:
    """The efam.muscle instances an MJCF file declares (``<extension><plugin plugin="efam.muscle">
    <instance name=...><config key= value=/>``, keyed by the instance's name, and ``<actuator>
    <plugin plugin="efam.muscle" name=...><config .../>``, keyed by the actuator's), as Python
    muscles (instances whose config does not read as numbers are left to the compiler's message)."""
    from .stress import LAWS, StressLaw

    out: dict[str, Muscle] = {}
    if (root := _mjcf_root(path)) is None:
        return out
    declared = []  # (name, config): <extension> instances, and plugins written inside an actuator
    for plugin in root.iter("plugin"):
        if plugin.get("plugin") != PLUGIN_NAME:
            continue
        for k, instance in enumerate(plugin.iter("instance")):
            declared.append((instance.get("name") or f"instance {k}", instance))
        if plugin.find("instance") is None and plugin.find("config") is not None:
            declared.append((plugin.get("name") or "", plugin))
    for name, holder in declared:
        config = {c.get("key"): c.get("value") for c in holder.iter("config")}
        try:
            law = config.get("law", "linear")
            coefficients = tuple(float(config[key]) for key in LAWS[law].params)
            out[name] = Muscle(
                rest_length_m=float(config["rest_length_m"]),
                rest_diameter_m=float(config["rest_diameter_m"]),
                theta_rest_deg=float(config["theta_rest_deg"]),
                bladder_volume_m3=float(config["bladder_volume_m3"]),
                deadband_Pa=float(config["deadband_Pa"]),
                stress=StressLaw(law, coefficients),
                tension_only=config.get("tension_only", "0").strip() in ("1", "true"),
                name=name,
            )
        except (KeyError, TypeError, ValueError, ArithmeticError):
            continue
    return out


def config_beside_instance(path: str | Path) -> list[str]:
    """Actuators that name an efam.muscle ``instance`` and also carry ``<config>`` keys of their
    own: MuJoCo compiles them with the instance's config and ignores the inline keys without a
    word, so the muscle simulated is not the one written there."""
    if (root := _mjcf_root(path)) is None:
        return []
    ours = {
        instance.get("name")
        for plugin in root.iter("plugin")
        if plugin.get("plugin") == PLUGIN_NAME
        for instance in plugin.iter("instance")
    }
    out = []
    for actuators in root.iter("actuator"):
        for k, plugin in enumerate(actuators.iter("plugin")):
            keys = [c.get("key") for c in plugin.iter("config")]
            if plugin.get("instance") in ours and keys:
                label = plugin.get("name") or f"number {k}"
                out.append(
                    f"actuator '{label}' uses efam.muscle instance '{plugin.get('instance')}' and also has "
                    f"config keys of its own ({', '.join(map(str, keys[:3]))}{', ...' if len(keys) > 3 else ''}), "
                    "which MuJoCo ignores: put them on the instance, or drop instance= to configure the "
                    "actuator alone"
                )
    return out


def check_muscle_laws(path: str | Path, declared: dict[str, Muscle]) -> None:
    """Every efam.muscle instance the file declares (``declared``: :func:`muscles_in_file`) gives
    a finite force at every admissible length (the plugin would hand MuJoCo 0 where the law
    overflows, Python NaN): else an error naming the file and the instance."""
    from .musclefile import check_finite_forces

    for name, muscle in declared.items():
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
    if problem := _display_problem():
        raise RuntimeError(
            f"{args.file}: cannot open a window: {problem} (a stale DISPLAY, e.g. over ssh?); "
            "'efam view --check FILE' checks a model without one"
        )
    data = mujoco.MjData(model)
    from mujoco import viewer as mujoco_viewer  # needs a display; imported only to open a window

    mujoco_viewer.launch(model, data)
    return 0


def _display_problem() -> str:
    """Why no window can be opened here ('' when one can, or when GLFW is not there to ask):
    MuJoCo's viewer only finds out in its own thread, where it prints GLFW's error, writes
    MUJOCO_LOG.TXT into the working folder and exits 1."""
    import warnings

    try:
        import glfw
    except Exception:  # noqa: BLE001 - no GLFW binding (or no libglfw): let the viewer say
        return ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        opened = glfw.init()
    if opened:
        glfw.terminate()
        return ""
    said = "; ".join(str(w.message) for w in caught)
    return f"GLFW could not initialise ({said})" if said else "GLFW could not initialise"


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
