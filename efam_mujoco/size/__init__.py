"""Actuator sizing (``efam size``): design an EFAM, or a bundle of them, for a stroke, a force and a
pressure budget from catalogue parts (docs/sizing.md).

>>> from efam_mujoco.size import Request, size
>>> result = size(Request(stroke=0.5, force_N=40.0, pressure_Pa=400e3, length_m=0.15))  # doctest: +SKIP
>>> result.best.tubing.name, result.best.geometry.sleeve_length_ref_m                 # doctest: +SKIP
"""

from .catalogue import Catalogue, CatalogueError, load_catalogue
from .cli import register_cli
from .constraints import Check, Performance
from .design import Material
from .relax import ClosestPoint, Relaxation
from .request import Request, RequestError
from .search import Design, SizingResult, size

__all__ = [
    "Catalogue",
    "CatalogueError",
    "Check",
    "ClosestPoint",
    "Design",
    "Material",
    "Performance",
    "Relaxation",
    "Request",
    "RequestError",
    "SizingResult",
    "load_catalogue",
    "register_cli",
    "size",
]
