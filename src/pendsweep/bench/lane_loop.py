"""What LLVM made of the batched kernel's lane loop: its instruction mix, for this process's target or another ISA.

Any x86-64 machine can compile the kernel for another ISA (it cannot run
it), so an AVX-512 machine can check the AVX2 build's loop and the other
way round (issue 33): ``make bench`` (``throughput``) and
``tests/test_lane_loop.py`` do both.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile

import numba as nb
import numpy as np

# Double arithmetic as AT&T assembly spells it: packed (…pd, register width from the operands) and scalar (…sd).
_ARITHMETIC = r"v?(?:fn?m(?:add|sub)\d+|mul|add|sub|div|sqrt|min|max)"
_PACKED = re.compile(rf"^\s+{_ARITHMETIC}pd\s.*%([xyz])mm\d+\s*$")
_SCALAR = re.compile(rf"^\s+{_ARITHMETIC}sd\s")
_CONVERSION = re.compile(r"^\s+v?cvtt?(?:sd2si|si2sd)")  # scalar int <-> double: AVX2 has no packed form
_MASKED_STORE = re.compile(r"^\s+vmaskmovpd\s+%[xy]mm\d+,\s*%[xy]mm\d+,\s*\S*\(")
#: Vector ISAs whose lane loop make bench and the tests inspect: ``NUMBA_CPU_NAME`` and ``NUMBA_CPU_FEATURES``.
#: The features are given in full: with a CPU name alone numba still passes the host's features (an
#: AVX-512 host's would leak into an AVX2 target). The AVX-512 target drops ``prefer-256-bit`` as
#: :mod:`pendsweep.kernels._vector_width` does on such a host.
TARGETS_ISA = {"avx2": ("haswell", ""), "avx512": ("skylake-avx512", "-prefer-256-bit")}


def _innermost_loops(asm: str) -> list[list[str]]:
    """Instruction lines of each innermost loop of ``asm`` (a label and the last backward jump to it)."""
    lines = asm.splitlines()
    labels = {m.group(1): i for i, line in enumerate(lines) if (m := re.match(r"^(\.LBB\d+_\d+):", line))}
    spans = {}
    for i, line in enumerate(lines):
        m = re.search(r"\bj\w+\s+(\.LBB\d+_\d+)\s*$", line)
        if m and labels.get(m.group(1), i) < i:
            spans[m.group(1)] = (labels[m.group(1)], i)
    inner = [
        (a, b) for a, b in spans.values() if not any(a <= c and d <= b and (c, d) != (a, b) for c, d in spans.values())
    ]
    return [[x for x in lines[a : b + 1] if re.match(r"^\s+[a-z]", x)] for a, b in inner]


def lane_loop_mix(asm: str, llvm_ir: str) -> dict:
    """Instruction mix of the vectorised lane loop: the innermost loop of ``asm`` with the most packed double arithmetic.

    ``lanes_per_iteration`` is the lanes one iteration of LLVM's ``vector.body``
    advances (vector width times interleave), ``vector_width`` the doubles per
    vector; ``scalar_double_ops_in_function`` counts the whole function, whose
    scalar remainder loop never runs (chunks are padded to whole iterations).
    """
    body = max(_innermost_loops(asm), key=lambda loop: sum(bool(_PACKED.match(x)) for x in loop))
    packed = [m.group(1) for x in body if (m := _PACKED.match(x))]
    bodies = re.findall(r"^vector\.body[\w.]*:.*?(?=^\S)", llvm_ir, re.M | re.S)
    widest = max(bodies, key=lambda b: b.count(" x double>"))
    step = re.search(r"%index\.next\S* = add nuw (?:nsw )?i64 %index\S*, (\d+)", widest)
    width = re.search(r"fmul[^<]*<(\d+) x double>", widest)
    return {
        "loop_instructions": len(body),
        "zmm_packed_double_ops": packed.count("z"),
        "ymm_packed_double_ops": packed.count("y"),
        "xmm_packed_double_ops": packed.count("x"),
        "scalar_double_ops": sum(bool(_SCALAR.match(x)) for x in body),
        "scalar_conversions": sum(bool(_CONVERSION.match(x)) for x in body),
        "masked_stores": sum(bool(_MASKED_STORE.match(x)) for x in body),
        "lanes_per_iteration": int(step.group(1)) if step else 0,
        "vector_width": int(width.group(1)) if width else 0,
        "scalar_double_ops_in_function": sum(bool(_SCALAR.match(x)) for x in asm.splitlines()),
    }


def vector_instructions() -> dict:
    """:func:`lane_loop_mix` of the batched kernel as LLVM builds it for this process's target."""
    from numba.core import config

    from ..kernels._batched import _N_CONST, _advance_chunk

    fn = nb.njit(**{k: v for k, v in _advance_chunk.targetoptions.items() if k not in ("cache", "nopython")})(
        _advance_chunk.py_func
    )  # uncached, to inspect
    fn(*[np.zeros(16) for _ in range(7)], np.ones((_N_CONST, 16)), np.zeros((3, 16)), np.zeros(3), True, 0, 1, False)
    mix = lane_loop_mix(next(iter(fn.inspect_asm().values())), next(iter(fn.inspect_llvm().values())))
    return {"cpu_name": config.CPU_NAME or "host", **mix}


_MIX_SCRIPT = (
    "import json; from pendsweep.bench.lane_loop import vector_instructions; print(json.dumps(vector_instructions()))"
)


def target_environment(isa: str, cache_dir: str) -> dict[str, str]:
    """The environment that builds pendsweep's kernels for ``isa`` (a key of :data:`TARGETS_ISA`)."""
    name, features = TARGETS_ISA[isa]
    return dict(os.environ, NUMBA_CPU_NAME=name, NUMBA_CPU_FEATURES=features, NUMBA_CACHE_DIR=cache_dir)


def vector_instructions_for(isa: str) -> dict:
    """:func:`vector_instructions` compiled for another ISA in a fresh process (any x86-64 host can compile it)."""
    with tempfile.TemporaryDirectory(prefix="pendsweep-isa-") as cache:
        done = subprocess.run(
            [sys.executable, "-c", _MIX_SCRIPT], env=target_environment(isa, cache),
            capture_output=True, text=True, check=True,
        )  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])
