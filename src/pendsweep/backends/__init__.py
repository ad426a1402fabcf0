"""Simulation backends behind one small protocol, registered by name."""

from ._base import (
    BACKENDS,
    Backend,
    BackendBase,
    PointRun,
    make_backend,
    register,
    steps_per_period,
)
from .emulated import EmulatedBackend
from .substructured import SubstructuredBackend

__all__ = [
    "BACKENDS",
    "Backend",
    "BackendBase",
    "EmulatedBackend",
    "PointRun",
    "SubstructuredBackend",
    "make_backend",
    "register",
    "steps_per_period",
]
