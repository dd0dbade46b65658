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


def install(directory: str | None = None) -> str:
    """Copy the plugin library into ``directory`` (default: MuJoCo's plugin directory, which
    must exist; another directory is created). Atomic: a crash leaves the old copy or the new
    one, never half a library. Returns the installed path."""
    target_dir = os.fspath(directory) if directory is not None else mujoco_plugin_dir()
    if directory is None and not os.path.isdir(target_dir):
        raise OSError(f"MuJoCo's plugin directory {target_dir} does not exist (is mujoco installed?)")
    os.makedirs(target_dir, exist_ok=True)
    target = os.path.join(target_dir, LIBRARY_FILE)
    source = library_path()
    if os.path.abspath(source) == os.path.abspath(target):
        return target
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


def remove(directory: str | None = None) -> list[str]:
    """Remove the plugin library from ``directory`` (default: MuJoCo's plugin directory);
    returns the removed paths (none when it was not installed)."""
    if directory is None:
        paths = installed_copies()
    else:
        path = os.path.join(os.fspath(directory), LIBRARY_FILE)
        paths = [path] if os.path.exists(path) else []
    for path in paths:
        os.remove(path)
    return paths


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
        print(library_path())
        return 0
    if args.remove:
        removed = remove(args.dir)
        for path in removed:
            print(f"removed {path}")
        if not removed:
            print("efam.muscle was not installed in MuJoCo's plugin directory: nothing removed")
        return 0
    target = install(args.dir)
    print(f"installed {target}")
    print("plain `import mujoco` (and mujoco.viewer, dm_control) now loads efam.muscle")
    return 0
