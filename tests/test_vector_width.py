"""The 512-bit tuning of the kernels (pendsweep.kernels._vector_width): applied once, before numba compiles, and only then."""

import os
import subprocess
import sys

import llvmlite.binding as llvm
import pytest

PROBE = (
    "import pendsweep.kernels as k; from numba.core import config; "
    "print(k.WIDE_VECTORS, config.CPU_FEATURES is not None and '-prefer-256-bit' in config.CPU_FEATURES)"
)


def _probe(code: str, **env: str) -> str:
    environment = {k: v for k, v in os.environ.items() if k not in ("PENDSWEEP_VECTOR_WIDTH", "NUMBA_CPU_FEATURES")}
    environment.update(env)
    done = subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True, check=True)
    return done.stdout.strip()


def _host_has_avx512() -> bool:
    llvm.initialize_native_target()
    return "+avx512f" in llvm.get_host_cpu_features().flatten().split(",")


def test_wide_vectors_on_an_avx512_host_and_not_elsewhere():
    wide = _host_has_avx512()
    assert _probe(PROBE) == f"{wide} {wide}"


@pytest.mark.parametrize(
    "setup, env",
    [
        ("", {"PENDSWEEP_VECTOR_WIDTH": "256"}),  # the user asks for numba's own tuning
        ("import warnings; warnings.simplefilter('ignore'); ", {"PENDSWEEP_VECTOR_WIDTH": "128"}),  # not a width
        ("", {"NUMBA_CPU_NAME": "generic"}),  # the user chose numba's target
        ("import numba; numba.njit(lambda x: x); ", {}),  # numba's code generator exists already: too late
    ],
    ids=["opt-out", "unknown-width", "cpu-name", "numba-first"],
)
def test_the_tuning_is_left_alone_when_asked_or_too_late(setup, env):
    assert _probe(setup + PROBE, **env) == "False False"


def test_a_users_own_cpu_features_win():
    features = llvm.get_host_cpu_features().flatten() if _host_has_avx512() else "+sse2"
    out = _probe("import pendsweep.kernels as k; from numba.core import config; print(k.WIDE_VECTORS, config.CPU_FEATURES)",
                 NUMBA_CPU_FEATURES=features)  # fmt: skip
    assert out == f"False {features}"


def test_an_unknown_width_warns_naming_the_accepted_ones():
    done = subprocess.run(
        [sys.executable, "-c", "import pendsweep.kernels"],
        env=dict(os.environ, PENDSWEEP_VECTOR_WIDTH="foo"), capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert "PENDSWEEP_VECTOR_WIDTH = 'foo': accepted 512 or 256" in done.stderr
