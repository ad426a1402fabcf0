"""Simulation backends behind one small protocol, registered by name."""

from ._base import BACKENDS, Backend, PointRun, make_backend, register, steps_per_period
from .emulated import EmulatedBackend

__all__ = [
    "BACKENDS",
    "Backend",
    "EmulatedBackend",
    "PointRun",
    "make_backend",
    "register",
    "steps_per_period",
]
