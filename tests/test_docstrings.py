"""Every public definition of the package has a docstring (the API reference is built from them).

Public: a module not starting with ``_``; in it, a function or class defined there whose name
does not start with ``_``; in such a class, the methods and properties it defines whose names do
not start with ``_``. Re-exports are checked where they are defined. The failure lists each
missing name with its file and line, so a gap is one look away.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import pkgutil
from pathlib import Path

import efam_mujoco

REPO = Path(efam_mujoco.__file__).resolve().parents[1]


def public_modules() -> list:
    """The package and every module under it whose dotted name has no ``_`` part."""
    names = [efam_mujoco.__name__]
    for info in pkgutil.walk_packages(efam_mujoco.__path__, prefix="efam_mujoco."):
        spec = importlib.util.find_spec(info.name)
        python_source = spec is not None and (spec.origin or "").endswith(".py")  # not the C plugin
        if python_source and not any(part.startswith("_") for part in info.name.split(".")):
            names.append(info.name)
    return [importlib.import_module(name) for name in sorted(names)]


def _where(obj, fallback: str) -> str:
    try:
        file = Path(inspect.getsourcefile(obj)).resolve()
        line = inspect.getsourcelines(obj)[1]
        return f"{file.relative_to(REPO)}:{line}"
    except (TypeError, OSError, ValueError):
        return fallback


def _has_doc(obj) -> bool:
    return bool((inspect.getdoc(obj) or "").strip())


def _own_doc(obj) -> bool:
    """A docstring written for this object (not one inherited from a base class or ``object``)."""
    return bool((getattr(obj, "__doc__", None) or "").strip())


def missing_docstrings() -> list[str]:
    """``file:line name`` of every public definition without a docstring."""
    missing = []
    for module in public_modules():
        module_file = Path(module.__file__).resolve().relative_to(REPO)
        if not _own_doc(module):
            missing.append(f"{module_file}:1 module {module.__name__}")
        for name, obj in vars(module).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
                continue
            if not (inspect.isfunction(obj) or inspect.isclass(obj)):
                continue
            if not _own_doc(obj):
                missing.append(f"{_where(obj, str(module_file))} {module.__name__}.{name}")
            if inspect.isclass(obj):
                for attr, member in vars(obj).items():
                    if attr.startswith("_"):
                        continue
                    target = member.fget if isinstance(member, property) else member
                    if isinstance(member, (staticmethod, classmethod)):
                        target = member.__func__
                    if not (inspect.isfunction(target) or isinstance(member, property)):
                        continue
                    if target is None or not _has_doc(target):
                        missing.append(f"{_where(target, str(module_file))} {module.__name__}.{name}.{attr}")
    return missing


def test_every_public_definition_has_a_docstring():
    missing = missing_docstrings()
    assert not missing, f"{len(missing)} public definitions without a docstring:\n" + "\n".join(missing)


def test_the_walk_sees_the_package():
    names = {m.__name__ for m in public_modules()}
    assert {"efam_mujoco.muscle", "efam_mujoco.plugin", "efam_mujoco.calibrate.fit"} <= names
