"""Load the native ``efam.muscle`` actuator plugin into MuJoCo, and write its config.

``load()`` is called by ``import efam_mujoco``; after it, any model that uses
``<plugin plugin="efam.muscle">`` compiles. ``plugin_config(muscle)`` gives the ``<config>``
key/value strings for a :class:`~efam_mujoco.muscle.Muscle`.

The library is built from ``efam_muscle.c`` by ``pip install`` (see setup.py). It is not linked
against ``libmujoco``; its MuJoCo symbols are resolved from the ``libmujoco`` that the ``mujoco``
package has already loaded, which ``load()`` first makes globally visible.
"""

from __future__ import annotations

import ctypes
import glob
import os
import sys
import threading

from ..muscle import Muscle
from ..stress import LAWS

PLUGIN_NAME = "efam.muscle"
_LIBRARY_FILE = "efam_muscle.dll" if sys.platform == "win32" else "libefam_muscle.so"
_REBUILD_HINT = (
    "rebuild it with `pip install -e .` (or `pip install .`) in the efam_mujoco source tree; "
    "a C compiler and the mujoco 3.17 wheel (its headers) are needed"
)

_lock = threading.Lock()
_library: ctypes.CDLL | None = None
_slot = -1


class PluginLoadError(ImportError):
    """The native plugin is missing, was built for another MuJoCo, or failed to register."""


def library_path() -> str:
    """Path of the compiled plugin library (raises :class:`PluginLoadError` when it is missing)."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), _LIBRARY_FILE)
    if not os.path.isfile(path):
        raise PluginLoadError(
            f"the efam.muscle plugin library is missing: {path} does not exist; {_REBUILD_HINT}"
        )
    return path


def _mujoco_library(mujoco_module) -> str:
    """The libmujoco shared library inside the mujoco package."""
    package_dir = os.path.dirname(os.path.abspath(mujoco_module.__file__))
    patterns = ("mujoco*.dll",) if sys.platform == "win32" else ("libmujoco.so*", "libmujoco*.dylib")
    for pattern in patterns:
        found = sorted(glob.glob(os.path.join(package_dir, pattern)))
        if found:
            return found[-1]
    raise PluginLoadError(f"no libmujoco shared library found in the mujoco package at {package_dir}")


def _check_versions(library: ctypes.CDLL, mujoco_module) -> None:
    built = library.efam_muscle_mujoco_header_version()
    running = mujoco_module.mj_version()
    # MuJoCo encodes versions as major*1e6 + minor*1e3 + patch; the plugin ABI follows minor versions
    if built // 1000 != running // 1000:
        raise PluginLoadError(
            f"the efam.muscle plugin was built against MuJoCo headers {built} but MuJoCo "
            f"{mujoco_module.__version__} ({running}) is running; {_REBUILD_HINT}"
        )


def _open_library():
    import mujoco  # loads libmujoco (privately); our library needs its symbols

    if sys.platform != "win32":
        # promote the already-loaded libmujoco to global visibility so our library links to it
        ctypes.CDLL(_mujoco_library(mujoco), mode=os.RTLD_NOW | os.RTLD_GLOBAL)
    path = library_path()
    try:
        library = ctypes.CDLL(path, mode=os.RTLD_NOW | getattr(os, "RTLD_LOCAL", 0))
    except OSError as err:
        raise PluginLoadError(
            f"cannot load the efam.muscle plugin library {path}: {err}; {_REBUILD_HINT}"
        ) from err
    library.efam_muscle_mujoco_header_version.restype = ctypes.c_int
    library.efam_muscle_register.restype = ctypes.c_int
    _check_versions(library, mujoco)
    slot = library.efam_muscle_register()
    if slot < 0:
        raise PluginLoadError(
            f"another plugin named '{PLUGIN_NAME}' is already registered in this process (a second "
            f"build of efam_mujoco?); this one is {path}"
        )
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
    return _library is not None


def _number(value: float) -> str:
    """A decimal string that parses back to exactly the same double (repr is shortest round-trip)."""
    return repr(float(value))


def plugin_config(muscle: Muscle) -> dict[str, str]:
    """The ``<config key=... value=...>`` pairs of the efam.muscle plugin for ``muscle``."""
    config = {
        "rest_length_m": _number(muscle.rest_length_m),
        "rest_diameter_m": _number(muscle.rest_diameter_m),
        "theta_rest_deg": _number(muscle.theta_rest_deg),
        "bladder_volume_m3": _number(muscle.bladder_volume_m3),
        "deadband_Pa": _number(muscle.deadband_Pa),
        "law": muscle.stress.name,
    }
    for key, value in zip(LAWS[muscle.stress.name].params, muscle.stress.coefficients):
        config[key] = _number(value)
    config["tension_only"] = "1" if muscle.tension_only else "0"
    config["lock_stiffness_N_per_m"] = _number(muscle.lock_stiffness_N_per_m)
    return config


def config_xml(muscle: Muscle, indent: str = "") -> str:
    """The ``<config>`` elements for ``muscle``, one per line."""
    return "\n".join(f'{indent}<config key="{k}" value="{v}"/>' for k, v in plugin_config(muscle).items())


def instance_xml(name: str, muscle: Muscle, indent: str = "") -> str:
    """A named ``<instance>`` for ``<extension><plugin plugin="efam.muscle">``.

    Actuators written ``<plugin instance="NAME" tendon=.../>`` then share it. One instance per
    distinct muscle is cheaper than one per actuator: MuJoCo visits every plugin instance in
    several stages of each step, whatever it computes.
    """
    body = config_xml(muscle, indent + "  ")
    return f'{indent}<instance name="{name}">\n{body}\n{indent}</instance>'


__all__ = [
    "PLUGIN_NAME",
    "PluginLoadError",
    "config_xml",
    "instance_xml",
    "is_loaded",
    "library_path",
    "load",
    "plugin_config",
    "plugin_slot",
]
