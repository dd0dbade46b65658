"""The one output policy: how every command writes a user-visible file.

* **Atomic.** Every file (JSON, MJCF, muscle files, CSV, PNG figures) is written to a unique
  temporary in the target's folder (``tempfile.mkstemp``: a name no user file has) and renamed
  over the target, so an interrupted or failed write leaves the old file as it was and no
  temporary behind. A fixed name such as ``X.tmp`` is never used (it could be a user's file).
* **Inputs are never outputs.** :func:`check_outputs` refuses an output that is an input (same
  file, through any path or link), naming both; two outputs that are one file are refused too.
  The installed package (``site-packages``) is never written into.
* **Report folders are replaced as a whole** (:func:`replace_folder`): the new contents are built
  in a temporary folder beside it and swapped in, so a killed run never leaves a new report mixed
  with the previous run's files. A folder that is not empty and not a previous efam report is
  never replaced (it might hold the user's data).
* **Names are sanitised** (:func:`safe_name`): a muscle called ``../x`` cannot write outside the
  output folder.
* **Strict JSON** (:func:`strict_json`): a non-finite number is an error naming where it is,
  never an ``Infinity``/``NaN`` token (not JSON).
* **MuJoCo's log** (:func:`route_mujoco_log`): MuJoCo warnings go to a file the user names, or
  to standard error; MuJoCo never creates ``MUJOCO_LOG.TXT`` in the working folder.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import sys
import sysconfig
import tempfile
from pathlib import Path

#: Marker file every report folder holds: only a folder with it (or an empty one) is replaced.
REPORT_MARKER = ".efam_report"


class OutputError(ValueError):
    """An output that would overwrite an input, land in the installed package, or is not JSON."""


# ---------------------------------------------------------------------------- atomic files
def _temporary_beside(path: Path, suffix: str = "") -> tuple[int, Path]:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".efam-tmp{suffix}", dir=path.parent)
    except OSError as err:  # the user's path, not the temporary's name nobody asked for
        raise OutputError(f"cannot write {path} ({err.strerror or err})") from None
    return fd, Path(name)


def _mode_of(path: Path) -> int:
    """The permissions a new file gets (mkstemp makes 0600; users expect their umask)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def _renamed_over(tmp: Path, path: Path):
    """Around the writing of ``tmp``: on success give it the usual permissions and rename it over
    ``path``; in every case leave no temporary behind."""
    try:
        yield
        os.chmod(tmp, _mode_of(path))
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to a unique temporary beside ``path`` and rename it over ``path``."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path}: is a folder, not a file")
    fd, tmp = _temporary_beside(path)
    with _renamed_over(tmp, path):
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
    return path


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` atomically (see :func:`write_bytes_atomic`)."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def strict_json(doc, *, indent: int | None = 1) -> str:
    """``doc`` as standard JSON text; a non-finite number raises :class:`OutputError` naming its
    place (``rows[2].blocked_force_N``), numpy scalars and arrays become numbers and lists."""
    return json.dumps(_plain(doc, "$"), indent=indent, allow_nan=False) + "\n"


def _plain(value, where: str):
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, dict):
        return {str(k): _plain(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if hasattr(value, "tolist"):  # numpy array or scalar
        return _plain(value.tolist(), where)
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        if not math.isfinite(value):
            raise OutputError(f"JSON output: {where} is {value!r}, not a finite number (not valid JSON)")
        return value
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"JSON output: {where}: {type(value).__name__} is not JSON serialisable") from None
    return _plain(number, where)


def write_json_atomic(path: str | os.PathLike, doc) -> Path:
    """Write ``doc`` as strict JSON (:func:`strict_json`) atomically; nothing is written when a
    value is not finite."""
    return write_text_atomic(path, strict_json(doc))


def save_figure(fig, path: str | os.PathLike, **savefig_kwargs) -> Path:
    """``fig.savefig`` into a unique temporary beside ``path``, then rename: a failed or killed
    write never leaves a truncated image. The format follows ``path``'s suffix."""
    path = Path(path)
    fmt = savefig_kwargs.pop("format", None) or (path.suffix[1:].lower() or "png")
    fd, tmp = _temporary_beside(path, suffix=path.suffix)
    os.close(fd)
    with _renamed_over(tmp, path):
        fig.savefig(tmp, format=fmt, **savefig_kwargs)
    return path


# ------------------------------------------------------------------------------- names
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")


def safe_name(name: str, fallback: str = "output", max_length: int = 80) -> str:
    """A file-name component made from ``name``: letters, digits and ``._+-`` only (others
    become ``_``), no leading dot, no path separators or ``..``; ``fallback`` when nothing is
    left. ``safe_name("../../x") == "x"``."""
    text = _UNSAFE.sub("_", str(name)).strip("._")
    text = re.sub(r"\.{2,}", ".", text)[:max_length].strip("._")
    return text or fallback


# ------------------------------------------------------------------- inputs vs outputs
def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


def installed_package_dirs() -> list[Path]:
    """Folders a command must never write into: the interpreter's ``site-packages`` folders,
    where an installed ``efam_mujoco`` lives (an editable checkout is not among them)."""
    dirs = set()
    for key in ("purelib", "platlib"):
        with contextlib.suppress(KeyError):
            dirs.add(Path(sysconfig.get_paths()[key]).resolve())
    return sorted(dirs)


#: the output flags that name a folder (every other output is a file, and a folder there is refused)
FOLDER_OUTPUTS = ("--out", "--report", "--models-dir")


def check_outputs(outputs: dict[str, object], inputs: dict[str, object]) -> None:
    """Refuse outputs that would overwrite an input or each other, or land in the package.

    ``outputs`` and ``inputs`` map a label the user knows (a CLI flag: ``--json``, ``FILE``) to
    a path or a list of paths (None entries are ignored). For an output folder (``--report``)
    an input inside it is refused too, because the folder is replaced as a whole.
    """
    ins = [(label, Path(p)) for label, v in inputs.items() for p in _paths(v)]
    outs = [(label, Path(p)) for label, v in outputs.items() for p in _paths(v)]
    package = installed_package_dirs()
    for i, (label, out) in enumerate(outs):
        if not str(out).strip() or str(out) in (".", ".."):
            if label not in FOLDER_OUTPUTS:
                raise OutputError(f"{label}: '{out}' is not a file name")
        for in_label, source in ins:
            if _same_file(out, source) or (out.is_dir() and _inside(source, out)):
                raise OutputError(
                    f"{label} {out} would overwrite the input {in_label} {source}; "
                    "choose another output path (inputs are never modified)"
                )
        for other_label, other in outs[:i]:
            if _same_file(out, other):
                raise OutputError(f"{other_label} and {label} are the same file ({out}); give two paths")
        if label not in FOLDER_OUTPUTS and out.is_dir():
            raise OutputError(
                f"{label} {out}: is a folder, not a file; give a file name (e.g. "
                f"{out / ('figure.png' if label in ('--figure', '--strip') else 'result.json')})"
            )
        _check_writable_place(label, out)
        for folder in package:
            if _inside(out, folder):
                raise OutputError(
                    f"{label} {out} is inside the installed package ({folder}); write somewhere else"
                )


def _check_writable_place(label: str, out: Path) -> None:
    """The nearest existing ancestor of ``out`` must be a folder we may write into: found now,
    before a long computation, not after other outputs were written."""
    for parent in [out.parent, *out.parent.parents] if str(out.parent) else []:
        if parent.exists():
            if not parent.is_dir():
                raise OutputError(f"{label} {out}: {parent} is a file, not a folder")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise OutputError(f"{label} {out}: cannot write into {parent} (permission denied)")
            return


def _paths(value) -> list:
    if value is None:
        return []
    if isinstance(value, (str, os.PathLike)):
        return [value]
    return [v for v in value if v is not None and isinstance(v, (str, os.PathLike))]


# ---------------------------------------------------------------------------- report folders
def check_replaceable_folder(path: str | os.PathLike, label: str = "output folder") -> Path:
    """Refuse a folder that exists and is neither empty nor a previous efam report (it would be
    replaced as a whole), and a path that is a file."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{label} {path} is a file, not a folder")
    if path.is_dir() and any(path.iterdir()) and not (path / REPORT_MARKER).is_file():
        raise OutputError(
            f"{label} {path} exists, is not empty and is not an efam report folder (no "
            f"{REPORT_MARKER}); it would be replaced as a whole, so name a new or empty folder"
        )
    return path


@contextlib.contextmanager
def replace_folder(path: str | os.PathLike, label: str = "output folder"):
    """Build a report folder in a temporary folder beside ``path``; on success swap it in as a
    whole (the previous report is removed only after the new one is in place); on any failure
    remove the temporary and leave ``path`` as it was. Yields the temporary folder to fill.

    A folder with other contents than a previous report is refused (see
    :func:`check_replaceable_folder`).
    """
    path = check_replaceable_folder(path, label)
    path.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".efam-tmp", dir=path.parent))
    try:
        yield staging
        (staging / REPORT_MARKER).write_text("written by efam_mujoco; this folder is replaced as a whole\n")
        os.chmod(staging, 0o777 & ~_umask())
        old = None
        if path.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".efam-old", dir=path.parent))
            os.rmdir(old)
            os.replace(path, old)
        os.replace(staging, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    finally:
        if staging.exists():
            shutil.rmtree(staging, ignore_errors=True)


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


# ------------------------------------------------------------------------------ MuJoCo log
_log_target: list = [None]
_collectors: list[list[str]] = []


def route_mujoco_log(path: str | os.PathLike | None = None) -> None:
    """Send MuJoCo's warnings to ``path`` (appended, one line each) or, without a path, to
    standard error; MuJoCo then never writes ``MUJOCO_LOG.TXT`` into the working folder."""
    import mujoco

    _log_target[0] = None if path is None else Path(path)
    mujoco.set_mju_user_warning(_mujoco_warning)


def _mujoco_warning(message: str) -> None:
    text = " ".join(str(message).split())
    for collector in _collectors:
        collector.append(text)
    target = _log_target[0]
    if target is None:
        print(f"MuJoCo warning: {text}", file=sys.stderr)
        return
    with contextlib.suppress(OSError), open(target, "a", encoding="utf-8") as handle:
        handle.write(text + "\n")


@contextlib.contextmanager
def mujoco_warnings():
    """Collect the MuJoCo warnings raised inside the block into the yielded list (they are also
    routed as :func:`route_mujoco_log` says)."""
    import mujoco

    previous = mujoco.get_mju_user_warning()
    if previous is not _mujoco_warning:
        mujoco.set_mju_user_warning(_mujoco_warning)
    collected: list[str] = []
    _collectors.append(collected)
    try:
        yield collected
    finally:
        _collectors.remove(collected)
        if previous is not _mujoco_warning:
            mujoco.set_mju_user_warning(previous)


# ---------------------------------------------------------------------------- output sets
class OutputSet:
    """All outputs of one command, written together at the end: texts are kept in memory and
    files (figures) rendered into a staging folder; :meth:`commit` then moves each into place
    (each an atomic rename). A failure before the commit writes nothing; so a bad ``--figures``
    path cannot fail after the muscle file was written."""

    def __init__(self):
        self.texts: dict[Path, str] = {}
        self._staging: Path | None = None
        self.staged: dict[Path, Path] = {}

    def text(self, path, text: str) -> Path:
        """Write ``text`` to ``path`` at :meth:`commit`."""
        self.texts[Path(path)] = text
        return Path(path)

    def json(self, path, doc) -> Path:
        """Write ``doc`` as strict JSON to ``path`` at :meth:`commit` (checked now)."""
        return self.text(path, strict_json(doc))

    def staging_path(self, path) -> Path:
        """Where to render ``path`` now; it is moved to ``path`` by :meth:`commit`."""
        path = Path(path)
        if self._staging is None:
            self._staging = Path(tempfile.mkdtemp(prefix="efam-outputs."))  # the system's temporary folder
        staged = self._staging / f"{len(self.staged)}{path.suffix}"
        self.staged[path] = staged
        return staged

    def commit(self) -> list[Path]:
        """Write every output (each atomically); the folders are made first, so a bad place fails
        before any file is written."""
        try:
            for path in [*self.texts, *self.staged]:
                path.parent.mkdir(parents=True, exist_ok=True)
                if path.is_dir():
                    raise OutputError(f"{path}: is a folder, not a file")
            written = []
            for path, text in self.texts.items():
                written.append(write_text_atomic(path, text))
            for path, staged in self.staged.items():
                path.parent.mkdir(parents=True, exist_ok=True)
                write_bytes_atomic(path, staged.read_bytes())
                written.append(path)
            return written
        finally:
            self.discard()

    def discard(self) -> None:
        """Remove the staging folder (what was not committed is dropped)."""
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None
