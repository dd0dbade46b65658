"""The ``efam`` command line. Each feature module adds its own subcommand.

What every subcommand gets from here, without code of its own:

* exact flag matching: ``allow_abbrev=False`` on the parser and on every subparser (the
  ``subparsers`` object handed to ``register_cli`` adds it), so ``--pressures 75`` is an error,
  never a silent ``--pressures-kPa 75``;
* a value flag given twice is an error naming both values (``--stress a --stress b`` kept the
  last without a word);
* every flag's default shown in its help;
* ``efam --version``;
* the output policy (:mod:`efam_mujoco.files`) checked before anything runs: an output path that
  is an input (or inside the installed package) is refused, naming both flags;
* MuJoCo's log routed to ``--mujoco-log FILE`` or standard error, never ``MUJOCO_LOG.TXT``;
* one error exit: bad input prints ``efam COMMAND: error: ...`` and exits 2, with no traceback;
  a Python warning prints one line, ``efam COMMAND: warning: ...``;
  a closed pipe (``efam muscle FAM1 | head``) ends quietly.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import math
import os
import re
import signal
import sys
import warnings
from pathlib import Path

from .units import visible

# Modules exposing ``register_cli(subparsers)``; each adds one subcommand.
COMMAND_MODULES = (
    "efam_mujoco.report",
    "efam_mujoco.viewer",
    "efam_mujoco.arm",
    "efam_mujoco.calibrate",
    "efam_mujoco.diagnose",
    "efam_mujoco.size",
    "efam_mujoco.plugin.install",
    "efam_mujoco.suite.cli",
    "efam_mujoco.armdiag",
)

#: Exit status of a bad input (argparse uses 2 too) and of an interrupted run.
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130


class _HelpFormatter(argparse.HelpFormatter):
    """Adds ``(default: X)`` to a flag's help when it has a default and does not say it."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if (
            default not in (None, False, argparse.SUPPRESS)
            and "default" not in text.lower()
            and action.option_strings
            and action.nargs != 0
        ):
            shown = " ".join(map(str, default)) if isinstance(default, (list, tuple)) else default
            text = f"{text} (default: {shown})" if text else f"(default: {shown})"
        return text


class _OneLineParser(argparse.ArgumentParser):
    """argparse's parser with the house's one-line error: the problem and where the help is,
    not the usage block first (``efam muscle: error: argument --pressures-kPa: ...``)."""

    def error(self, message):
        """Print ``<prog>: error: <message> (<prog> --help)`` on standard error and exit 2."""
        self.exit(2, f"{self.prog}: error: {visible(message)} (see {self.prog} --help)\n")


def _typed(value) -> str:
    """A parsed flag value as a user would have typed it (75, not 75.0)."""
    return f"{value:g}" if isinstance(value, float) else str(value)


class _StoreOnce(argparse._StoreAction):
    """argparse's ``store`` action, refusing a flag given twice in one command line: argparse
    keeps the last value, so ``--pressures-kPa 75 150 --pressures-kPa 300`` ran 300 kPa alone
    and the user's first list was dropped without a word."""

    def __call__(self, parser, namespace, values, option_string=None):
        """Store ``values``; a second occurrence of the flag in the same parse is a usage error."""
        if self.option_strings:
            # the namespace of this parse is the identity that matters (a parser can parse twice)
            last = getattr(self, "_last", None)
            if last is not None and last[0] is namespace:
                shown = lambda v: " ".join(map(_typed, v)) if isinstance(v, list) else _typed(v)  # noqa: E731
                parser.error(
                    f"argument {option_string}: given twice ('{shown(last[1])}', then "
                    f"'{shown(values)}'); give it once"
                )
            self._last = (namespace, values)
        super().__call__(parser, namespace, values, option_string)


class _ExactSubparsers:
    """Wraps argparse's subparsers action: every subparser gets ``allow_abbrev=False`` and the
    help formatter above, so no feature module has to remember them."""

    def __init__(self, action):
        self._action = action

    def add_parser(self, name, **kwargs):
        kwargs.setdefault("allow_abbrev", False)
        kwargs.setdefault("formatter_class", _HelpFormatter)
        kwargs["allow_abbrev"] = False
        parser = self._action.add_parser(name, **kwargs)
        # every type=float / type=int flag reads plain ASCII decimals, as the recordings do
        parser.register("type", float, plain_float)
        parser.register("type", int, plain_int)
        # every type=Path argument keeps '' as typed: pathlib reads it as '.', and _file_args'
        # empty-name check would see the current folder instead of the mistake
        parser.register("type", Path, path_or_empty)
        # every value flag is given at most once (``_StoreOnce``); None is argparse's default action
        parser.register("action", None, _StoreOnce)
        parser.register("action", "store", _StoreOnce)
        return parser

    def __getattr__(self, name):
        return getattr(self._action, name)


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("efam_mujoco")
    except Exception:  # not installed (a bare checkout on sys.path)
        return "unknown"


def build_parser() -> argparse.ArgumentParser:
    """The ``efam`` parser with every command of :data:`COMMAND_MODULES` (exact flags)."""
    parser = _OneLineParser(
        prog="efam",
        description="Extensile fluidic artificial muscles in MuJoCo (Garbulinski et al. 2021 model).",
        allow_abbrev=False,
        formatter_class=_HelpFormatter,
    )
    parser.register("action", None, _StoreOnce)
    parser.register("action", "store", _StoreOnce)
    parser.add_argument("--version", action="version", version=f"efam_mujoco {_version()}")
    parser.add_argument(
        "--mujoco-log",
        metavar="FILE",
        help="append MuJoCo's warnings to FILE (default: print them on standard error; "
        "MUJOCO_LOG.TXT is never written)",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=_OneLineParser)
    exact = _ExactSubparsers(sub)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register_cli(exact)
    return parser


def _file_args(args) -> tuple[dict, dict]:
    """The command's input and output paths, keyed by the flag a user typed."""
    names_in = getattr(args, "file_inputs", None) or ()
    names_out = getattr(args, "file_outputs", None) or ()
    if callable(names_out):  # outputs that depend on the other flags
        names_out = names_out(args)

    # a command whose file argument is positional (``file_positionals``) names it in capitals, as
    # its usage line does (``efam muscle ""`` said '--muscle', a flag that command does not have)
    positionals = set(getattr(args, "file_positionals", None) or ())

    def flag(name):
        if name in positionals:
            return name.upper()
        return "FILE" if name in ("files", "file") else "--" + name.replace("_", "-")

    def existing(value):  # a preset name (FAM1) is not a file
        values = value if isinstance(value, (list, tuple)) else [value]
        return [v for v in values if v is not None and Path(str(v)).exists()]

    for n in (*names_in, *names_out):  # '' is '.' to pathlib: "is a folder" hid the real mistake
        value = getattr(args, n, None)
        values = value if isinstance(value, (list, tuple)) else [value]
        if any(isinstance(v, (str, os.PathLike)) and not str(v).strip() for v in values):
            raise ValueError(f"{flag(n)}: an empty file name")
    inputs = {flag(n): existing(getattr(args, n, None)) for n in names_in}
    # files an input names inside itself (an arm spec's muscles given by path) are inputs too
    referenced = getattr(args, "file_inputs_referenced", None)
    if callable(referenced):
        inputs.update({label: existing(paths) for label, paths in referenced(args).items()})
    outputs = {flag(n): getattr(args, n, None) for n in names_out}
    if getattr(args, "mujoco_log", None) is not None:
        if not args.mujoco_log.strip():
            raise ValueError(f"--mujoco-log: '{args.mujoco_log}' is not a file name")
        if Path(args.mujoco_log).is_dir():
            raise ValueError(
                f"--mujoco-log {args.mujoco_log}: is a folder; give a log file's name "
                f"(e.g. {Path(args.mujoco_log) / 'mujoco.log'})"
            )
        outputs["--mujoco-log"] = args.mujoco_log
    return inputs, outputs


def _document_flags(args) -> dict[str, str]:
    """The output flags of this command that write an efam document, flag -> its format
    (``set_defaults(document_outputs={"out": "efam_mujoco.muscle/1"})``: calibrate's muscle file)."""
    declared = getattr(args, "document_outputs", None) or {}
    return {"--" + name.replace("_", "-"): kind for name, kind in declared.items()}


def _formatted_flags(args) -> dict[str, str]:
    """The output flags of this command whose content has a format, flag -> format: every
    ``--json`` and ``--xml``, and the efam documents a command writes (JSON)."""
    from .files import FORMATTED_OUTPUTS

    return {**FORMATTED_OUTPUTS, **{flag: "JSON" for flag in _document_flags(args)}}


def check_argument_bounds(args) -> None:
    """Refuse a value outside the bounds a command declares (``parser.set_defaults(
    argument_bounds={dest: (low, high, unit)})``; a flag the command does not have is skipped),
    naming the flag: a size that can exhaust the machine, or a control MuJoCo would clamp
    silently."""
    import math

    for dest, (low, high, unit) in (getattr(args, "argument_bounds", None) or {}).items():
        value = getattr(args, dest, None)
        if value is None:
            continue
        for v in value if isinstance(value, (list, tuple)) else [value]:
            if not (isinstance(v, (int, float)) and math.isfinite(v) and low <= v <= high):
                flag = "--" + dest.replace("_", "-")
                u = f" {unit}" if unit else ""
                raise ValueError(
                    f"{flag}: {v:g}{u} is outside {low:g} .. {high:g}{u}"
                    + (" (the actuators' control range: MuJoCo would clamp it)" if unit == "kPa" else "")
                )


_DECIMAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?", re.ASCII)
_WHOLE = re.compile(r"[+-]?\d+", re.ASCII)


def plain_float(text: str) -> float:
    """An argparse type: a finite number written as a plain ASCII decimal (``0.5``, ``-2e3``).
    Python's ``float`` also reads ``1_000``, other scripts' digits (``７５``), ``nan`` and
    ``inf``, none of which a user means as a pressure or a length. ``-0`` reads as 0."""
    if not _DECIMAL.fullmatch(text.strip()):
        raise argparse.ArgumentTypeError(f"takes a plain decimal number (like 0.5 or 2e3), got {text!r}")
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"takes a finite number, got {text!r}")
    return value + 0.0  # '-0' is 0: a negative zero printed as '-0.0' in every table and JSON


def plain_int(text: str) -> int:
    """An argparse type: a whole number written in plain ASCII digits."""
    if not _WHOLE.fullmatch(text.strip()):
        raise argparse.ArgumentTypeError(f"takes a whole number in plain digits, got {text!r}")
    return int(text)


def path_or_empty(text: str) -> Path | str:
    """An argparse type: ``Path(text)``, except ``''``, returned as is. ``Path('')`` is
    ``Path('.')``, the current folder, so a command would report ``'.' is a folder`` instead of
    the empty argument; kept as ``''``, :func:`_file_args` names it (``--model: an empty file
    name``) before the command runs."""
    return Path(text) if text else text


def bounded_int(low: int, high: int, what: str = ""):
    """An argparse type: a whole number in ``low .. high``; otherwise argparse's usage error,
    which names the flag (``efam suite: error: argument --seed: must be ...``), before anything
    runs, instead of a library's message (numpy's for a negative seed) or hours of work for a
    huge count."""

    def parse(text: str) -> int:
        value = plain_int(text)
        if not low <= value <= high:
            about = f" ({what})" if what else ""
            raise argparse.ArgumentTypeError(f"must be a whole number in {low} .. {high}{about}, got {value}")
        return value

    return parse


def _quiet_broken_pipe() -> None:
    """After a closed pipe: send what is left for stdout to /dev/null so that the flush at exit
    does not raise again (the recipe in Python's signal documentation)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    """Run one ``efam`` command; returns the exit status (0 ok, 2 bad input)."""
    # SIGTERM unwinds from the start: while the commands' modules import (seconds on a busy
    # machine) as well as while one runs
    previous_term = _terminate_as_interrupt()
    try:
        return _main(argv)
    except KeyboardInterrupt:
        print("efam: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if previous_term is not None:
            signal.signal(signal.SIGTERM, previous_term)


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:  # said by the command's own parser ('efam diagnose-arm: error: ...'), not 'efam: error'
            commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
            commands.choices.get(getattr(args, "command", None), parser).error(
                f"unrecognized arguments: {' '.join(extra)}"
            )
    except SystemExit as done:  # --help, --version, or a usage error argparse has printed
        return int(done.code or 0) if not isinstance(done.code, str) else EXIT_BAD_INPUT
    from .files import check_outputs, route_mujoco_log

    command = f"efam {args.command}"
    try:
        inputs, outputs = _file_args(args)
        check_outputs(outputs, inputs, formatted=_formatted_flags(args), documents=_document_flags(args))
        check_argument_bounds(args)
        route_mujoco_log(args.mujoco_log)
        with warnings.catch_warnings():  # Python's filters; each shown as one line
            warnings.showwarning = functools.partial(_show_warning, command=command)
            if _small_kilopascal_flags(args):
                # said once in the flag's own unit: the Pa-level check of every function the value
                # feeds would repeat it, naming internal functions and a unit the user did not give
                from .units import PressureUnitWarning

                warnings.simplefilter("ignore", PressureUnitWarning)
            status = int(args.run(args) or 0)
        sys.stdout.flush()
        return status
    except BrokenPipeError:
        _quiet_broken_pipe()
        return 0
    except KeyboardInterrupt:
        print(f"{command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, OSError, ArithmeticError, RuntimeError) as err:  # bad input: one clear line
        print(f"{command}: error: {_message(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Exception as err:  # a bug: still one line for the user; the traceback on request
        if os.environ.get("EFAM_DEBUG"):
            raise
        print(
            f"{command}: internal error: {type(err).__name__}: {err} (set EFAM_DEBUG=1 for the traceback; "
            "please report it)",
            file=sys.stderr,
        )
        return 3


def _terminate_as_interrupt():
    """SIGTERM (``kill``, a job scheduler's time limit) unwinds like Ctrl-C, so every temporary
    file and folder of the output policy is removed on the way out. Returns the previous
    handler (None when signals cannot be set here, e.g. outside the main thread)."""

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    try:
        return signal.signal(signal.SIGTERM, interrupt)
    except (ValueError, OSError):
        return None


def _message(err: BaseException) -> str:
    """The one line an error or warning prints: its lines joined by one space, and any control
    character left (a terminal escape sequence in a file name) escaped, never sent as is."""
    if isinstance(err, OSError) and err.filename and err.strerror:
        text = f"{err.filename}: {err.strerror}"
    else:
        text = " ".join(line.strip() for line in str(err).splitlines() if line.strip())
    return visible(text) or type(err).__name__


def _small_kilopascal_flags(args) -> bool:
    """Warn (once per flag, in kPa) of a pressure flag below 1 kPa (``--pressures-kPa 0.3``: kPa
    meant as MPa or bar?); True when one was. The kPa flags: every ``*_kPa`` destination and those a
    command lists in ``kpa_flags`` (``efam size --pressure``)."""
    said = False
    names = [n for n in vars(args) if n.lower().endswith("_kpa")] + list(getattr(args, "kpa_flags", ()))
    for name in names:
        value = getattr(args, name, None)
        values = [
            v for v in (value if isinstance(value, (list, tuple)) else [value]) if isinstance(v, (int, float))
        ]
        values = [v for v in values if math.isfinite(v) and v > 0]
        if values and max(values) < 1.0:
            flag = "--" + name.replace("_", "-")
            warnings.warn(
                f"{flag} {max(values):g} is below 1 kPa: pressures here are kPa", UserWarning, stacklevel=2
            )
            said = True
    return said


def _show_warning(message, category, filename, lineno, file=None, line=None, *, command="efam") -> None:
    # like the error line: the command, no source file:line (a user cannot act on it), one line
    print(f"{command}: warning: {_message(message)}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
