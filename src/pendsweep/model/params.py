"""Reference parameter sets and their validation.

Every default number in pendsweep lives here, so that tests, figures, the CLI
and the docs share one source. Values are SI throughout.

The model is Eqs. (1)-(2) of Gonzalez-Buelga, Wagg & Neild (2007), with the
pendulum damping ``f_d = b1 sgn(w) + b2 w + b3 w^2 sgn(w)`` and an optional
cubic spring term ``k3 y^3`` (zero by default, used by model extensions).
The oscillator mass and damping are split as ``M = M1 + M2`` and
``C = C1 + C2`` for the substructured test, where ``M2`` and ``C2`` belong to
the physical mounting platform (Table IV).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import ParameterError

if TYPE_CHECKING:
    import numpy as np

__all__ = [
    "ENCODER_RESOLUTION",
    "KERNEL_FIELDS",
    "ModelParams",
    "kernel_vector",
    "ParamSpec",
    "PARAM_SPECS",
    "TABLE_IV",
    "FIG8",
    "FIG9_PO",
    "FIG9_CO",
    "FIG11A",
    "FIG11B",
    "LoopParams",
    "FIG5_LOOP",
    "FIG7_LOOP",
    "TABLE_II_P",
    "TABLE_II_LOOPS",
    "TABLE_II_MODELS",
    "TABLE_II_FREQ_THEORY_PAPER",
    "TABLE_II_FREQ_EXPERIMENT_PAPER",
    "FIG6_OMEGA_N",
    "FIG6_ZETA",
    "ParameterError",
    "check_value",
]

#: Encoder resolution [rad/pulse], Table III. "At rest" means |theta| below this.
ENCODER_RESOLUTION = 0.0013


@dataclass(frozen=True)
class ParamSpec:
    """Unit, accepted range and meaning of one model parameter."""

    unit: str
    lower: float = -math.inf
    lower_inclusive: bool = True
    upper: float = math.inf
    doc: str = ""

    def describe_range(self) -> str:
        lo = "[" if self.lower_inclusive and self.lower != -math.inf else "("
        lo_v = "-inf" if self.lower == -math.inf else f"{self.lower:g}"
        hi_v = "inf" if self.upper == math.inf else f"{self.upper:g}"
        return f"{lo}{lo_v}, {hi_v})"

    def accepts(self, value: float) -> bool:
        if not math.isfinite(value):
            return False
        if self.lower_inclusive:
            ok_lo = value >= self.lower
        else:
            ok_lo = value > self.lower
        return ok_lo and value < self.upper


_POS = dict(lower=0.0, lower_inclusive=False)
_NONNEG = dict(lower=0.0, lower_inclusive=True)

#: Units, ranges and meanings of every parameter a sweep may step.
PARAM_SPECS: dict[str, ParamSpec] = {
    # Lengths and masses far outside any rig (1e-300 m) overflow the formulas (l^2 = 0): refused.
    "m": ParamSpec("kg", lower=1e-9, upper=1e6, doc="pendulum mass"),
    "l": ParamSpec("m", lower=1e-6, upper=1e3, doc="pendulum length"),
    "b1": ParamSpec("kg m^2/s^2", **_NONNEG, doc="pendulum Coulomb friction"),
    "b2": ParamSpec("kg m^2/s", **_NONNEG, doc="pendulum viscous damping"),
    "b3": ParamSpec("kg m^2", **_NONNEG, doc="pendulum quadratic (air) drag"),
    "g": ParamSpec("m/s^2", **_POS, doc="gravitational acceleration"),
    "M": ParamSpec("kg", **_POS, doc="oscillator mass, M = M1 + M2"),
    "C": ParamSpec("kg/s", **_NONNEG, doc="oscillator damping, C = C1 + C2"),
    "K": ParamSpec("N/m", **_POS, doc="oscillator stiffness"),
    "k3": ParamSpec("N/m^3", doc="cubic spring coefficient (restoring force K y + k3 y^3)"),
    "M2": ParamSpec("kg", **_NONNEG, doc="platform mass (physical part of M)"),
    "C2": ParamSpec("kg/s", **_NONNEG, doc="platform damping (physical part of C)"),
    "alpha": ParamSpec("N", **_NONNEG, doc="forcing amplitude, F_e = alpha sin(2 pi fe t)"),
    "fe": ParamSpec("Hz", **_POS, doc="forcing frequency"),
    # Derived on assignment: setting M1 sets M = M1 + M2, setting C1 sets C = C1 + C2.
    "M1": ParamSpec("kg", **_POS, doc="numerical-model mass, M1 = M - M2"),
    "C1": ParamSpec("kg/s", **_NONNEG, doc="numerical-model damping, C1 = C - C2"),
}


def check_value(name: str, value: float) -> float:
    """Return ``value`` as float, or raise :class:`ParameterError` naming the range."""
    if name not in PARAM_SPECS:
        raise ParameterError(f"unknown parameter {name!r}; known parameters: {', '.join(PARAM_SPECS)}")
    spec = PARAM_SPECS[name]
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} = {value!r} is not a number") from None
    if not spec.accepts(v):
        raise ParameterError(
            f"{name} = {v!r} {spec.unit} is outside the accepted range {spec.describe_range()} ({spec.doc})"
        )
    return v


#: Field metadata marking the physical parameters that form the kernels' parameter vector.
_KERNEL = {"kernel": True}


@dataclass(frozen=True)
class ModelParams:
    """Physical parameters of the pendulum-oscillator system and its forcing.

    Defaults are Table IV (pendulum, platform) and the oscillator of Figs. 9-11:
    ``M = 10.9 kg``, ``C = 20 kg/s``, ``K = 1910 N/m``, forced at
    ``alpha = 17 N``, ``fe = 2.5 Hz``.
    """

    m: float = field(default=0.27, metadata=_KERNEL)
    l: float = field(default=0.1955, metadata=_KERNEL)
    b1: float = field(default=3.01411e-4, metadata=_KERNEL)
    b2: float = field(default=4.5067e-5, metadata=_KERNEL)
    b3: float = field(default=9.17e-7, metadata=_KERNEL)
    g: float = field(default=9.81, metadata=_KERNEL)
    M: float = field(default=10.9, metadata=_KERNEL)
    C: float = field(default=20.0, metadata=_KERNEL)
    K: float = field(default=1910.0, metadata=_KERNEL)
    k3: float = field(default=0.0, metadata=_KERNEL)
    M2: float = 0.9
    C2: float = 10.0
    alpha: float = 17.0
    fe: float = 2.5

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            check_value(f.name, getattr(self, f.name))

    # -- derived quantities -------------------------------------------------
    @property
    def M1(self) -> float:
        """Numerical-model mass [kg]."""
        return self.M - self.M2

    @property
    def C1(self) -> float:
        """Numerical-model damping [kg/s]."""
        return self.C - self.C2

    @property
    def omega_p(self) -> float:
        """Pendulum natural frequency sqrt(g/l) [rad/s]."""
        return math.sqrt(self.g / self.l)

    @property
    def omega_nm(self) -> float:
        """Oscillator natural frequency sqrt(K/(M+m)) with theta = 0 [rad/s]."""
        return math.sqrt(self.K / (self.M + self.m))

    @property
    def omega_e(self) -> float:
        """Forcing angular frequency 2 pi fe [rad/s]."""
        return 2.0 * math.pi * self.fe

    @property
    def omega_hat(self) -> float:
        """Frequency ratio omega_e / (2 omega_p), the abscissa of Fig. 10."""
        return self.omega_e / (2.0 * self.omega_p)

    # -- construction -------------------------------------------------------
    def replace(self, **changes: float) -> ModelParams:
        """Return a copy with ``changes`` applied; ``M1``/``C1`` set ``M``/``C``.

        Raises :class:`ParameterError` for unknown names or values out of range.
        """
        direct: dict[str, float] = {}
        for name, value in changes.items():
            v = check_value(name, value)
            if name == "M1":
                direct["M"] = check_value("M", v + check_value("M2", changes.get("M2", self.M2)))
            elif name == "C1":
                direct["C"] = check_value("C", v + check_value("C2", changes.get("C2", self.C2)))
            else:
                direct[name] = v
        # Every field of self is valid and every change was just checked: copy without __post_init__'s
        # check of all 14 fields again (a dense sweep makes thousands of parameter sets).
        copy = object.__new__(type(self))
        copy.__dict__.update(self.__dict__, **direct)
        return copy

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any]) -> ModelParams:
        """Defaults updated by ``mapping`` (unknown keys raise ParameterError)."""
        return cls().replace(**dict(mapping))

    def to_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)

    def kernel_array(self) -> np.ndarray:
        """Contiguous float64 vector of the :data:`KERNEL_FIELDS` for the kernels."""
        return kernel_vector(self.__dict__)  # the fields themselves: asdict's deep copy costs more than the sweep


#: The kernels' parameter vector, in order: the fields of :class:`ModelParams`
#: marked as kernel parameters (``pendsweep.kernels._layout`` indexes it by name).
KERNEL_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(ModelParams) if f.metadata.get("kernel"))


def kernel_vector(values: Mapping[str, float]) -> np.ndarray:
    """Contiguous float64 kernel parameter vector from a mapping holding every :data:`KERNEL_FIELDS` name."""
    import numpy as np  # imported here so that reading parameters (`pendsweep --help`) does not load numpy

    return np.array([values[name] for name in KERNEL_FIELDS], dtype=np.float64)


#: Table IV test-rig parameters with the Figs. 9-11 oscillator.
TABLE_IV = ModelParams()
#: Fig. 8: 2:1 internal resonance and quenching, alpha = 2 N, fe = 2.25 Hz.
FIG8 = TABLE_IV.replace(alpha=2.0, fe=2.25)
#: Fig. 9(a): periodic orbit (PO), alpha = 5 N, fe = 2.2 Hz.
FIG9_PO = TABLE_IV.replace(alpha=5.0, fe=2.2)
#: Fig. 9(b): chaotic orbit (CO), alpha = 12 N, fe = 2.2 Hz.
FIG9_CO = TABLE_IV.replace(alpha=12.0, fe=2.2)
#: Fig. 11(a): alpha swept 0-45 N at fe = 2.5 Hz (alpha here is the start value).
FIG11A = TABLE_IV.replace(alpha=0.0, fe=2.5)
#: Fig. 11(b): M swept at alpha = 17 N, fe = 2.5 Hz.
FIG11B = TABLE_IV.replace(alpha=17.0, fe=2.5)


# -- the linear substructured loop of section 2.4 ------------------------------


@dataclass(frozen=True)
class LoopParams:
    """The linear substructured loop of Eqs. (6)-(9), pendulum at rest.

    ``M1 ÿ* + C1 ẏ* + K y* + m_s ẍ + C2 ẋ = F_e`` with ``x`` the delayed
    ``y*``; ``m_s = M2 + m`` is everything the actuator carries. These are
    not :class:`ModelParams` because the stability analysis needs only these
    five numbers (and the paper's Fig. 5 example is not a pendulum rig).

    Attributes
    ----------
    M1 : float
        Numerical-model mass [kg], > 0.
    C1 : float
        Numerical-model damping [kg/s], >= 0.
    K : float
        Numerical-model stiffness [N/m], > 0.
    ms : float
        Mass carried by the actuator, ``M2 + m`` [kg], > 0.
    C2 : float
        Damping of the physical platform [kg/s], >= 0.
    """

    M1: float
    C1: float
    K: float
    ms: float
    C2: float

    _SPECS = {
        "M1": ("kg", False, "numerical-model mass"),
        "C1": ("kg/s", True, "numerical-model damping"),
        "K": ("N/m", False, "numerical-model stiffness"),
        "ms": ("kg", False, "mass carried by the actuator, m_s = M2 + m"),
        "C2": ("kg/s", True, "platform damping"),
    }

    def __post_init__(self) -> None:
        for name, (unit, zero_ok, doc) in self._SPECS.items():
            value = getattr(self, name)
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{name} = {value!r} is not a number ({doc})") from None
            ok = math.isfinite(v) and (v >= 0.0 if zero_ok else v > 0.0)
            if not ok:
                bound = "[0, inf)" if zero_ok else "(0, inf)"
                raise ParameterError(f"{name} = {v!r} {unit} is outside the accepted range {bound} ({doc})")
            object.__setattr__(self, name, v)

    @property
    def mass_ratio(self) -> float:
        """p = m_s / M1, the abscissa of Fig. 6 [-]."""
        return self.ms / self.M1

    @classmethod
    def from_model(cls, params: ModelParams) -> LoopParams:
        """The loop of a rig: ``M1 = M - M2``, ``C1 = C - C2``, ``m_s = M2 + m``."""
        return cls(M1=params.M1, C1=params.C1, K=params.K, ms=params.M2 + params.m, C2=params.C2)

    @classmethod
    def from_natural(cls, omega_n: float, zeta: float, p: float, c2_over_c1: float, M1: float = 1.0) -> LoopParams:
        """Loop from the numerical model's ``omega_n`` [rad/s] and ``zeta`` [-] (Fig. 6)."""
        C1 = 2.0 * zeta * omega_n * M1
        return cls(M1=M1, C1=C1, K=omega_n**2 * M1, ms=p * M1, C2=c2_over_c1 * C1)


#: Fig. 5 example (caption): M1 = 20 kg, C1 = 20 kg/s, K = 2000 N/m, m_s = 10 kg, C2 = 20 kg/s.
FIG5_LOOP = LoopParams(M1=20.0, C1=20.0, K=2000.0, ms=10.0, C2=20.0)
#: Fig. 7 numerical model M1 = 1 kg, C1 = 5 kg/s, K = 12000 N/m on the bare platform
#: (m_s = M2 = 0.9 kg, C2 = 10 kg/s, Table IV); the caption's tau_max = 0.009 s.
FIG7_LOOP = LoopParams(M1=1.0, C1=5.0, K=12000.0, ms=0.9, C2=10.0)
#: Table II mass ratios p = m_s/M1: M2 = 0.9 kg alone, then M2 + m with m = 0.27 kg
#: plus 0.65 kg steps ("adding mass to the pendulum in increments of 650 g").
TABLE_II_P = (0.2250, 0.2925, 0.4550, 0.6175)
#: Table II numerical model (Fig. 6 caption): M1 = 4 kg, C1 = 10 kg/s, K = 3000 N/m, C2 = C1.
TABLE_II_LOOPS = tuple(LoopParams(M1=4.0, C1=10.0, K=3000.0, ms=p * 4.0, C2=10.0) for p in TABLE_II_P)
#: Table II as rigs for the substructured backend (alpha = 0). p = 0.225 has m_s = 0.9 kg,
#: which needs m > 0 here: it is split as M2 = 0.63 kg, m = 0.27 kg (only m_s enters the loop
#: while the pendulum is at rest). The others keep M2 = 0.9 kg and load the pendulum.
TABLE_II_MODELS = tuple(
    TABLE_IV.replace(
        m=0.27 if i == 0 else p * 4.0 - 0.9,
        M2=p * 4.0 - 0.27 if i == 0 else 0.9,
        C2=10.0,
        M1=4.0,
        C1=10.0,
        K=3000.0,
        alpha=0.0,
    )
    for i, p in enumerate(TABLE_II_P)
)
#: Table II instability frequencies [rad/s] as printed: theoretical row.
TABLE_II_FREQ_THEORY_PAPER = (31.0, 32.0, 37.0, 44.0)
#: Table II instability frequencies [rad/s] as printed: experimental row.
TABLE_II_FREQ_EXPERIMENT_PAPER = (32.0, 34.0, 40.0, 45.0)
#: Fig. 6 numerical model (text of section 2.4): omega_n = 10 rad/s, zeta = 0.05.
FIG6_OMEGA_N = 10.0
FIG6_ZETA = 0.05
