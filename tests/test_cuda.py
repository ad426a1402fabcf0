"""The CUDA kernel of the emulated system against the CPU batched kernel.

Without a GPU (CI) the kernel runs in numba's CUDA simulator, which must be
switched on before numba is imported, so those runs happen in a subprocess
(``NUMBA_ENABLE_CUDASIM=1``) on a few points with a coarse step (100 steps
per forcing period, identical on both sides). A real GPU, when present, is
checked in this process on many points at the paper's 1 ms step.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numba
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from pendsweep.backends import PointRun, make_backend
from pendsweep.backends._batch import run_batch
from pendsweep.classify import classify_run
from pendsweep.cli import main
from pendsweep.errors import ConfigError
from pendsweep.gpu import cuda_unavailable_reason
from pendsweep.kernels import RECORD_COLUMNS, STATUS_DIVERGED, STATUS_OK
from pendsweep.params import TABLE_IV
from pendsweep.results import read_metadata
from pendsweep.status import Status
from pendsweep.sweep import SweepConfig, run_sweep

DT = 0.004  # 100 steps per period at 2.5 Hz, 114 at 2.2 Hz: two forcing tables in one launch
TRANSIENT, RECORD = 5, 25  # 30 periods compared
#: (alpha [N], fe [Hz]) of non-chaotic points: semi-trivial, and three periodic-2 swings.
POINTS = ((5.0, 2.5), (25.0, 2.5), (8.0, 2.2), (45.0, 2.5))
SETTLE_PERIODS = 400

SIMULATED = textwrap.dedent(
    """
    import sys
    import numpy as np
    from pendsweep.backends._batch import run_batch
    from pendsweep.params import TABLE_IV

    data = np.load(sys.argv[1])
    params = [TABLE_IV.replace(alpha=a, fe=fe) for a, fe in data["points"]]
    out = {}
    for precision in ("float64", "float32"):
        run = run_batch(params, data["states"], int(data["transient"]), int(data["record"]), dt=float(data["dt"]),
                        device="cuda", precision=precision)
        out.update({f"{precision}_{k}": v for k, v in run._asdict().items()})
    run = run_batch(params, data["states"], 0, 3, dt=float(data["dt"]), signum="stage", device="cuda")
    out.update({f"stage_{k}": v for k, v in run._asdict().items()})
    from pendsweep.basins import EmulatedMap
    basin_map = EmulatedMap(tuple(params[:4]), dt=float(data["dt"]), device="cuda")
    out["map_records"] = basin_map.advance(data["states"][:4], 3, np.arange(4))[0]
    np.savez(sys.argv[2], **out)
    import json
    from pendsweep.sweep import SweepConfig, run_sweep
    run_sweep(SweepConfig.from_dict(json.loads(open(sys.argv[3]).read())), sys.argv[4])
    """
)


def _labels(params, run, dt=DT) -> list[str]:
    """Motion labels of a batched run's points (classification re-simulates on the CPU at step ``dt``)."""
    backend = make_backend("emulated", dt=dt)
    return [
        classify_run(
            backend,
            q,
            PointRun(run.records[i], run.states[i], Status.from_code(run.status[i]), int(run.periods_done[i])),
        ).label
        for i, q in enumerate(params)
    ]


def _scaled_error(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |a - b| over finite records, per column relative to max(1, that column's largest |b|)."""
    scale = np.maximum(1.0, np.nanmax(np.abs(b), axis=(0, 1)))
    return float(np.nanmax(np.abs(a - b) / scale))


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """CPU reference and the simulator's float64, float32 and per-stage-signum runs on the same points."""
    params = [TABLE_IV.replace(alpha=a, fe=fe) for a, fe in POINTS]
    # Start on the attractors (settled by the CPU kernel), plus one point that diverges at once.
    settled = run_batch(params, np.tile([0.0, 0.0, 0.5, 0.0], (len(params), 1)), 0, SETTLE_PERIODS, dt=DT).states
    settled[0] = [0.0, 0.0, 0.0, 0.0]  # the pendulum at rest stays at rest: the semi-trivial solution
    params.append(TABLE_IV)
    states = np.vstack([settled, [np.nan, 0.0, 0.1, 0.0]])
    folder = tmp_path_factory.mktemp("cudasim")
    np.savez(
        folder / "in.npz",
        points=np.array([*POINTS, (TABLE_IV.alpha, TABLE_IV.fe)]),
        states=states,
        transient=TRANSIENT,
        record=RECORD,
        dt=DT,
    )
    (folder / "sweep.json").write_text(json.dumps(sweep_config("cuda").to_dict()))
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            SIMULATED,
            str(folder / "in.npz"),
            str(folder / "out.npz"),
            str(folder / "sweep.json"),
            str(folder / "sweep.parquet"),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = dict(np.load(folder / "out.npz"))
    cpu = run_batch(params, states, TRANSIENT, RECORD, dt=DT)
    stage = run_batch(params, states, 0, 3, dt=DT, signum="stage")
    out["sweep"] = folder / "sweep.parquet"
    out["states"] = states
    return params, cpu, stage, out


def sweep_config(device: str) -> SweepConfig:
    """A small multistart alpha sweep (3 values x 2 seeded starts) on ``device``."""
    return SweepConfig(
        parameter="alpha",
        values=(5.0, 25.0, 45.0),
        mode="multistart",
        starts=2,
        backend_options={"dt": DT, "device": device},
        transient_periods=2,
        record_periods=4,
    )


def _run(out, prefix):
    from pendsweep.backends._batch import BatchRun

    return BatchRun(*(out[f"{prefix}_{k}"] for k in BatchRun._fields))


def test_simulated_float64_records_match_cpu_batched_kernel(simulated):
    params, cpu, _, out = simulated
    gpu = _run(out, "float64")
    assert gpu.records.shape == cpu.records.shape == (len(params), RECORD, len(RECORD_COLUMNS))
    ok = slice(0, len(POINTS))
    assert _scaled_error(gpu.records[ok], cpu.records[ok]) < 1e-9
    assert np.max(np.abs(gpu.states[ok] - cpu.states[ok])) < 1e-9
    # The swinging points really swing (the comparison is not between two pendulums at rest).
    assert np.all(np.nanmax(cpu.records[1 : len(POINTS), :, 1], axis=1) > 0.9)


def test_simulated_same_status_codes_and_divergence_as_cpu(simulated):
    _, cpu, _, out = simulated
    gpu = _run(out, "float64")
    assert gpu.status.tolist() == cpu.status.tolist() == [STATUS_OK] * len(POINTS) + [STATUS_DIVERGED]
    assert gpu.periods_done.tolist() == cpu.periods_done.tolist() == [TRANSIENT + RECORD] * len(POINTS) + [0]
    assert np.isnan(gpu.records[-1]).all()


def test_simulated_motion_labels_match(simulated):
    params, cpu, _, out = simulated
    labels = _labels(params, cpu)
    assert labels == ["semi-trivial", "periodic-2", "periodic-2", "periodic-2", "n/a"]
    assert _labels(params, _run(out, "float64")) == labels
    assert _labels(params, _run(out, "float32")) == labels


def test_simulated_basin_map_rounds_match_cpu(simulated):
    """Basins and 2-D maps integrate their rounds on the GPU through the same EmulatedMap."""
    from pendsweep.basins import EmulatedMap

    params, cpu, _, out = simulated
    reference = EmulatedMap(tuple(params[:4]), dt=DT).advance(out["states"][:4], 3, np.arange(4))[0]
    assert _scaled_error(out["map_records"], reference) < 1e-9


def test_simulated_signum_per_stage_matches(simulated):
    params, _, stage, out = simulated
    ok = slice(0, len(POINTS))
    assert _scaled_error(_run(out, "stage").records[ok], stage.records[ok]) < 1e-9


def test_simulated_sweep_file_matches_cpu_sweep(simulated, tmp_path):
    """``--device cuda`` streams the same rows to the same result file format as the CPU."""
    gpu = pd.read_parquet(simulated[3]["sweep"])
    cpu = run_sweep(sweep_config("cpu"), tmp_path / "cpu.parquet")
    assert len(gpu) == len(cpu) == 3 * 2 * 4
    keys = ["point", "start", "period"]
    gpu, cpu = gpu.sort_values(keys).reset_index(drop=True), cpu.sort_values(keys).reset_index(drop=True)
    assert gpu["motion"].tolist() == cpu["motion"].tolist()
    for column in RECORD_COLUMNS:
        np.testing.assert_allclose(gpu[column], cpu[column], rtol=0, atol=1e-9)
    assert read_metadata(simulated[3]["sweep"])["config"]["backend_options"]["device"] == "cuda"


def test_simulated_float32_error_is_single_precision_rounding(simulated):
    """float32 differs from float64 by accumulated single-precision rounding: far above 1e-12, far below the motion."""
    _, cpu, _, out = simulated
    ok = slice(0, len(POINTS))
    err = _scaled_error(_run(out, "float32").records[ok], cpu.records[ok])
    assert 1e-7 < err < 1e-3, err


def test_device_cuda_without_gpu_exits_2(tmp_path):
    if numba.config.ENABLE_CUDASIM or cuda_unavailable_reason() is None:
        pytest.skip("a CUDA device (or the simulator) is available here")
    args = [
        "alpha",
        "--from",
        "10",
        "--to",
        "11",
        "--points",
        "2",
        "--mode",
        "fresh",
        "--device",
        "cuda",
        "-o",
        str(tmp_path / "a.parquet"),
    ]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2
    message = result.output.strip()
    assert "\n" not in message and "no usable CUDA GPU" in message and "pendsweep[cuda]" in message
    assert not (tmp_path / "a.parquet").exists()
    result = CliRunner().invoke(
        main, ["hopf", "--what", "1.0", "--method", "simulate", "--device", "cuda", "-o", str(tmp_path / "h.parquet")]
    )
    assert result.exit_code == 2 and "no usable CUDA GPU" in result.output
    result = CliRunner().invoke(main, args[:-4] + ["-B", "device=cuda", "-o", str(tmp_path / "b.parquet")])
    assert result.exit_code == 2 and "no usable CUDA GPU" in result.output
    for command in (
        ["basins", "--alpha", "40", "--grid", "3x3", "--device", "cuda", "-o", str(tmp_path / "g.parquet")],
        [
            "map",
            "alpha",
            "fe",
            "--alpha",
            "0:45:3",
            "--fe",
            "2:3:3",
            "--device",
            "cuda",
            "-o",
            str(tmp_path / "m.parquet"),
        ],
    ):
        result = CliRunner().invoke(main, command)
        assert result.exit_code == 2 and "no usable CUDA GPU" in result.output, command
    assert list(tmp_path.iterdir()) == []  # stopped before any result file or its parts were made


def test_device_and_precision_options_are_validated():
    with pytest.raises(ConfigError, match="device"):
        make_backend("emulated", device="tpu")
    with pytest.raises(ConfigError, match="float32"):
        make_backend("emulated", precision="float32")  # the CPU kernels are float64 only
    with pytest.raises(ConfigError, match="precision"):
        run_batch([TABLE_IV], np.zeros((1, 4)), 0, 1, device="cuda", precision="float16")


PTX = textwrap.dedent(
    """
    import sys, types
    from numba import types as nt
    from pendsweep.kernels._cuda import emulated_kernel_function, import_cuda

    cuda = import_cuda()
    if getattr(cuda, "implementation", "") == "Built-in":
        sys.exit("SKIP numba-cuda is not installed (pip install 'pendsweep[cuda]')")
    import numba.cuda.dispatcher as dispatcher
    # No device here: device functions are compiled for compute capability 9.0 instead of the current device's.
    dispatcher.get_current_device = lambda: types.SimpleNamespace(compute_capability=(9, 0))
    for precision, real in (("float64", nt.float64), ("float32", nt.float32)):
        sig = (real[:, ::1], real[:, ::1], real[::1], real[::1], nt.int64[::1], nt.int64[::1], real[::1], nt.int64,
               nt.float64[:, :, ::1], nt.int64[::1], nt.int64[::1])
        try:
            ptx, _ = cuda.compile_ptx(emulated_kernel_function(precision, False), sig, cc=(9, 0))
        except Exception as exc:
            if "nvvm" in str(exc).lower() or "nvrtc" in str(exc).lower():
                sys.exit(f"SKIP no NVVM/NVRTC here: {str(exc).splitlines()[0]}")
            raise
        print(precision, ptx.count(".f64"), ptx.count(".f32"))
    """
)


def test_kernel_compiles_for_a_real_gpu():
    """With numba-cuda and NVVM installed, the kernel (float64 and float32) compiles to PTX for sm_90, no GPU needed."""
    proc = subprocess.run([sys.executable, "-c", PTX], capture_output=True, text=True, timeout=300)
    if proc.returncode != 0 and "SKIP" in proc.stderr:
        pytest.skip(proc.stderr.strip().split("SKIP ", 1)[1])
    assert proc.returncode == 0, proc.stderr[-3000:]
    counts = {line.split()[0]: [int(v) for v in line.split()[1:]] for line in proc.stdout.splitlines()}
    assert counts["float64"][1] == 0  # float64: no single-precision arithmetic at all
    assert counts["float32"][1] > counts["float32"][0]  # float32: the right-hand sides run in single precision


@pytest.mark.skipif(numba.config.ENABLE_CUDASIM, reason="the real-GPU test does not run in the simulator")
def test_real_gpu_matches_cpu_on_many_points():
    reason = cuda_unavailable_reason()
    if reason is not None:
        pytest.skip(f"no CUDA GPU: {reason}")
    rng = np.random.default_rng(16)
    n = 1024
    params = [
        TABLE_IV.replace(alpha=a, fe=fe) for a, fe in zip(rng.uniform(0, 45, n), rng.choice([2.0, 2.2, 2.5, 2.8], n))
    ]
    states = np.column_stack([np.zeros(n), np.zeros(n), rng.uniform(-0.5, 0.5, n), np.zeros(n)])
    cpu = run_batch(params, states, 0, 30)
    gpu = run_batch(params, states, 0, 30, device="cuda")
    labels = _labels(params, cpu, 1e-3)
    steady = np.array([lab == "semi-trivial" or lab.startswith("periodic") for lab in labels])
    assert steady.sum() > 50
    assert _scaled_error(gpu.records[steady], cpu.records[steady]) < 1e-9
    assert _labels([p for p, s in zip(params, steady) if s], _subset(gpu, steady), 1e-3) == [
        lab for lab, s in zip(labels, steady) if s
    ]
    print(json.dumps({"gpu_points": len(params), "steady_points": int(steady.sum())}))


def _subset(run, mask):
    from pendsweep.backends._batch import BatchRun

    return BatchRun(*(a[mask] for a in run))
