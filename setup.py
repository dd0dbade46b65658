"""Build the native MuJoCo actuator plugin ``efam.muscle`` during the ordinary ``pip install``.

Everything else about the package is in pyproject.toml. The plugin is a plain C shared library
(loaded with ctypes by ``efam_mujoco.plugin``, not imported as a Python module), compiled
against the headers that ship inside the ``mujoco`` wheel. It is deliberately not linked against
``libmujoco``: MuJoCo's symbols are resolved at load time from the ``libmujoco`` the ``mujoco``
package has already loaded, so the same build works with any 3.17.x wheel and in any venv.
"""

from __future__ import annotations

import importlib.util
import os
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

PLUGIN_SOURCE = "efam_mujoco/plugin/efam_muscle.c"
LIBRARY_NAME = "efam_muscle"  # the loader looks for libefam_muscle.so (efam_muscle.dll)


def mujoco_include_dir() -> str:
    """The ``include`` directory of the installed ``mujoco`` wheel (found without importing it)."""
    spec = importlib.util.find_spec("mujoco")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(
            "building the efam.muscle plugin needs the 'mujoco' package (its headers): "
            "pip install 'mujoco>=3.17,<3.18', or build with pip's default build isolation"
        )
    for location in spec.submodule_search_locations:
        include = os.path.join(location, "include")
        if os.path.isfile(os.path.join(include, "mujoco", "mjplugin.h")):
            return include
    raise RuntimeError(f"the installed mujoco package ({spec.origin}) has no include/mujoco/mjplugin.h")


class BuildPlugin(build_ext):
    """Compile the plugin as a plain shared library with the flags the model needs."""

    def build_extensions(self):
        include = mujoco_include_dir()
        for ext in self.extensions:
            ext.include_dirs.append(include)
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
