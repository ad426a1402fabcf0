"""Many emulated points on a CUDA GPU: device discovery and the host side of the GPU kernel.

:func:`run_batch_cuda` is what :func:`pendsweep.backends._batch.run_batch` calls for
``device="cuda"``: it groups the points by steps per forcing period (so that
the threads of a warp share a forcing table and reach their period ends
together), builds one unit forcing table per distinct step count, launches
:func:`pendsweep.kernels._cuda.emulated_kernel` one thread per point, and
returns the same :class:`~pendsweep.backends._batch.BatchRun` as the CPU path.

The GPU dependencies are an extra (``pip install 'pendsweep[cuda]'``); with
``NUMBA_ENABLE_CUDASIM=1`` in the environment, numba's CUDA simulator runs
the same kernel in Python (slowly), which is how the tests run without a GPU.
"""

from __future__ import annotations

import functools
import threading

import numpy as np

from ..errors import ConfigError
from ..kernels import N_RECORD_COLUMNS, forcing_table
from ..kernels._cuda import PRECISIONS, emulated_kernel, import_cuda

#: Threads per block of the kernel launch.
THREADS_PER_BLOCK = 128
#: Points per launch at most, bounding device memory (records: 64 bytes per point and recorded period).
MAX_POINTS_PER_LAUNCH = 1 << 20
#: Points per batch that callers hand a GPU at least (sweeps raise their task size to it).
GPU_BATCH_POINTS = 1 << 17
#: The devices a batched run accepts.
DEVICES = ("cpu", "cuda")

_LAUNCH = threading.Lock()


@functools.cache
def cuda_unavailable_reason() -> str | None:
    """Why no CUDA GPU can be used here (one line), or None when one can."""
    try:
        cuda = import_cuda()
    except Exception as exc:  # ImportError, or a driver/toolkit error raised while importing
        return f"numba.cuda cannot be imported ({_one_line(exc)})"
    try:
        if cuda.is_available():
            return None
        cuda.get_current_device()  # not available: this raises numba's reason (no driver, no device)
    except Exception as exc:
        return _one_line(exc)
    return "no CUDA device found"


def _one_line(exc: BaseException) -> str:
    """The first sentence of an exception's message, on one line."""
    text = " ".join(str(exc).split()).strip(" :")
    return text.split(". ")[0].rstrip(".") or type(exc).__name__


def require_cuda() -> None:
    """Raise :class:`ConfigError` (exit 2 on the CLI) when no CUDA GPU can be used."""
    reason = cuda_unavailable_reason()
    if reason is not None:
        raise ConfigError(
            f"device = 'cuda' but no usable CUDA GPU: {reason}; use device 'cpu', or "
            "pip install 'pendsweep[cuda]' on a machine with an NVIDIA GPU and driver"
        )


def check_device(device: str, precision: str) -> None:
    """Validate a ``device``/``precision`` pair (raises :class:`ConfigError`); does not look for a GPU."""
    if device not in DEVICES:
        raise ConfigError(f"device = {device!r}; choose one of {', '.join(DEVICES)}")
    if precision not in PRECISIONS:
        raise ConfigError(f"precision = {precision!r}; choose one of {', '.join(PRECISIONS)}")
    if device == "cpu" and precision != "float64":
        raise ConfigError(f"precision = {precision!r} needs device 'cuda' (the CPU kernels are float64 only)")


def with_device(backend: str, backend_options: dict, device: str | None) -> dict:
    """``backend_options`` with the CLI's ``--device`` added (None: leave them as they are).

    Raises :class:`ConfigError` when the backend has no device option, or
    when ``device`` is ``"cuda"`` and no CUDA GPU is usable, so that the
    command stops before any work.
    """
    if device is None or (device == "cpu" and backend != "emulated"):
        return backend_options
    if backend != "emulated":
        raise ConfigError(f"--device {device} applies to the emulated backend only, not {backend!r}")
    if device == "cuda":
        require_cuda()
    return {**backend_options, "device": device}


def device_name() -> str:
    """Name of the current CUDA device (requires one)."""
    name = import_cuda().get_current_device().name
    return name.decode() if isinstance(name, bytes) else str(name)


def run_batch_cuda(
    kernel_params: np.ndarray,
    alpha: np.ndarray,
    fe: np.ndarray,
    steps: np.ndarray,
    states: np.ndarray,
    transient_periods: int,
    record_periods: int,
    *,
    sgn_per_stage: bool = False,
    precision: str = "float64",
):
    """Integrate ``n`` independent points on the GPU; arguments already validated by ``run_batch``.

    Parameters
    ----------
    kernel_params : float64[n, N_PARAMS]
        ``ModelParams.kernel_array()`` per point.
    alpha, fe : float64[n]
        Forcing amplitude [N] and frequency [Hz] per point.
    steps : int64[n]
        RK4 steps per forcing period; each point's step is ``1 / (fe * steps)`` [s].
    states : float64[n, 4]
        Initial ``(y [m], ydot [m/s], theta [rad], thetadot [rad/s])``.
    transient_periods, record_periods : int
        Forcing periods discarded, then recorded.
    sgn_per_stage : bool
        Evaluate sgn(thetadot) at every RK4 stage.
    precision : {"float64", "float32"}
        Arithmetic on the device; results are float64 either way.

    Returns
    -------
    records : float64[n, record_periods, 8]
    states : float64[n, 4]
    status, periods_done : int64[n]
        In the order of the inputs (the fields of
        :class:`pendsweep.backends._batch.BatchRun`, which wraps them: this
        module does not import the backends, which import it).
    """
    require_cuda()
    cuda = import_cuda()
    real = PRECISIONS[precision]
    kernel = emulated_kernel(precision, bool(sgn_per_stage))
    n = len(steps)
    # Sorted by steps per period; a basin map's single step count is sorted already and skips the copies.
    order = None if np.all(steps[1:] >= steps[:-1]) else np.argsort(steps, kind="stable")
    sorted_steps = np.ascontiguousarray(steps if order is None else steps[order], dtype=np.int64)
    # One unit forcing table per distinct step count, as in the CPU kernels.
    distinct, first = np.unique(sorted_steps, return_inverse=True)
    offsets = np.concatenate([[0], np.cumsum(2 * distinct + 1)])
    table = np.concatenate([forcing_table(1.0, int(s)) for s in distinct]).astype(real)
    table_start = np.ascontiguousarray(offsets[:-1][first], dtype=np.int64)

    def in_order(values: np.ndarray, dtype) -> np.ndarray:
        return np.ascontiguousarray(values if order is None else values[order], dtype=dtype)

    dt = (1.0 / (in_order(fe, np.float64) * sorted_steps)).astype(real)
    p = in_order(kernel_params, real)
    a = in_order(alpha, real)
    z = np.array(states if order is None else states[order], dtype=real, order="C")  # a copy: the kernel writes it
    records = np.full((n, int(record_periods), N_RECORD_COLUMNS), np.nan)
    status = np.zeros(n, dtype=np.int64)
    done = np.zeros(n, dtype=np.int64)
    with _LAUNCH:
        d_table = cuda.to_device(table)
        for lo in range(0, n, MAX_POINTS_PER_LAUNCH):
            hi = min(n, lo + MAX_POINTS_PER_LAUNCH)
            d_state = cuda.to_device(z[lo:hi])
            d_out = cuda.to_device(records[lo:hi])
            d_status = cuda.to_device(status[lo:hi])
            d_done = cuda.to_device(done[lo:hi])
            blocks = (hi - lo + THREADS_PER_BLOCK - 1) // THREADS_PER_BLOCK
            kernel[blocks, THREADS_PER_BLOCK](
                d_state, cuda.to_device(p[lo:hi]), cuda.to_device(a[lo:hi]), cuda.to_device(dt[lo:hi]),
                cuda.to_device(sorted_steps[lo:hi]), cuda.to_device(table_start[lo:hi]), d_table,
                int(transient_periods), d_out, d_status, d_done,
            )  # fmt: skip
            for device_array, host in ((d_state, z), (d_out, records), (d_status, status), (d_done, done)):
                device_array.copy_to_host(host[lo:hi])  # into the host array: no temporary of each
    if order is None:
        return records, z.astype(np.float64, copy=False), status, done
    out = (np.empty_like(records), np.empty((n, 4)), np.empty_like(status), np.empty_like(done))
    for target, source in zip(out, (records, z, status, done)):
        target[order] = source
    return out
