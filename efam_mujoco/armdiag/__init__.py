"""Sim vs real at the arm: why a real arm's tip moves differently from the MuJoCo arm's.

Give it the arm model (the builder's spec file or an MJCF) and a recording of the commanded
pressures and the tip (:mod:`.recording`); :func:`diagnose_arm` replays the commands in MuJoCo,
re-fits what the model already has, locates the mismatch and names the missing physics from a
library (:mod:`.effects`) with held-out probabilities; :mod:`.report` writes the report, the JSON
and an MJCF with the identified terms switched on. ``efam diagnose-arm`` on the command line.
"""

from __future__ import annotations

from .diagnosis import ArmDiagnosis, diagnose_arm
from .effects import EFFECT_NAMES, LIBRARY
from .recording import ArmRecording, ArmRecordingError, ArmRecordingWarning, read_csv, write_csv
from .replay import Knobs, Replayer
from .specfile import ArmModelError, load_arm_model, load_spec, save_spec

__all__ = [
    "ArmDiagnosis", "diagnose_arm", "EFFECT_NAMES", "LIBRARY", "ArmRecording", "ArmRecordingError",
    "ArmRecordingWarning", "read_csv", "write_csv", "Knobs", "Replayer", "ArmModelError", "load_arm_model",
    "load_spec", "save_spec", "register_cli",
]  # fmt: skip


def register_cli(subparsers) -> None:
    """``efam diagnose-arm`` (for efam_mujoco.cli.COMMAND_MODULES)."""
    from .report import register_cli as register

    register(subparsers)
