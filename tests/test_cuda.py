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

from pendsweep.analysis.classify import classify_run
from pendsweep.backends import PointRun, make_backend
from pendsweep.backends._batch import run_batch
from pendsweep.backends.gpu import cuda_unavailable_reason
from pendsweep.backends.status import Status
from pendsweep.cli import main
from pendsweep.engine.results import read_metadata
from pendsweep.errors import ConfigError
from pendsweep.kernels import RECORD_COLUMNS, STATUS_DIVERGED, STATUS_OK
from pendsweep.model.params import TABLE_IV
from pendsweep.studies.sweep import SweepConfig, run_sweep

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
    from pendsweep.model.params import TABLE_IV

    data = np.load(sys.argv[1])
    params = [TABLE_IV.replace(alpha=a, fe=fe) for a, fe in data["points"]]
    out = {}
    for precision in ("float64", "float32"):
        run = run_batch(params, data["states"], int(data["transient"]), int(data["record"]), dt=float(data["dt"]),
                        device="cuda", precision=precision)
        out.update({f"{precision}_{k}": v for k, v in run._asdict().items()})
    run = run_batch(params, data["states"], 0, 3, dt=float(data["dt"]), signum="stage", device="cuda")
    out.update({f"stage_{k}": v for k, v in run._asdict().items()})
    from pendsweep.studies.basins import EmulatedMap
    basin_map = EmulatedMap(tuple(params[:4]), dt=float(data["dt"]), device="cuda")
    out["map_records"] = basin_map.advance(data["states"][:4], 3, np.arange(4))[0]
    np.savez(sys.argv[2], **out)
    import json
    from pendsweep.studies.sweep import SweepConfig, run_sweep
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
    from pendsweep.studies.basins import EmulatedMap

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


real_gpu_only = pytest.mark.skipif(numba.config.ENABLE_CUDASIM, reason="the real-GPU tests do not run in the simulator")
#: Labels whose records converge onto an attractor, so that GPU and CPU records agree to rounding.
STEADY = ("semi-trivial", "periodic-")
MANY_TRANSIENT = 200


#: Initial-angle offsets [rad] of the CPU runs that tell which points rounding can move elsewhere, and the record
#: difference under which such a run counts as unmoved: float64's comparison, and single precision's.
PERTURBATIONS = {"float64": (1e-12, 1e-9), "float32": (1e-6, 1e-3)}


def _point_errors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per point, the largest |a - b| over its records, each column relative to max(1, its largest |b|)."""
    scale = np.maximum(1.0, np.nanmax(np.abs(b), axis=(0, 1)))
    return np.nanmax(np.abs(a - b) / scale, axis=(1, 2))


@pytest.fixture(scope="module")
def many_points():
    """1024 random (alpha, fe, theta0) points, their CPU records at 1 ms and which are robust; no GPU: skipped.

    200 periods of transient, then 30 recorded (without the transient most
    points are labelled ``transient``). Many starts pass through a chaotic
    transient on their way to a periodic attractor, and there a rounding
    difference may land them on another attractor, or on the same one a
    period later. ``robust[precision]`` marks the steady points whose CPU run
    moves by less than the precision's tolerance when theta0 is offset by
    +- its offset (``PERTURBATIONS``): only there must the GPU reproduce the
    CPU point by point. ``kept[precision]`` is the fraction of steady points
    whose label both offsets keep: the GPU must keep as many. ``held[precision]``
    counts the robust points that an offset in another direction (thetadot0,
    not used to select them) leaves within the tolerance: a calibration of
    how many robust points rounding of that size still moves.
    """
    reason = cuda_unavailable_reason()
    if reason is not None:
        pytest.skip(f"no CUDA GPU: {reason}")
    rng = np.random.default_rng(16)
    n = 1024
    params = [
        TABLE_IV.replace(alpha=a, fe=fe) for a, fe in zip(rng.uniform(0, 45, n), rng.choice([2.0, 2.2, 2.5, 2.8], n))
    ]
    states = np.column_stack([np.zeros(n), np.zeros(n), rng.uniform(-0.5, 0.5, n), np.zeros(n)])
    cpu = run_batch(params, states, MANY_TRANSIENT, 30)
    labels = np.array(_labels(params, cpu, 1e-3))
    steady = np.array([lab.startswith(STEADY) for lab in labels])
    robust, kept, held = {}, {}, {}
    for precision, (offset, tol) in PERTURBATIONS.items():
        robust[precision], same = steady.copy(), steady.copy()
        for sign in (1.0, -1.0):
            moved = run_batch(params, states + [0.0, 0.0, sign * offset, 0.0], MANY_TRANSIENT, 30)
            robust[precision] &= _point_errors(moved.records, cpu.records) < tol
            same &= np.array(_labels(params, moved, 1e-3)) == labels
        kept[precision] = same.sum() / steady.sum()
        aside = run_batch(params, states + [0.0, 0.0, 0.0, offset], MANY_TRANSIENT, 30)
        held[precision] = int((_point_errors(aside.records, cpu.records)[robust[precision]] < tol).sum())
    assert robust["float64"].sum() > 200
    return params, states, cpu, labels, steady, robust, kept, held


def _compare(many_points, precision: str) -> dict:
    """The GPU run in ``precision`` against the CPU (see ``many_points``); the summary is printed."""
    params, states, cpu, labels, steady, robust, kept, held = many_points
    gpu = run_batch(params, states, MANY_TRANSIENT, 30, device="cuda", precision=precision)
    errors = _point_errors(gpu.records, cpu.records)
    gpu_labels = np.array(_labels([p for p, s in zip(params, steady) if s], _subset(gpu, steady), 1e-3))
    ok = robust[precision]
    summary = {
        "precision": precision,
        "points": len(params),
        "steady": int(steady.sum()),
        "robust": int(ok.sum()),
        "robust_largest_scaled_error": float(errors[ok].max()),
        "robust_median_scaled_error": float(np.median(errors[ok])),
        "robust_within_tolerance": int((errors[ok] < PERTURBATIONS[precision][1]).sum()),
        "robust_held_by_cpu_offset_aside": held[precision],
        "robust_same_labels": int((gpu_labels[ok[steady]] == labels[ok]).sum()),
        "steady_same_labels_fraction": float((gpu_labels == labels[steady]).mean()),
        "perturbed_cpu_same_labels_fraction": float(kept[precision]),
        "same_status": bool(gpu.status.tolist() == cpu.status.tolist()),
    }
    print(json.dumps(summary))
    return summary


@pytest.fixture
def gpu_launches(monkeypatch):
    """The number of points of each call of the GPU path, so that a test knows the GPU really ran."""
    import pendsweep.backends._batch as batch

    launches: list[int] = []
    real = batch.run_batch_cuda

    def counted(kernel_params, *args, **kwargs):
        launches.append(len(kernel_params))
        return real(kernel_params, *args, **kwargs)

    monkeypatch.setattr(batch, "run_batch_cuda", counted)
    return launches


@real_gpu_only
def test_real_gpu_matches_cpu_on_many_points(many_points):
    """float64 on the GPU reproduces the CPU kernel to rounding wherever rounding cannot move the point."""
    summary = _compare(many_points, "float64")
    assert summary["robust_largest_scaled_error"] < 1e-9
    assert summary["robust_same_labels"] == summary["robust"]
    assert summary["steady_same_labels_fraction"] >= summary["perturbed_cpu_same_labels_fraction"] - 0.02
    assert summary["same_status"]


@real_gpu_only
def test_real_gpu_float32_is_single_precision_rounding(many_points):
    """float32 on the GPU: far above float64's rounding, far below the motion; labels kept as often as a 1e-6 offset keeps them."""
    summary = _compare(many_points, "float32")
    assert 1e-8 < summary["robust_median_scaled_error"] < 1e-4
    # On the H200 one robust point of 345 still moved (1.45): a 1e-6 offset is not float32's whole rounding.
    # The GPU may move at most three more robust points than the CPU's offset aside does (fixed beforehand).
    assert summary["robust_within_tolerance"] >= summary["robust_held_by_cpu_offset_aside"] - 3
    assert summary["steady_same_labels_fraction"] >= summary["perturbed_cpu_same_labels_fraction"] - 0.02
    assert summary["same_status"]


@real_gpu_only
def test_real_gpu_divergence_and_status_codes(many_points):
    """Non-finite starts diverge at once on both devices: same codes, no periods done, NaN records."""
    params = [TABLE_IV.replace(alpha=a) for a in (5.0, 25.0, 45.0, 20.0, 20.0)]
    states = np.array([[0, 0, 0.1, 0], [0, 0, 0.5, 0], [0, 0, 1.0, 0], [np.nan, 0, 0.1, 0], [0, np.inf, 0.1, 0]])
    cpu = run_batch(params, states, 2, 3)
    gpu = run_batch(params, states, 2, 3, device="cuda")
    assert gpu.status.tolist() == cpu.status.tolist() == [STATUS_OK] * 3 + [STATUS_DIVERGED] * 2
    assert gpu.periods_done.tolist() == cpu.periods_done.tolist() == [5, 5, 5, 0, 0]
    assert np.isnan(gpu.records[3:]).all() and np.isfinite(gpu.records[:3]).all()


@real_gpu_only
def test_real_gpu_fig11a_sweep_matches_cpu(many_points, gpu_launches, tmp_path):
    """The Fig. 11(a) fresh sweep on the GPU: the CPU's labels, and its records wherever the motion is steady."""
    values = tuple(float(v) for v in np.arange(0.0, 45.01, 0.5))
    rows = {
        device: run_sweep(
            SweepConfig("alpha", values, mode="fresh", backend_options={"device": device}),
            tmp_path / f"{device}.parquet",
        ).sort_values(["point", "period"], ignore_index=True)
        for device in ("cpu", "cuda")
    }
    cpu, gpu = rows["cpu"], rows["cuda"]
    steady = cpu["motion"].str.startswith(STEADY).to_numpy()
    print(json.dumps({"fig11a_points": len(values), "steady_rows": int(steady.sum())}))
    assert steady.sum() > len(steady) // 2
    assert sum(gpu_launches) >= len(values)  # the cuda sweep did integrate on the GPU
    assert gpu["motion"][steady].tolist() == cpu["motion"][steady].tolist()
    for column in RECORD_COLUMNS:
        np.testing.assert_allclose(gpu[column][steady], cpu[column][steady], rtol=0, atol=1e-8, err_msg=column)


@real_gpu_only
def test_real_gpu_basins_command_matches_cpu(many_points, gpu_launches, tmp_path):
    """``pendsweep basins --device cuda`` gives the CPU's basin fractions; per start, it disagrees no more than rounding.

    At alpha = 40 N most starts pass through a chaotic transient: moving the
    grid by 1e-13 rad changes the attractor of about one start in eight on the
    CPU alone. That perturbed CPU run calibrates how often the GPU's own
    rounding may change a start's attractor.
    """
    import math

    from pendsweep.studies.basins import BasinConfig, run_basins

    frames = {}
    for device in ("cpu", "cuda"):
        out = tmp_path / f"{device}.parquet"
        args = ["basins", "--alpha", "40", "--fe", "2.5", "--grid", "40x40", "--max-periods", "300"]
        result = CliRunner().invoke(main, [*args, "--device", device, "--no-progress", "-o", str(out)])
        assert result.exit_code == 0, result.output
        frames[device] = pd.read_parquet(out, columns=["start", "motion"]).sort_values("start", ignore_index=True)
    shifted = BasinConfig(
        "alpha", (40.0,), {"fe": 2.5}, sampling="grid", grid=(40, 40), max_periods=300,
        theta_range=(-math.pi + 1e-13, math.pi + 1e-13),
    )  # fmt: skip
    frames["cpu_shifted"] = run_basins(shifted, None).sort_values("start", ignore_index=True)
    cpu, gpu, shifted = (frames[d]["motion"] for d in ("cpu", "cuda", "cpu_shifted"))
    agree_gpu, agree_shifted = float((gpu == cpu).mean()), float((shifted == cpu).mean())
    print(json.dumps({"basin_starts": len(cpu), "gpu_agreement": agree_gpu, "shifted_1e-13_agreement": agree_shifted}))
    assert sum(gpu_launches) >= len(cpu)  # the first round of every start ran on the GPU
    assert agree_shifted < 0.97  # the calibration is sensitive: rounding does change attractors here
    assert agree_gpu > agree_shifted - 0.03  # 0.03: about 2.5 standard deviations of the difference at 1600 starts
    for motion in ("periodic-2", "rotating"):
        assert abs((gpu == motion).mean() - (cpu == motion).mean()) < 0.02, motion


@real_gpu_only
def test_real_gpu_hopf_simulate_matches_cpu(many_points, gpu_launches):
    """The simulated Hopf amplitude, bisected on the GPU, is the CPU's to the bisection tolerance."""
    from pendsweep.studies.hopf import HopfConfig, run_hopf

    found = {
        device: run_hopf(
            HopfConfig(
                omega_hat=(0.95, 1.05), masses=(10.9,), methods=("simulate",), backend_options={"device": device}
            ),
            n_jobs=1,
        ).sort_values("omega_hat", ignore_index=True)
        for device in ("cpu", "cuda")
    }
    tol = HopfConfig(omega_hat=(1.0,)).tol
    print(
        json.dumps({"alpha_H_cpu": found["cpu"]["alpha_H"].tolist(), "alpha_H_gpu": found["cuda"]["alpha_H"].tolist()})
    )
    assert gpu_launches  # the bisection's batches ran on the GPU
    assert found["cuda"]["status"].tolist() == found["cpu"]["status"].tolist()
    np.testing.assert_allclose(found["cuda"]["alpha_H"], found["cpu"]["alpha_H"], rtol=0, atol=tol)


def _subset(run, mask):
    from pendsweep.backends._batch import BatchRun

    return BatchRun(*(a[mask] for a in run))
