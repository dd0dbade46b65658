"""Imported by ``efam_mujoco/__init__.py``: registers the efam.muscle plugin with MuJoCo."""

from . import load

LIBRARY_PATH = load()
