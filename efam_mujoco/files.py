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
import hashlib
import json
import math
import os
import re
import shutil
import sys
import sysconfig
import tempfile
from pathlib import Path

from .units import visible

#: Marker file every report folder holds: only a folder with it (or an empty one) is replaced.
REPORT_MARKER = ".efam_report"


class OutputError(ValueError):
    """An output that would overwrite an input, land in the installed package, or is not JSON."""


# ---------------------------------------------------------------------------- atomic files
def _link_target(path: str | os.PathLike) -> Path:
    """``path``, or what it links to: an output (file or report folder) goes where the link
    points, the link kept."""
    path = Path(path)
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def output_target(path: str | os.PathLike, label: str = "output") -> Path:
    """Where an output file is really written: a link's target (the link is kept, the file it
    points to replaced), refused when that is not a regular file or a new name: renaming over a
    device, a pipe or a socket would replace it with a regular file (``--json /dev/null`` as
    root replaced the system's /dev/null)."""
    path = Path(path)
    target = _link_target(path)
    # a link the kernel resolves but realpath cannot (/dev/stdout on a pipe: /proc/self/fd/1 ->
    # 'pipe:[123]') is judged by what it opens, not by a name that does not exist: the work was
    # done and then 'cannot write /proc/.../pipe:[123]'
    if path.is_symlink() and path.exists() and not target.exists():
        target = path
    if target.exists() and not target.is_file() and not target.is_dir():
        raise OutputError(
            f"{label} {path} is not a regular file (a device, a pipe or a socket): outputs are written to a "
            "temporary and renamed over, which would replace it; give a file name"
        )
    return target


#: the most of an output's name a temporary beside it repeats: a name near the file system's limit
#: (255 bytes) is a good output name, but '.NAME.XXXXXXXX.efam-tmp' beside it was not one
TEMPORARY_NAME_KEEP = 100


def _temporary_prefix(name: str) -> str:
    """``.NAME.`` for a temporary beside the output ``NAME``, ``NAME`` cut to
    :data:`TEMPORARY_NAME_KEEP` bytes (never inside a character)."""
    kept = name.encode("utf-8", "surrogateescape")[:TEMPORARY_NAME_KEEP].decode("utf-8", "ignore")
    return f".{kept}."


def _temporary_beside(path: Path, suffix: str = "") -> tuple[int, Path]:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(
            prefix=_temporary_prefix(path.name), suffix=f".efam-tmp{suffix}", dir=path.parent
        )
    except OSError as err:  # the user's path, not the temporary's name nobody asked for
        raise OutputError(f"cannot write {path} ({err.strerror or err})") from None
    return fd, Path(name)


def _mode_of(path: Path) -> int:
    """The permissions a new file gets (mkstemp makes 0600; users expect their umask)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def _remove_temporaries(ready) -> None:
    """Remove the temporaries of ``ready`` ((temporary, target) pairs) that were not renamed."""
    for tmp, _ in ready:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


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


def _write_beside(path: Path, data: bytes) -> Path:
    """``data`` in a unique temporary beside ``path``, on disk (fsync) with the permissions a new
    file gets; returns the temporary, which the caller renames. A failed write removes it."""
    fd, tmp = _temporary_beside(path)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, _mode_of(path))
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
    return tmp


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to a unique temporary beside ``path`` and rename it over ``path``."""
    path = output_target(path)
    if path.is_dir():
        raise OutputError(f"{path}: is a folder, not a file")
    tmp = _write_beside(path, data)
    try:
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
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


#: Figure formats matplotlib writes with its built-in backends (``FigureCanvasBase.
#: get_supported_filetypes()`` of matplotlib 3.7-3.10); used when matplotlib is not importable.
FIGURE_FORMATS = (
    "eps", "jpeg", "jpg", "pdf", "pgf", "png", "ps", "raw", "rgba", "svg", "svgz", "tif", "tiff", "webp",
)  # fmt: skip
#: The output flags that name a figure file: checked (format, matplotlib) before a command runs.
FIGURE_OUTPUTS = ("--figure", "--strip")


def figure_formats() -> tuple[str, ...]:
    """The file suffixes (lower case, no dot) a figure can be written as: matplotlib's own list
    when it is installed, else :data:`FIGURE_FORMATS`; ``pgf`` only where the TeX program its
    backend measures text with is installed (without it the figure failed after the command had
    done its work and written its other outputs)."""
    try:
        import matplotlib
        from matplotlib.backend_bases import FigureCanvasBase
    except ImportError:
        formats, tex = FIGURE_FORMATS, "xelatex"
    else:
        formats = tuple(sorted(FigureCanvasBase.get_supported_filetypes()))
        tex = str(matplotlib.rcParams.get("pgf.texsystem", "xelatex"))
    return tuple(f for f in formats if f != "pgf" or shutil.which(tex))


def check_figure_path(label: str, path: str | os.PathLike) -> None:
    """Refuse a figure path whose suffix matplotlib cannot write (``x.txt``, ``x.json``), and a
    figure when matplotlib is missing, naming the flag: found before the work, not after it.
    A path without a suffix is written as PNG (:func:`save_figure`)."""
    import importlib.util

    suffix = Path(path).suffix[1:].lower()
    formats = figure_formats()
    if suffix and suffix not in formats:
        raise OutputError(
            f"{label} {path}: '.{suffix}' is not a figure format; use one of "
            f"{', '.join('.' + f for f in formats)} (e.g. .png, .pdf, .svg)"
        )
    if importlib.util.find_spec("matplotlib") is None:
        raise OutputError(f"{label} {path}: writing a figure needs matplotlib (pip install matplotlib)")


def save_figure(fig, path: str | os.PathLike, **savefig_kwargs) -> Path:
    """``fig.savefig`` into a unique temporary beside ``path``, then rename: a failed or killed
    write never leaves a truncated image. The format follows ``path``'s suffix (PNG without one);
    a suffix matplotlib cannot write is an :class:`OutputError` before anything is written."""
    path = output_target(path, "figure")
    if "format" not in savefig_kwargs:
        check_figure_path("figure", path)
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
    where an installed ``efam_mujoco`` lives, and the ``efam_mujoco`` package folder itself
    (in an editable checkout too: its presets are inputs a preset name reads, ``--json`` over
    ``efam_mujoco/presets/fam1.json`` replaced FAM1 for every later command). The rest of a
    checkout (``models/``, ``bench/``) may be written."""
    dirs = {Path(__file__).resolve().parent}
    for key in ("purelib", "platlib"):
        with contextlib.suppress(KeyError):
            dirs.add(Path(sysconfig.get_paths()[key]).resolve())
    return sorted(dirs)


#: the output flags that name a folder (every other output is a file, and a folder there is refused)
FOLDER_OUTPUTS = ("--out", "--report", "--models-dir")
#: the folder outputs that are never a file (``--out`` is a folder for demo, a file for calibrate)
FOLDER_ONLY_OUTPUTS = ("--report", "--models-dir")
#: data files an output never replaces, even when they are not the command's inputs
DATA_SUFFIXES = (".csv", ".tsv")
#: the output flags whose content has a format whatever their name, flag -> format (every
#: command's ``--json``, the arm's MJCF ``--xml``; a command adds the efam documents it writes,
#: such as calibrate's ``--out`` muscle file, through ``set_defaults(document_outputs=...)``)
FORMATTED_OUTPUTS = {"--json": "JSON", "--xml": "XML"}
#: the preset muscles' names as a user types them (``musclefile.PRESETS``, lower case): an output
#: of that bare name is refused, as it would shadow the preset in the folder it is written to
PRESET_NAMES = ("fam1", "fam2")


def check_json_name(label: str, path: str | os.PathLike, content: str = "JSON") -> None:
    """Refuse a JSON (or XML: ``content``) output named like a recording (``--json out.csv``):
    the readers take any file with a data suffix (:data:`DATA_SUFFIXES`) for a recording, so a
    later command read the JSON as one. A name without a suffix, or with any other, is the
    user's choice."""
    suffix = Path(path).suffix
    own = f".{content.lower()}"
    if suffix.lower() in DATA_SUFFIXES:
        raise OutputError(
            f"{label} {path}: writes {content}, but '{suffix}' is a recording's suffix (a later command would "
            f"read the file as a recording); give it a {own} name (e.g. {Path(path).with_suffix(own)})"
        )


def check_kind_of_name(label: str, path: str | os.PathLike, content: str = "JSON") -> None:
    """Refuse a JSON (or XML: ``content``) output named like another kind of file: a figure
    (``--json table.png``) or the other text format (``arm --xml arm.json``). A viewer, or a
    command that reads a file by its name (a muscle file, a model), would open it as what it is
    not."""
    suffix = Path(path).suffix
    own = f".{content.lower()}"
    other = {"JSON": ".xml", "XML": ".json"}.get(content)
    if suffix.lower().lstrip(".") in figure_formats() or suffix.lower() == other:
        raise OutputError(
            f"{label} {path}: writes {content}, but '{suffix}' names another kind of file; give it a {own} "
            f"name (e.g. {Path(path).with_suffix(own)})"
        )


#: An efam document's declared format near the top of a JSON file (``"format": "efam_mujoco.muscle/1"``)
_DOCUMENT_FORMAT = re.compile(rb'"format"\s*:\s*"(efam_mujoco\.[A-Za-z_]+/[0-9]+)"')
#: What each efam document is, in words, for the message that refuses to replace one
DOCUMENT_NAMES = {
    "efam_mujoco.muscle": "a muscle file",
    "efam_mujoco.arm_spec": "an arm spec",
    "efam_mujoco.catalogue": "a sizing catalogue",
}


def check_replaced_kind(label: str, path: str | os.PathLike, content: str, writes: str | None = None) -> None:
    """Refuse to replace an existing file that does not hold what this output writes: a JSON
    output replaces only JSON (``{`` or ``[`` first), and not an efam document of another kind
    (a muscle file, an arm spec, a catalogue: another command's input) unless it writes that
    document (``writes``, e.g. ``efam_mujoco.muscle/1``); an XML output replaces only XML. A
    recording saved as ``.txt``, a script or a muscle file given to ``--json`` by a slip of the
    tab key was replaced without a word. A new or empty file, or one that cannot be read (the
    write's own check names it), is not refused here."""
    path = Path(path)
    try:
        if not path.is_file() or path.stat().st_size == 0:
            return
        with open(path, "rb") as handle:
            head = handle.read(4096).lstrip(b"\xef\xbb\xbf \t\r\n")
    except OSError:
        return
    if not head:  # blank: nothing to lose
        return
    opens = {"JSON": (b"{", b"["), "XML": (b"<",)}.get(content, ())
    if opens and head[:1] not in opens:
        first = head.split(b"\n", 1)[0][:60].decode("utf-8", "replace").strip()
        raise OutputError(
            f"{label} {path}: the file exists and does not hold {content} (it begins '{visible(first)}'); "
            f"this command would replace it with {content}: give the output a new name"
        )
    found = _DOCUMENT_FORMAT.search(head) if content == "JSON" else None
    if found and found.group(1).decode() != writes:
        kind = found.group(1).decode()
        what = DOCUMENT_NAMES.get(kind.split("/")[0], "an efam document")
        raise OutputError(
            f"{label} {path}: the file is {what} ({kind}), which this output would replace; "
            "give the output a new name"
        )


def check_outputs(
    outputs: dict[str, object],
    inputs: dict[str, object],
    formatted: dict[str, str] = FORMATTED_OUTPUTS,
    documents: dict[str, str] | None = None,
) -> None:
    """Refuse outputs that would overwrite an input or each other, or land in the package.

    ``outputs`` and ``inputs`` map a label the user knows (a CLI flag: ``--json``, ``FILE``) to
    a path or a list of paths (None entries are ignored). For an output folder (``--report``)
    an input inside it is refused too, because the folder is replaced as a whole. The outputs
    labelled in ``formatted`` (flag -> "JSON", "XML") write that format: one named like a
    recording is refused (:func:`check_json_name`), and an existing file they would replace must
    hold that format (:func:`check_replaced_kind`; ``documents``: flag -> the efam document
    format that output writes, e.g. calibrate's muscle file).
    """
    ins = [(label, Path(p)) for label, v in inputs.items() for p in _paths(v)]
    outs = [(label, Path(p)) for label, v in outputs.items() for p in _paths(v)]
    for label, v in outputs.items():
        for p in _paths(v):
            # Path() drops a trailing separator: 'x.json/' (a folder meant) was written as the file x.json
            if label not in FOLDER_OUTPUTS and str(p).endswith(("/", os.sep)) and str(p).strip("/" + os.sep):
                raise OutputError(
                    f"{label} {p}: ends in '{str(p)[-1]}', which names a folder; give a file name "
                    f"(e.g. {str(p).rstrip('/' + os.sep)})"
                )
    package = installed_package_dirs()
    for i, (label, out) in enumerate(outs):
        _check_name_length(label, out)  # first: a name too long makes every stat of it raise
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
            for file_label, file, folder_label, folder in (
                (label, out, other_label, other),
                (other_label, other, label, out),
            ):
                if (
                    folder_label in ("--out", "--report")
                    and file_label not in FOLDER_OUTPUTS
                    and _inside(file, folder)
                ):
                    raise OutputError(
                        f"{file_label} {file} is inside the {folder_label} folder {folder}, which is written as a "
                        "whole (one would overwrite or remove the other); give a path outside it"
                    )
        if out.name.lower() in PRESET_NAMES:
            # a bare preset name written as a file made every later '--muscle FAM1' in this folder
            # ambiguous ("both a preset and a file here")
            raise OutputError(
                f"{label} {out}: is the name of a preset muscle; give another name (e.g. {out}.json)"
            )
        if label not in FOLDER_OUTPUTS and out.is_dir():
            raise OutputError(
                f"{label} {out}: is a folder, not a file; give a file name (e.g. "
                f"{out / ('figure.png' if label in ('--figure', '--strip') else 'result.json')})"
            )
        writes_data = label not in (*FIGURE_OUTPUTS, *FOLDER_ONLY_OUTPUTS)  # a folder output: said below
        if writes_data and out.suffix.lower() in DATA_SUFFIXES and out.is_file():
            # a recording that is not this command's input (a slip of the tab key) was replaced
            # by JSON or MJCF without a word
            raise OutputError(
                f"{label} {out}: an existing {out.suffix} file (a recording?) would be replaced by this "
                "command's output; give the output a name of its own (.json, .xml)"
            )
        if label in formatted:
            check_json_name(label, out, formatted[label])
        if label not in FOLDER_OUTPUTS and label != "--mujoco-log":  # the log: check_log_target
            output_target(out, label)  # before the work: not a device, a pipe or a socket
        _check_not_in_a_report(label, out)
        if label in FIGURE_OUTPUTS:
            check_figure_path(label, out)
        _check_writable_place(label, out)
        for folder in package:
            if _inside(out, folder):
                raise OutputError(
                    f"{label} {out} is inside the installed package ({folder}); write somewhere else"
                )
    # last, for every output: the checks above say more about where an output goes (an input, the
    # package, another output) than its name's kind or the kind of file it would replace
    for label, out in outs:
        if label in formatted:
            check_kind_of_name(label, out, formatted[label])
            check_replaced_kind(label, out, formatted[label], (documents or {}).get(label))


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


def _check_name_length(label: str, out: Path) -> None:
    """Refuse a path with a name longer than its file system takes (255 bytes on most): found
    before the work, not when the first output is written after it."""
    limit = 255
    for parent in [out.parent, *out.parent.parents]:
        try:
            limit = os.pathconf(parent, "PC_NAME_MAX")
            break
        except (OSError, ValueError, AttributeError):  # not there (yet), or no such limit
            continue
    for part in out.parts:
        size = len(os.fsencode(part))
        if size > limit:
            raise OutputError(
                f"{label} {out}: the name '{part[:40]}...' is {size} bytes long; the file system takes "
                f"names of at most {limit} bytes"
            )


def _check_not_in_a_report(label: str, out: Path) -> None:
    """Refuse an output inside an existing efam report folder (one that holds the
    :data:`REPORT_MARKER`): the file made the folder the user's, and the next run of the command
    that wrote the report refused to replace it (``--json rep/x.json`` after ``diagnose --report
    rep``); over one of the report's files it edited the report. A report folder output may be
    such a folder itself (it is replaced whole); ``--models-dir`` writes files into it."""
    target = _link_target(out)
    for folder in target.parents if label != "--models-dir" else [target, *target.parents]:
        try:
            marked = (folder / REPORT_MARKER).is_file()
        except OSError:  # a folder we may not look into: the write itself will say so
            marked = False
        if marked:
            raise OutputError(
                f"{label} {out} is inside the efam report folder {folder}, which its command replaces "
                "as a whole (the file would be lost, or stop the report from being replaced); give a "
                "path outside it"
            )


def _paths(value) -> list:
    if value is None:
        return []
    if isinstance(value, (str, os.PathLike)):
        return [value]
    return [v for v in value if v is not None and isinstance(v, (str, os.PathLike))]


# ---------------------------------------------------------------------------- report folders
#: the marker's first line; the lines after it list what the report wrote: "<sha256>  <path>"
_MARKER_HEADER = "written by efam_mujoco; this folder is replaced as a whole; its files:"


def _digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _report_files(folder: Path) -> dict[str, Path]:
    """Every entry below ``folder`` but the marker, by its path relative to it ('/'-separated);
    folders end with '/'."""
    out = {}
    for entry in sorted(folder.rglob("*")):
        relative = entry.relative_to(folder).as_posix()
        if relative != REPORT_MARKER:
            out[relative + ("/" if entry.is_dir() and not entry.is_symlink() else "")] = entry
    return out


#: the marker's line naming the command that wrote the report (older markers have none)
_MARKER_COMMAND = "command: efam "


def _write_marker(folder: Path, command: str | None = None) -> None:
    """The marker, listing every file of the report with its sha256 (what may be replaced), and
    the command that wrote it (only that command replaces it)."""
    lines = [_MARKER_HEADER] + ([_MARKER_COMMAND + command] if command else [])
    for relative, entry in _report_files(folder).items():
        if not relative.endswith("/"):
            lines.append(f"{_digest(entry)}  {relative}")
    (folder / REPORT_MARKER).write_text("\n".join(lines) + "\n")


def _not_the_reports(folder: Path, command: str | None = None) -> str:
    """What in ``folder`` is not the report its marker lists, unchanged ('' when nothing): a file
    the user added or edited there is the user's, and the folder is then not replaced; nor is
    another command's report (``efam diagnose --report`` over ``efam demo``'s folder removed the
    demo's files without a word)."""
    text = (folder / REPORT_MARKER).read_text(errors="replace").splitlines()
    if not text or text[0] != _MARKER_HEADER:
        return f"its {REPORT_MARKER} lists no report files (hand-made, or from an older efam_mujoco)"
    wrote = next(
        (line[len(_MARKER_COMMAND) :] for line in text[1:] if line.startswith(_MARKER_COMMAND)), None
    )
    if command and wrote and wrote != command:
        return f"it is the report of 'efam {wrote}', not of 'efam {command}'"
    listed = dict(reversed(line.split("  ", 1)) for line in text[1:] if "  " in line)
    for relative, entry in _report_files(folder).items():
        if relative.endswith("/"):
            continue
        if relative not in listed:
            return f"{relative} is not a file the report wrote"
        if entry.is_symlink() or not entry.is_file() or _digest(entry) != listed[relative]:
            return f"{relative} was changed after the report wrote it"
    return ""


def check_replaceable_folder(
    path: str | os.PathLike, label: str = "output folder", command: str | None = None
) -> Path:
    """Refuse a folder that exists and is neither empty nor an untouched previous efam report
    (its marker lists every file in it, unchanged: it would be replaced as a whole) of the same
    ``command`` (``"demo"``, ``"diagnose"``...; any, when not given or when an older marker does
    not say), and a path that is a file. Returns the folder to write (a link's target)."""
    given = Path(path)
    path = _link_target(given)
    if given.is_symlink() and not path.exists():
        raise OutputError(f"{label} {given} is a link to {path}, which does not exist")
    if path.exists() and not path.is_dir():
        raise OutputError(f"{label} {given} is a file, not a folder")
    if path.is_dir() and _inside(Path.cwd(), path):
        raise OutputError(f"{label} {given} is the folder you are in (or holds it): name a folder inside it")
    if path.is_dir() and any(path.iterdir()):
        if not (path / REPORT_MARKER).is_file():
            why = f"is not an efam report folder (no {REPORT_MARKER})"
        else:
            why = _not_the_reports(path, command)
            why = f"is not only this command's efam report: {why}" if why else ""
        if why:
            raise OutputError(
                f"{label} {given} exists, is not empty and {why}; it would be replaced as a whole, so name "
                "a new or empty folder (or move your files out)"
            )
    return path


@contextlib.contextmanager
def replace_folder(path: str | os.PathLike, label: str = "output folder", command: str | None = None):
    """Build a report folder in a temporary folder beside ``path``; on success swap it in as a
    whole (the previous report is removed only after the new one is in place); on any failure
    remove the temporary and leave ``path`` as it was. Yields the temporary folder to fill.

    A folder with other contents than an untouched previous report is refused (see
    :func:`check_replaceable_folder`); a link to a folder is followed (the link is kept).
    """
    path = check_replaceable_folder(path, label, command)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(
            tempfile.mkdtemp(prefix=_temporary_prefix(path.name), suffix=".efam-tmp", dir=path.parent)
        )
    except OSError as err:  # the user's folder, not the temporary's name nobody asked for
        raise OutputError(f"{label} {path}: cannot write here ({err.strerror or err})") from None
    try:
        yield staging
        _write_marker(staging, command)
        os.chmod(staging, 0o777 & ~_umask())
        old = None
        if path.exists():
            old = Path(
                tempfile.mkdtemp(prefix=_temporary_prefix(path.name), suffix=".efam-old", dir=path.parent)
            )
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
_log_lead: list[str] = [""]  # a newline before the first warning, when the log's last line has none
_collectors: list[list[str]] = []


def route_mujoco_log(path: str | os.PathLike | None = None) -> None:
    """Send MuJoCo's warnings to ``path`` (appended, one line each) or, without a path, to
    standard error; MuJoCo then never writes ``MUJOCO_LOG.TXT`` into the working folder."""
    import mujoco

    if path is not None:
        check_log_target(path)
        try:  # found now, not as warnings silently lost later: no permission
            # a missing folder is made, as for every other output (check_outputs has checked that
            # its nearest existing ancestor is a folder we may write into)
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            with open(path, "a", encoding="utf-8"):
                pass
        except OSError as err:
            raise OutputError(f"--mujoco-log {path}: cannot append to it ({err.strerror})") from None
    _log_target[0] = None if path is None else Path(path)
    # a log whose last line has no newline keeps it: the first warning starts a line of its own
    # (every warning then ends with one)
    _log_lead[0] = "\n" if path is not None and _ends_without_newline(Path(path)) else ""
    mujoco.set_mju_user_warning(_mujoco_warning)


#: suffixes of files the log is never appended to: efam's own data, models and figures (a
#: warning appended to a muscle file left it unreadable JSON)
NOT_A_LOG_SUFFIXES = ("csv", "tsv", "json", "xml", "mjb", "npz", "npy", "yaml", "yml", "toml", "py", "so")


def check_log_target(path: str | os.PathLike) -> None:
    """Refuse a ``--mujoco-log`` target the log cannot be appended to safely. It is appended to,
    never renamed over: a character device (``/dev/null``, to discard the warnings) is fine, a
    pipe or a socket is refused (opening one to append waits for a reader, and the command would
    hang). An existing file that holds data rather than a log is refused: one with a data, model
    or figure suffix, whose text opens as JSON or XML does (``{``, ``[``, ``<``), or whose first
    line is a table's header, whatever its name; appending a warning to it would corrupt it. A
    new file, an empty one, or a plain text log is fine."""
    target = _link_target(path)
    if target.exists() and not target.is_file() and not target.is_dir() and not target.is_char_device():
        raise OutputError(
            f"--mujoco-log {path} is a pipe or a socket: opening it for the log would wait for a reader; "
            "give a file name (or /dev/null to discard the warnings)"
        )
    if not target.is_file() or target.stat().st_size == 0:
        return
    suffix = target.suffix.lower().lstrip(".")
    try:
        with open(target, "rb") as handle:
            head = handle.read(4096).lstrip(b"\xef\xbb\xbf \t\r\n")
    except OSError:
        return  # the append check that follows names what is wrong with it
    first = head.split(b"\n", 1)[0].strip()
    # a table's header line (a recording saved as .txt): fields split by commas or tabs and no
    # spaces, which MuJoCo's warnings always have
    table = len(re.split(rb"[,\t;]", first)) >= 2 and b" " not in first
    if suffix in NOT_A_LOG_SUFFIXES or suffix in figure_formats() or head[:1] in (b"{", b"[", b"<") or table:
        raise OutputError(
            f"--mujoco-log {path}: the file exists and holds data, not a log (appending MuJoCo's "
            "warnings would corrupt it); name a new file or a .log/.txt log"
        )


def _mujoco_warning(message: str) -> None:
    text = " ".join(str(message).split())
    for collector in _collectors:
        collector.append(text)
    target = _log_target[0]
    if target is None:
        print(f"MuJoCo warning: {text}", file=sys.stderr)
        return
    try:
        with open(target, "a", encoding="utf-8") as handle:
            handle.write(_log_lead[0] + text + "\n")
        _log_lead[0] = ""
    except OSError as err:  # the log went away or filled up: the warning still reaches the user
        print(
            f"MuJoCo warning: {text} (not written to --mujoco-log {target}: {err.strerror})", file=sys.stderr
        )


def _ends_without_newline(path: Path) -> bool:
    """Whether the file at ``path`` exists, is not empty and its last byte is not a newline."""
    try:
        with open(path, "rb") as handle:
            if handle.seek(0, os.SEEK_END) == 0:
                return False
            handle.seek(-1, os.SEEK_END)
            return handle.read(1) != b"\n"
    except OSError:
        return False


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
    files (figures) rendered into a staging folder. :meth:`prepare` writes each into a unique
    temporary beside its target, :meth:`commit` then renames them into place. A place that cannot
    be written fails in :meth:`prepare`, before any output is replaced: a bad ``--figures`` path
    cannot fail after the muscle file was written, nor an unwritable ``--json`` after the
    ``--report`` folder was swapped in (``efam diagnose`` prepares before it swaps)."""

    def __init__(self):
        self.texts: dict[Path, str] = {}
        self._staging: Path | None = None
        self.staged: dict[Path, Path] = {}
        self._ready: list[tuple[Path, Path]] | None = None  # (temporary, target), once prepared

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

    def prepare(self) -> None:
        """Write every output into a temporary beside its target (folders made, the user's
        permissions given); nothing the user has is replaced yet. Any failure removes what was
        prepared and raises :class:`OutputError` naming the output."""
        if self._ready is not None:
            return
        ready: list[tuple[Path, Path]] = []
        try:
            contents = [(path, lambda text=text: text.encode("utf-8")) for path, text in self.texts.items()]
            contents += [(path, staged.read_bytes) for path, staged in self.staged.items()]
            for path, data in contents:
                path = output_target(path)
                path.parent.mkdir(parents=True, exist_ok=True)
                if path.is_dir():
                    raise OutputError(f"{path}: is a folder, not a file")
                try:
                    ready.append((_write_beside(path, data()), path))
                except OSError as err:  # a full disk: the user's path, not the temporary's name
                    raise OutputError(f"cannot write {path} ({err.strerror or err})") from None
        except BaseException:
            _remove_temporaries(ready)
            raise
        self._ready = ready

    def commit(self) -> list[Path]:
        """Write every output: :meth:`prepare` (if not done), then rename each temporary over its
        target. Returns the targets written."""
        try:
            self.prepare()
            written = []
            for tmp, path in self._ready:
                os.replace(tmp, path)
                written.append(path)
            return written
        finally:
            self.discard()

    def discard(self) -> None:
        """Remove the staging folder and any temporary not renamed (what was not committed is dropped)."""
        if self._ready is not None:
            _remove_temporaries(self._ready)
            self._ready = None
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None
