"""Build the native MuJoCo actuator plugin ``efam.muscle`` during the ordinary ``pip install``.

Everything else about the package is in pyproject.toml. The plugin is a plain C shared library, a
MuJoCo plugin library like MuJoCo's own (``libactuator.so``...): it registers itself when loaded
(``mjPLUGIN_LIB_INIT``), by ``import efam_mujoco``, by ``mj_loadPluginLibrary`` in C, or from
MuJoCo's plugin directory (``efam install-plugin``). It is compiled against the headers that ship
inside the ``mujoco`` wheel and linked against that wheel's ``libmujoco`` (by its soname), so a
process that has MuJoCo loaded resolves the plugin's MuJoCo symbols to that same library; the
rpath finds the wheel's ``libmujoco`` from ``site-packages/efam_mujoco/plugin`` and from
``site-packages/mujoco/plugin``. Rebuild after changing the MuJoCo version (the loader says so).
"""

from __future__ import annotations

import glob
import importlib.util
import os
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

PLUGIN_SOURCE = "efam_mujoco/plugin/efam_muscle.c"
LIBRARY_NAME = "efam_muscle"  # the loader looks for libefam_muscle.so (efam_muscle.dll)


def mujoco_package_dir() -> str:
    """The directory of the installed ``mujoco`` package (found without importing it)."""
    spec = importlib.util.find_spec("mujoco")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(
            "building the efam.muscle plugin needs the 'mujoco' package (its headers): "
            "pip install 'mujoco>=3.17,<3.18', or build with pip's default build isolation"
        )
    for location in spec.submodule_search_locations:
        if os.path.isfile(os.path.join(location, "include", "mujoco", "mjplugin.h")):
            return location
    raise RuntimeError(f"the installed mujoco package ({spec.origin}) has no include/mujoco/mjplugin.h")


def mujoco_library(package_dir: str) -> str:
    """The wheel's ``libmujoco`` shared library (``libmujoco.so.X.Y.Z``; ``mujoco.lib`` on Windows)."""
    patterns = ("mujoco.lib",) if sys.platform == "win32" else ("libmujoco.so.*", "libmujoco*.dylib")
    for pattern in patterns:
        found = sorted(glob.glob(os.path.join(package_dir, pattern)))
        if found:
            return found[-1]
    raise RuntimeError(f"the installed mujoco package ({package_dir}) has no libmujoco shared library")


class BuildPlugin(build_ext):
    """Compile the plugin as a plain shared library with the flags the model needs."""

    def build_extensions(self):
        package_dir = mujoco_package_dir()
        for ext in self.extensions:
            ext.include_dirs.append(os.path.join(package_dir, "include"))
            # linked by soname: an already-loaded libmujoco (Python's mujoco, simulate, a C program)
            # satisfies it; otherwise the rpath finds the wheel's copy beside the installed package
            ext.extra_objects.append(mujoco_library(package_dir))
            if sys.platform.startswith("linux"):
                ext.extra_link_args.append("-Wl,-rpath,$ORIGIN/..:$ORIGIN/../../mujoco")
            elif sys.platform == "darwin":
                ext.extra_link_args += ["-Wl,-rpath,@loader_path/..", "-Wl,-rpath,@loader_path/../../mujoco"]
        super().build_extensions()

    def get_ext_filename(self, fullname):
        # a plain library name: this is not an importable Python extension module
        package, _, name = fullname.rpartition(".")
        filename = f"{name}.dll" if sys.platform == "win32" else f"lib{name}.so"
        return os.path.join(*package.split("."), filename)

    def get_export_symbols(self, ext):
        return []  # no PyInit_ function: the library is loaded with ctypes


if sys.platform == "win32":
    compile_args = ["/O2", "/fp:precise"]
else:
    compile_args = [
        "-O3",  # vectorises the batched force (tension_batch)
        "-fexceptions",  # MuJoCo's compiler reports config errors by unwinding through init
        "-ffp-contract=off",  # no fused multiply-add: the same rounding as the Python reference
        "-fno-fast-math",
        "-fno-math-errno",  # sqrt inlined; values unchanged
        "-fvisibility=hidden",
        "-Wall",
    ]

setup(
    ext_modules=[
        Extension(
            f"efam_mujoco.plugin.{LIBRARY_NAME}",
            sources=[PLUGIN_SOURCE],
            depends=["efam_mujoco/plugin/efam_effects.h"],
            extra_compile_args=compile_args,
            libraries=[] if sys.platform == "win32" else ["m"],
        )
    ],
    cmdclass={"build_ext": BuildPlugin},
)
