"""The ``efam`` command line. Each feature module adds its own subcommand."""

from __future__ import annotations

import argparse
import importlib
import sys

# Modules exposing ``register_cli(subparsers)``; each adds one subcommand.
COMMAND_MODULES = (
    "efam_mujoco.report",
    "efam_mujoco.viewer",
    "efam_mujoco.arm",
    "efam_mujoco.calibrate",
    "efam_mujoco.diagnose",
    "efam_mujoco.armdiag",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="efam",
        description="Extensile fluidic artificial muscles in MuJoCo (Garbulinski et al. 2021 model).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register_cli(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except (ValueError, OSError) as err:  # bad input: one clear line, no traceback
        print(f"efam {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
