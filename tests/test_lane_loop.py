"""The batched kernel's lane loop as LLVM builds it for AVX2 and AVX-512 (issue 33), checked from any x86-64 host."""

import pytest

from pendsweep.bench.lane_loop import TARGETS_ISA, lane_loop_mix, vector_instructions_for
from pendsweep.kernels._batched import LANE_GROUP

#: Expected register, doubles per vector and lanes per loop iteration (two iterations interleaved).
SHAPES = {"avx2": ("ymm", 4, 8), "avx512": ("zmm", 8, 16)}


@pytest.mark.parametrize("isa", sorted(TARGETS_ISA))
def test_the_lane_loop_is_packed_for_each_vector_isa(isa):
    """No scalar double arithmetic and no scalar int-float conversion in the loop body, two vector groups per iteration.

    Compiled in a fresh process for the target (``NUMBA_CPU_NAME`` with its
    own features), so an AVX-512 host checks the AVX2 build and the other way
    round. The chunks' padding must be a whole number of iterations, or a lane
    would run in the scalar remainder loop and differ in its last bits.
    """
    register, width, lanes = SHAPES[isa]
    mix = vector_instructions_for(isa)
    assert mix[f"{register}_packed_double_ops"] > 300, mix
    assert mix["scalar_double_ops"] == 0 and mix["scalar_conversions"] == 0, mix
    assert (mix["vector_width"], mix["lanes_per_iteration"]) == (width, lanes), mix
    assert LANE_GROUP % mix["lanes_per_iteration"] == 0


ASM = """\
.LBB0_1:
\tvmulsd\t%xmm0, %xmm1, %xmm1
.LBB0_2:
\tvfmadd213pd\t%ymm2, %ymm1, %ymm0
\tvmulpd\t48(%rsp), %ymm4, %ymm0
\tvcvttsd2si\t%xmm6, %rdx
\tvmaskmovpd\t%ymm1, %ymm9, (%rcx,%rax,8)
\tjne\t.LBB0_2
.LBB0_3:
\tvaddsd\t%xmm0, %xmm1, %xmm1
\tjne\t.LBB0_3
\tjmp\t.LBB0_1
"""
IR = """\
vector.body:                                      ; preds = %vector.body
  %1 = fmul contract <4 x double> %a, %b
  %index.next = add nuw i64 %index, 8
  br i1 %2, label %middle.block, label %vector.body
middle.block:
"""


def test_the_mix_counts_the_innermost_loop_with_packed_arithmetic():
    """The outer loop (scalar work around the vector loop) and the scalar remainder loop are not the lane loop."""
    mix = lane_loop_mix(ASM, IR)
    assert mix["ymm_packed_double_ops"] == 2 and mix["scalar_double_ops"] == 0
    assert mix["scalar_conversions"] == 1 and mix["masked_stores"] == 1 and mix["loop_instructions"] == 5
    assert (mix["vector_width"], mix["lanes_per_iteration"]) == (4, 8)
    assert mix["scalar_double_ops_in_function"] == 2
