"""``efam install-plugin``: put the efam.muscle library where MuJoCo itself looks for plugins.

``import efam_mujoco`` registers the plugin, so Python code that imports it needs nothing more.
This is for code that does not: plain ``mujoco`` scripts, ``python -m mujoco.viewer``, dm_control
environments, MuJoCo's ``simulate`` and C/C++ programs. ``import mujoco`` loads every library in
its plugin directory (``mujoco.PLUGINS_DIR``, inside the installed ``mujoco`` package);
``simulate`` loads those in the ``mujoco_plugin`` directory beside its executable (``--dir``). The copy is
byte-for-byte this build; ``import efam_mujoco`` warns when an installed copy is another build
(after a rebuild or an upgrade: run the command again).
"""

from __future__ import annotations

import os
import shutil
import tempfile

from . import LIBRARY_FILE, installed_copies, library_path, mujoco_plugin_dir

#: bytes every build of the library holds (its version entry point, in the dynamic symbol
#: table): how a file is told to be an efam.muscle build before it is replaced or removed
_BUILD_MARK = b"efam_muscle_mujoco_header_version"
#: leading bytes of a shared library: ELF (Linux), PE (Windows), Mach-O (macOS, both byte orders)
_LIBRARY_MAGIC = (b"\x7fELF", b"MZ", b"\xcf\xfa\xed\xfe", b"\xce\xfa\xed\xfe", b"\xca\xfe\xba\xbe")


class InstallError(ValueError):
    """``efam install-plugin`` refused to act: the message names the path and why."""


def is_plugin_build(path: str) -> bool:
    """Whether ``path`` is a regular file holding a build of the efam.muscle library (a shared
    library with its version entry point); read, never loaded: loading runs a library's code."""
    if not os.path.isfile(path):
        return False
    try:
        with open(path, "rb") as f:
            head = f.read(4)
            if not head.startswith(_LIBRARY_MAGIC):
                return False
            tail = b""
            # the mark may straddle two chunks: keep the end of the previous one
            while chunk := f.read(1 << 20):
                if _BUILD_MARK in tail + chunk:
                    return True
                tail = chunk[-len(_BUILD_MARK) :]
    except OSError:
        return False
    return False


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _target_dir(directory: str | None, installing: bool = True) -> str:
    """The folder to act in, checked: ``--dir`` names a folder (or one to create), not a file;
    installing, not one inside the efam_mujoco package."""
    if directory is None:
        return mujoco_plugin_dir()
    target_dir = os.fspath(directory)
    if not target_dir.strip():
        raise InstallError("--dir is empty: give the folder to install into")
    if os.path.basename(os.path.normpath(target_dir)) == LIBRARY_FILE and not os.path.isdir(target_dir):
        raise InstallError(
            f"--dir {target_dir}: give the folder, not the library's own path (e.g. --dir "
            f"{os.path.dirname(os.path.normpath(target_dir)) or '.'})"
        )
    if os.path.lexists(target_dir) and not os.path.isdir(target_dir):
        raise InstallError(f"--dir {target_dir}: exists and is not a folder")
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    where = os.path.realpath(target_dir)
    library_dir = os.path.dirname(os.path.realpath(os.path.join(package, "plugin", LIBRARY_FILE)))
    inside = os.path.commonpath([where, os.path.realpath(package)]) == os.path.realpath(package)
    if installing and inside and where != library_dir:
        # nothing is written inside the package folder (its presets are inputs): '--dir
        # efam_mujoco/presets' put a library among them; the library's own folder is said below
        raise InstallError(
            f"--dir {target_dir}: is inside the efam_mujoco package ({package}); give a folder outside it"
        )
    return target_dir


def install(directory: str | None = None) -> str:
    """Copy the plugin library into ``directory`` (default: MuJoCo's plugin directory, which
    must exist; another directory is created). Atomic: a crash leaves the old copy or the new
    one, never half a library. A file already there is replaced only when it is a build of this
    library (:func:`is_plugin_build`): anything else of that name is the user's and is refused.
    Returns the installed path."""
    target_dir = _target_dir(directory)
    if directory is None and not os.path.isdir(target_dir):
        raise OSError(f"MuJoCo's plugin directory {target_dir} does not exist (is mujoco installed?)")
    target = os.path.join(target_dir, LIBRARY_FILE)
    source = library_path()
    if _same_file(source, target):
        return target  # this build's own file (the package folder itself, or a link to it)
    if os.path.isdir(target):
        raise InstallError(f"{target} is a folder: not replaced")
    # a link is replaced, never its target; a link to a file that is not a build is the user's
    if os.path.lexists(target) and os.path.exists(target) and not is_plugin_build(target):
        raise InstallError(
            f"{target} exists and is not an efam.muscle plugin library: not replaced (move it away, or "
            "give another --dir)"
        )
    os.makedirs(target_dir, exist_ok=True)
    handle, partial = tempfile.mkstemp(prefix=".efam_muscle.", dir=target_dir)
    os.close(handle)
    try:
        shutil.copyfile(source, partial)
        os.chmod(partial, 0o755)
        os.replace(partial, target)
    finally:
        if os.path.exists(partial):
            os.remove(partial)
    return target


def remove(directory: str | None = None) -> tuple[list[str], list[str]]:
    """Remove the plugin library from ``directory`` (default: MuJoCo's plugin directory). Only
    builds of this library are removed, never the package's own copy (every ``efam`` command
    loads it) and never a file that only has the name. Returns (removed paths, paths left alone)."""
    if directory is None:
        paths = installed_copies()
    else:
        path = os.path.join(_target_dir(directory, installing=False), LIBRARY_FILE)
        paths = [path] if os.path.lexists(path) else []
    removed, kept = [], []
    for path in paths:
        if _same_file(path, library_path()) and not os.path.islink(path):
            kept.append(path)  # the package's own library, not an installed copy
        elif os.path.islink(path) or is_plugin_build(path):
            os.remove(path)
            removed.append(path)
        else:
            kept.append(path)
    return removed, kept


def register_cli(subparsers) -> None:
    """Add the ``install-plugin`` subcommand."""
    p = subparsers.add_parser(
        "install-plugin",
        help="copy the efam.muscle plugin into MuJoCo's plugin directory (for code that does not "
        "import efam_mujoco)",
        description=(
            "Copy the efam.muscle plugin library into MuJoCo's plugin directory, so that plain "
            "`import mujoco`, `python -m mujoco.viewer`, dm_control and C programs find it without "
            "`import efam_mujoco`. For MuJoCo's `simulate`, give --dir MUJOCO/bin/mujoco_plugin (the "
            "directory beside the simulate executable)."
        ),
    )
    p.add_argument(
        "--dir",
        metavar="DIR",
        default=None,
        help="install into DIR instead (created if missing); default: the mujoco package's plugin directory",
    )
    p.add_argument(
        "--remove", action="store_true", help="remove the installed copy instead (default: install)"
    )
    p.add_argument(
        "--print-path",
        action="store_true",
        help="only print the path of this build's library (for mj_loadPluginLibrary); install nothing",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``efam install-plugin`` with parsed arguments."""
    if args.print_path:
        if args.remove or args.dir is not None:
            raise InstallError("--print-path only prints this build's path: it takes no --remove or --dir")
        print(library_path())
        return 0
    where = args.dir if args.dir is not None else "MuJoCo's plugin directory"
    if args.remove:
        removed, kept = remove(args.dir)
        for path in removed:
            print(f"removed {path}")
        for path in kept:
            what = (
                "the package's own library"
                if _same_file(path, library_path())
                else "not an efam.muscle build"
            )
            print(f"left {path}: {what}")
        if not removed:
            print(f"efam.muscle was not installed in {where}: nothing removed")
        return 0
    target = install(args.dir)
    if _same_file(library_path(), target):  # nothing was copied: say so, not "installed"
        print(f"{target} is this build's own library: nothing to install there")
        return 0
    print(f"installed {target}")
    if args.dir is None:
        print("plain `import mujoco` (and mujoco.viewer, dm_control) now loads efam.muscle")
    else:
        print(
            "MuJoCo's `simulate` loads it when this is the mujoco_plugin folder beside its executable; "
            "C programs load it with mj_loadPluginLibrary()"
        )
    return 0
