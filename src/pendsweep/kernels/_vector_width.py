"""How LLVM builds the kernels' vector loops: 512-bit vectors where the CPU has them, two iterations interleaved.

LLVM tunes the Intel server CPUs that have AVX-512 to *prefer* 256-bit
vectors (the ``prefer-256-bit`` tuning feature: wide vectors used to lower
the clock of older parts). The batched kernel (:mod:`pendsweep.kernels._batched`)
is bound by its arithmetic, and on the machines measured (``make bench``,
``throughput``) 8 lanes per instruction beat the clock penalty: 7.2 against
10.4 ns per point-step per core on one thread. The tuning is a CPU feature of numba's code
generator, which it reads once, when the first function is compiled; so
:func:`prefer_wide_vectors` runs before any of pendsweep's kernels is
defined, and changes nothing when numba has already compiled something in
this process, when ``NUMBA_CPU_FEATURES`` or ``NUMBA_CPU_NAME`` is set, or
when ``PENDSWEEP_VECTOR_WIDTH=256`` asks for numba's own tuning (any other
value than 256 or 512 warns and keeps numba's). The tuning is numba's, for
the whole process: numba code of the user's own compiled after pendsweep is
imported gets it too (only the width LLVM prefers changes, not what the code
computes). Results may differ from the 256-bit build in the last bits that
FMA contraction moves (the tests' tolerances, and the bit-identical resumes
within one build, hold for both; an independent check found the Fig. 11(a)
sweep, the dense fresh sweep and a 60 x 60 basin map bitwise identical); numba's cache keeps the two builds apart (its index is keyed by the
CPU features).

Two vector iterations in flight (issue 33): one iteration of the batched
lane loop is a long chain of dependent operations per lane group (four RK4
stages, each waiting on the last, a division in each), about 500
instructions, more than a core keeps in flight (Zen 3: 256), so consecutive
iterations barely overlap. LLVM interleaves two iterations of a vectorised
loop only where it judges the register pressure low, which it never does
here; :func:`interleave_vector_loops` forces two (``-force-vector-interleave=2``,
an LLVM option read whenever a loop is vectorised, so it holds for every
kernel compiled afterwards, whatever numba compiled before). Measured on a
loaded 2-core AMD EPYC (Zen 5) in one session, ns per point-step per core:
the AVX2 build 11.4-11.6 -> 9.5, the AVX-512 build 6.4-6.7 -> 5.2-5.5. Each
lane's arithmetic is unchanged (records bit-identical), and the chunks'
padding (``LANE_GROUP`` = 16 lanes) is a whole number of interleaved
iterations for every vector width up to 8 doubles, so no lane runs in the
scalar remainder loop. Like the width, the option is LLVM's, for the whole
process: vectorised loops of the user's own numba code compiled in it are
interleaved twice too (only their speed may change).
"""

import os
import warnings

#: Values of ``PENDSWEEP_VECTOR_WIDTH``: 512 (the default where the CPU has AVX-512) or 256 (numba's tuning).
WIDTHS = ("512", "256")


def prefer_wide_vectors() -> bool:
    """Drop LLVM's ``prefer-256-bit`` tuning on an AVX-512 CPU; whether it was dropped."""
    width = os.environ.get("PENDSWEEP_VECTOR_WIDTH", "512")
    if width not in WIDTHS:
        warnings.warn(
            f"PENDSWEEP_VECTOR_WIDTH = {width!r}: accepted {' or '.join(WIDTHS)}; numba's own tuning is kept",
            stacklevel=2,
        )
        return False
    if width == "256" or os.environ.get("NUMBA_CPU_FEATURES") or os.environ.get("NUMBA_CPU_NAME"):
        return False
    from numba.core import config
    from numba.core.registry import cpu_target

    if config.CPU_FEATURES is not None or config.CPU_NAME is not None or "_toplevel_target_context" in vars(cpu_target):
        return False  # the user chose the target, or numba's code generator already exists
    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features().flatten()
    if "+avx512f" not in features.split(","):
        return False
    config.CPU_FEATURES = features + ",-prefer-256-bit"
    return True


#: Vector iterations LLVM interleaves in every vectorised loop (see the module docstring).
INTERLEAVE = 2


def interleave_vector_loops() -> None:
    """Have LLVM interleave :data:`INTERLEAVE` iterations of every loop it vectorises from now on."""
    import llvmlite.binding as llvm

    llvm.set_option("", f"-force-vector-interleave={INTERLEAVE}")


#: Whether this process builds the kernels with 512-bit vectors (decided on first import).
WIDE_VECTORS = prefer_wide_vectors()
interleave_vector_loops()
