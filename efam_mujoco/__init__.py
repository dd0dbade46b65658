"""efam_mujoco: extensile fluidic artificial muscles as a native MuJoCo actuator plugin.

The physics (``muscle``, ``stress``) is plain numpy; ``import efam_mujoco`` also loads the
compiled actuator plugin into MuJoCo so that models using ``efam.muscle`` compile.
"""

from .muscle import NEUTRAL_BRAID_ANGLE_DEG, Geometry, Muscle, MuscleError
from .musclefile import MuscleFileError, load_muscle, save_muscle
from .plugin import _autoload  # noqa: F401  (registers the efam.muscle plugin with MuJoCo)
from .stress import LAW_NAMES, StressLaw, StressLawError

__all__ = [
    "Geometry",
    "Muscle",
    "MuscleError",
    "NEUTRAL_BRAID_ANGLE_DEG",
    "MuscleFileError",
    "load_muscle",
    "save_muscle",
    "LAW_NAMES",
    "StressLaw",
    "StressLawError",
]
__version__ = "0.1.0"
