"""Load the native ``efam.muscle`` actuator plugin into MuJoCo, and write its config.

``load()`` is called by ``import efam_mujoco``; after it, any model that uses
``<plugin plugin="efam.muscle">`` compiles. ``plugin_config(muscle)`` gives the ``<config>``
key/value strings for a :class:`~efam_mujoco.muscle.Muscle`; ``plugin_config(muscle, effects)``
also switches on effect terms identified by ``efam diagnose`` (``efam_effects.h``: config key
``effects`` and ``<effect>.<parameter>``), and ``actuator_dynamics(effects)`` gives the actuator
attributes ``pressure_lag`` needs.

The library is built from ``efam_muscle.c`` by ``pip install`` (see setup.py). It is a MuJoCo
plugin library like MuJoCo's own: it registers ``efam.muscle`` itself when loaded
(``mjPLUGIN_LIB_INIT``), so it also works without Python: copied into MuJoCo's plugin directory
(``efam install-plugin``), where ``import mujoco``, ``python -m mujoco.viewer``, dm_control and
``simulate`` load it, or loaded from C with ``mj_loadPluginLibrary`` (``examples/c``). Whichever
path loads it first registers it; the others find it registered (once, never twice).
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import math
import os
import sys
import threading
import warnings

from ..muscle import MAX_PRESSURE_LAG_S, Muscle, deadband_problem, written_deadband_Pa
from ..stress import LAWS

PLUGIN_NAME = "efam.muscle"
LIBRARY_FILE = "efam_muscle.dll" if sys.platform == "win32" else "libefam_muscle.so"
_REBUILD_HINT = (
    "rebuild it with `pip install -e .` (or `pip install .`) in the efam_mujoco source tree; "
    "a C compiler and the mujoco 3.17 wheel (its headers) are needed"
)

#: What to do when MuJoCo says the plugin is missing (appended to such errors, and in the docs).
MISSING_PLUGIN_HINT = (
    "the MuJoCo plugin 'efam.muscle' is not registered in this process. In Python, `import "
    "efam_mujoco` before loading the model; for plain `mujoco`, `python -m mujoco.viewer`, "
    "dm_control or MuJoCo's `simulate`, run `efam install-plugin` once (it copies the plugin "
    "library into MuJoCo's plugin directory); in C, call mj_loadPluginLibrary() on the path "
    "`efam install-plugin --print-path` prints"
)

_lock = threading.Lock()
_library: ctypes.CDLL | None = None
_slot = -1


class PluginLoadError(ImportError):
    """The native plugin is missing, was built for another MuJoCo, or failed to register."""


def library_path() -> str:
    """Path of the compiled plugin library (raises :class:`PluginLoadError` when it is missing)."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), LIBRARY_FILE)
    if not os.path.isfile(path):
        raise PluginLoadError(
            f"the efam.muscle plugin library is missing: {path} does not exist; {_REBUILD_HINT}"
        )
    return path


def mujoco_plugin_dir() -> str:
    """MuJoCo's plugin directory: every library in it is loaded by ``import mujoco``."""
    import mujoco

    return getattr(mujoco, "PLUGINS_DIR", os.path.join(os.path.dirname(mujoco.__file__), "plugin"))


def _check_versions(library: ctypes.CDLL, mujoco_module) -> None:
    built = library.efam_muscle_mujoco_header_version()
    running = mujoco_module.mj_version()
    # MuJoCo encodes versions as major*1e6 + minor*1e3 + patch; the plugin ABI follows minor versions
    if built // 1000 != running // 1000:
        raise PluginLoadError(
            f"the efam.muscle plugin was built against MuJoCo headers {built} but MuJoCo "
            f"{mujoco_module.__version__} ({running}) is running; {_REBUILD_HINT}"
        )


def _file_digest(path: str) -> str:
    with open(path, "rb") as handle:
        return hashlib.sha256(handle.read()).hexdigest()


def installed_copies() -> list[str]:
    """Copies of the plugin library in MuJoCo's plugin directory (see ``efam install-plugin``)."""
    directory = mujoco_plugin_dir()
    if not os.path.isdir(directory):
        return []
    return sorted(
        os.path.join(directory, name)
        for name in os.listdir(directory)
        if name.startswith(os.path.splitext(LIBRARY_FILE)[0])
    )


def _check_registered_copy(path: str) -> None:
    """Another copy of the library registered efam.muscle first: warn unless it is this build."""
    ours = _file_digest(path)
    copies = installed_copies()
    if copies and all(_file_digest(copy) == ours for copy in copies):
        return  # `efam install-plugin` put this very build into MuJoCo's plugin directory
    where = ", ".join(copies) if copies else "a library loaded before efam_mujoco"
    warnings.warn(
        f"efam.muscle is registered by {where}, which is not this efam_mujoco's build ({path}); "
        "models use that copy. Run `efam install-plugin` to replace it with this build, or "
        "`efam install-plugin --remove` to remove it",
        RuntimeWarning,
        stacklevel=4,
    )


def _open_library():
    import mujoco  # loads libmujoco, and the libraries in MuJoCo's plugin directory

    path = library_path()
    try:
        # linked to libmujoco (see setup.py); loading registers efam.muscle (mjPLUGIN_LIB_INIT)
        library = ctypes.CDLL(path, mode=os.RTLD_NOW | getattr(os, "RTLD_LOCAL", 0))
    except OSError as err:
        raise PluginLoadError(
            f"cannot load the efam.muscle plugin library {path}: {err}; {_REBUILD_HINT}"
        ) from err
    for function in ("efam_muscle_mujoco_header_version", "efam_muscle_register", "efam_muscle_slot"):
        getattr(library, function).restype = ctypes.c_int
    _check_versions(library, mujoco)
    slot = library.efam_muscle_register()  # idempotent: the slot the constructor registered
    if slot < 0:
        slot = library.efam_muscle_slot()
        if slot < 0:
            raise PluginLoadError(f"the efam.muscle plugin library {path} failed to register")
        _check_registered_copy(path)
    return library, slot


def load() -> str:
    """Register ``efam.muscle`` with MuJoCo (idempotent, thread-safe); returns the library path."""
    global _library, _slot
    with _lock:
        if _library is None:
            _library, _slot = _open_library()
        return _library._name


def plugin_slot() -> int:
    """MuJoCo's registry slot of efam.muscle (``MjModel.plugin`` holds slots); loads if needed."""
    load()
    return _slot


def is_loaded() -> bool:
    """Whether :func:`load` has run in this process."""
    return _library is not None


def is_missing_plugin_error(err: BaseException) -> bool:
    """Whether ``err`` is MuJoCo's compile error for an unregistered ``efam.muscle`` plugin."""
    text = str(err)
    return PLUGIN_NAME in text and ("not found" in text or "unknown plugin" in text)


@contextlib.contextmanager
def missing_plugin_hint():
    """Re-raise MuJoCo's "plugin efam.muscle not found" inside the block with how to fix it.

    >>> with missing_plugin_hint():  # doctest: +SKIP
    ...     model = mujoco.MjModel.from_xml_path("models/arm_3x3.xml")
    """
    try:
        yield
    except ValueError as err:
        if is_missing_plugin_error(err):
            raise ValueError(f"{err}\nHint: {MISSING_PLUGIN_HINT}") from err
        raise


def load_model(path: str):
    """``mujoco.MjModel`` of the MJCF file ``path``, with the plugin registered first (a
    missing-plugin error says how to fix it)."""
    import mujoco

    load()
    with missing_plugin_hint():
        return mujoco.MjModel.from_xml_path(os.fspath(path))


def _number(value: float) -> str:
    """A decimal string that parses back to exactly the same double (repr is shortest round-trip)."""
    return repr(float(value))


#: The muscle's config keys in the plugin's attribute order (``kAttributes`` in efam_muscle.c; the
#: effect keys follow them): a compiled model stores each instance's values in this order.
MUSCLE_CONFIG_KEYS = (
    "rest_length_m", "rest_diameter_m", "theta_rest_deg", "bladder_volume_m3", "deadband_Pa",
    "law", "tension_only", "lock_stiffness_N_per_m", "E1_Pa", "E2", "E3_Pa", "E3", "E4_Pa", "E4",
    "segments", "arc_geometry",
)  # fmt: skip


def instance_config(model, instance: int) -> dict[str, str]:
    """The muscle config keys (:data:`MUSCLE_CONFIG_KEYS`) that plugin instance ``instance`` of a
    compiled ``model`` was given (keys left unset are absent)."""
    if not 0 <= instance < model.nplugin:
        raise ValueError(f"plugin instance {instance} does not exist (the model has {model.nplugin})")
    raw = bytes(model.plugin_attr[model.plugin_attradr[instance] :])
    values = raw.split(b"\0")[: len(MUSCLE_CONFIG_KEYS)]
    return {key: v.decode() for key, v in zip(MUSCLE_CONFIG_KEYS, values) if v}


#: Effects that are not actuator forces: the rig adds them to its sensors, not the plugin.
SENSOR_EFFECTS = ("force_offset",)


def plugin_config(
    muscle: Muscle, effects=None, segments: int = 1, arc_geometry: bool = False
) -> dict[str, str]:
    """The ``<config key=... value=...>`` pairs of the efam.muscle plugin for ``muscle``, with
    the ``effects`` (``[(name, parameters), ...]``, as ``EffectModel`` and ``Diagnosis.effects``
    hold them) switched on; see :func:`effects_config`.

    ``segments`` = N > 1: each actuator of the instance drives the tendon of a whole muscle, and
    the N tendons that follow that tendon (in tendon order) are the muscle's segments between
    consecutive spacer disks, of equal resting length; every segment pushes with
    ``muscle.push(P, N * segment_length)`` at the actuator's one pressure state (the actuator
    applies the whole muscle's push, the plugin's passive stage the difference per segment).

    ``arc_geometry`` (segmented muscles of the arm builder's links, see
    :mod:`efam_mujoco.arm.builder`): each segment's length is its muscle's arc length in its
    half-link, computed from the link's joints (exact at constant curvature, any bend plane), not
    the segment tendon's linear approximation; :class:`efam_mujoco.arm.SegmentLengths` is the
    same geometry in Python."""
    if int(segments) != segments or segments < 1:
        raise ValueError(f"segments must be a whole number >= 1, got {segments!r}")
    if arc_geometry and segments < 2:
        raise ValueError("arc_geometry needs segmented muscles (segments > 1)")
    deadband = written_deadband_Pa(muscle.deadband_Pa)
    if problem := deadband_problem(deadband):  # the plugin would refuse it (efam_muscle.c)
        raise ValueError(f"config key 'deadband_Pa' = {deadband:.10g} is invalid: {problem}")
    config = {
        "rest_length_m": _number(muscle.rest_length_m),
        "rest_diameter_m": _number(muscle.rest_diameter_m),
        "theta_rest_deg": _number(muscle.theta_rest_deg),
        "bladder_volume_m3": _number(muscle.bladder_volume_m3),
        "deadband_Pa": _number(deadband),
        "law": muscle.stress.name,
    }
    for key, value in zip(LAWS[muscle.stress.name].params, muscle.stress.coefficients):
        config[key] = _number(value)
    config["tension_only"] = "1" if muscle.tension_only else "0"
    config["lock_stiffness_N_per_m"] = _number(muscle.lock_stiffness_N_per_m)
    config.update(effects_config(effects))
    if segments > 1:
        config["segments"] = str(int(segments))
    if arc_geometry:
        config["arc_geometry"] = "1"
    return config


def effects_config(effects=None) -> dict[str, str]:
    """The plugin keys that switch ``effects`` on: ``effects`` = their names, comma-separated, and
    each parameter as ``<effect>.<key>`` (e.g. ``friction.f0_N``). ``effects`` is a list of
    ``(name, parameters)`` or of dicts with ``name`` and ``parameters`` (``Diagnosis.effects``).
    Parameters are checked against the library's bounds (an error names the effect and key).
    ``force_offset``, a load-cell error, is left to the rig's load cell; per-recording values
    (``*_by_recording``) are dropped: pass the effects of one recording. Empty for no effects."""
    if not effects:
        return {}
    from ..diagnose.effects import check_values  # the library's keys and bounds (imports scipy)

    keys: dict[str, str] = {}
    names = []
    for name, values in effect_pairs(effects):
        values = check_values(name, dict(values))
        if name in SENSOR_EFFECTS:
            continue
        if name in names:
            raise ValueError(f"effect '{name}' is given twice")
        names.append(name)
        for key, value in values.items():
            if not key.endswith("_by_recording"):
                keys[f"{name}.{key}"] = _number(value)
    return {"effects": ",".join(names), **keys} if names else {}


def effect_pairs(effects) -> list[tuple[str, dict]]:
    """``effects`` as (name, parameters) pairs: pairs, or the diagnosis report's dicts with
    ``name`` and ``parameters``; anything else is refused by name (a bare 'friction' was
    unpacked into its letters: "not enough values to unpack")."""
    if isinstance(effects, (str, dict)):
        raise ValueError(f"effects must be a list of (name, parameters) pairs, got {effects!r}")
    out = []
    for effect in effects or ():
        if isinstance(effect, dict) and {"name", "parameters"} <= set(effect):
            out.append((effect["name"], effect["parameters"]))
        elif (
            isinstance(effect, (tuple, list)) and len(effect) == 2 and isinstance(effect[0], str)
            and isinstance(effect[1], dict)
        ):  # fmt: skip
            out.append((effect[0], effect[1]))
        else:
            raise ValueError(
                f"effects must be (name, parameters) pairs, e.g. ('friction', {{'f0_N': 2.0}}), got {effect!r}"
            )
    return out


CTRL_HISTORY_STEP_S = 2.5e-4  # the finest step a delayed pressure's history is sized for (4 kHz)


def actuator_dynamics(effects=None, lag_s: float | None = None) -> str:
    """Attributes of the ``<plugin>`` actuator element for its pressure dynamics: a valve/tube lag
    ``lag_s`` (MuJoCo ``filterexact``), or the ``pressure_lag`` effect's (the plugin adds the gas
    volume term to MuJoCo's lag, so the two time constants must be one; ``actearly`` makes the
    lag include the current sample, as the effect's reference does; a ``delay_s`` rides on MuJoCo's
    ctrl delay, linearly interpolated). Empty for no dynamics. A lag outside 0 ..
    ``MAX_PRESSURE_LAG_S`` is refused, as the plugin refuses such a ``dynprm``."""
    if lag_s is not None and not 0 <= float(lag_s) <= MAX_PRESSURE_LAG_S:
        raise ValueError(
            f"the actuator's pressure lag (dynprm) {lag_s!r} s must be in 0 .. {MAX_PRESSURE_LAG_S:g} s: a valve "
            "and a tube fill a bladder in milliseconds to seconds (was it in ms?)"
        )
    lag_effect = dict(effect_pairs(effects)).get("pressure_lag", {})
    tau = lag_effect.get("tau_s")
    if tau is not None:
        if lag_s is not None and float(lag_s) != float(tau):
            raise ValueError(
                f"the actuator's pressure lag {lag_s!r} s and effect pressure_lag tau_s = {tau!r} s are "
                "one first-order lag: give one of them"
            )
        out = f' dyntype="filterexact" dynprm="{_number(tau)}" actdim="1" actearly="true"'
        delay = float(lag_effect.get("delay_s", 0.0))
        if delay > 0:
            # MuJoCo's own ctrl delay carries the line's transport delay; its history must span
            # the delay at the finest step it will be stepped with (CTRL_HISTORY_STEP_S)
            nsample = int(math.ceil(delay / CTRL_HISTORY_STEP_S)) + 2
            out += f' delay="{_number(delay)}" nsample="{nsample}" interp="linear"'
        return out
    if lag_s:
        return f' dyntype="filterexact" dynprm="{_number(lag_s)}" actdim="1"'
    return ""


def config_xml(muscle: Muscle, indent: str = "", effects=None) -> str:
    """The ``<config>`` elements for ``muscle`` (with ``effects`` switched on), one per line."""
    config = plugin_config(muscle, effects)
    return "\n".join(f'{indent}<config key="{k}" value="{v}"/>' for k, v in config.items())


def instance_xml(name: str, muscle: Muscle, indent: str = "", effects=None) -> str:
    """A named ``<instance>`` for ``<extension><plugin plugin="efam.muscle">``.

    Actuators written ``<plugin instance="NAME" tendon=.../>`` then share it. One instance per
    distinct muscle is cheaper than one per actuator: MuJoCo visits every plugin instance in
    several stages of each step, whatever it computes.
    """
    body = config_xml(muscle, indent + "  ", effects)
    return f'{indent}<instance name="{name}">\n{body}\n{indent}</instance>'


__all__ = [
    "LIBRARY_FILE",
    "MISSING_PLUGIN_HINT",
    "MUSCLE_CONFIG_KEYS",
    "PLUGIN_NAME",
    "PluginLoadError",
    "SENSOR_EFFECTS",
    "actuator_dynamics",
    "config_xml",
    "effects_config",
    "instance_xml",
    "installed_copies",
    "instance_config",
    "is_loaded",
    "is_missing_plugin_error",
    "library_path",
    "load",
    "load_model",
    "missing_plugin_hint",
    "mujoco_plugin_dir",
    "plugin_config",
    "plugin_slot",
]
