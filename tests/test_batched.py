"""The batched (vectorised) emulated kernel against the scalar one, and its sin/cos."""

import numba as nb
import numpy as np
import pytest

from pendsweep.analysis.classify import classify_run
from pendsweep.backends import BackendBase, EmulatedBackend, PointRun
from pendsweep.backends._batch import batched_evidence, chunk_bounds, run_batch, run_lanes
from pendsweep.backends.status import Status
from pendsweep.bench.throughput import vector_instructions
from pendsweep.errors import ConfigError
from pendsweep.kernels import RECORD_COLUMNS, STATUS_DIVERGED, STATUS_OK
from pendsweep.kernels._batched import Lanes
from pendsweep.kernels._layout import SECTION_COLUMNS
from pendsweep.kernels._sincos import ROTATE_MAX_STEP, rotate_sincos, sincos_poly
from pendsweep.model.params import TABLE_IV


@nb.njit(cache=True, error_model="numpy")
def _sincos_array(x, s, c):
    for i in range(x.shape[0]):
        s[i], c[i] = sincos_poly(x[i])


def _errors(approx, x, fn):
    """``(|approx - f(x)|, ulp of the float64 result)`` against a long-double reference."""
    ref = fn(x.astype(np.longdouble))
    return np.abs(approx.astype(np.longdouble) - ref), np.spacing(np.abs(ref.astype(np.float64))).astype(np.longdouble)


def test_sincos_poly_accuracy_on_1e7_arguments():
    """Within 2 ulp of the result, plus 1e-26 |x| absolute next to the zeros.

    The zeros are where the two-piece Cody-Waite reduction shows: pi/2 is
    carried to about 3.5e-27 per multiple, far below the rounding of the
    argument itself (ulp(x) / 2 = 4e-16 at 2 pi). A kernel is affected only
    through absolute errors, which stay below 2**-52 everywhere.
    """
    assert np.finfo(np.longdouble).nmant >= 63, "needs x87 long double for an exact reference"
    rng = np.random.default_rng(7)
    # The pendulum angle (rewrapped every period, rotations within it), the
    # forcing phase, tiny angles near rest, and points next to multiples of pi/2.
    x = np.concatenate(
        [
            rng.uniform(-40 * np.pi, 40 * np.pi, 6_000_000),
            rng.uniform(0, 2 * np.pi, 2_000_000),
            rng.uniform(-1e-3, 1e-3, 1_000_000),
            np.resize(np.arange(-80, 81) * (np.pi / 2), 1_000_000) + rng.normal(0, 1e-9, 1_000_000),
        ]
    )
    x[:1000] = np.arange(1, 1001) * 100 * np.pi / 2  # and zeros far out, up to |x| = 1.6e5
    assert x.size == 10_000_000
    s = np.empty_like(x)
    c = np.empty_like(x)
    _sincos_array(x, s, c)
    for approx, fn in ((s, np.sin), (c, np.cos)):
        err, ulp = _errors(approx, x, fn)
        # Measured: at most 1.56 ulp (sin) and 1.55 ulp (cos) where |f| > 1e-3, and 0.78 * 2**-52 absolute.
        assert np.all(err <= 2 * ulp + 1e-26 * np.abs(x))
        assert err.max() <= np.spacing(1.0)


def test_sincos_poly_quadrants_and_nan():
    x = np.array([0.0, np.pi / 2, np.pi, 3 * np.pi / 2, -np.pi, 2 * np.pi, 1e5, np.nan])
    s = np.empty_like(x)
    c = np.empty_like(x)
    _sincos_array(x, s, c)
    # Zeros of sin/cos are reached only to the rounding of x itself (|x| ulp).
    tol = 2 * np.spacing(np.maximum(1.0, np.abs(x[:-1])))
    assert np.all(np.abs(s[:-1] - np.sin(x[:-1])) <= tol)
    assert np.all(np.abs(c[:-1] - np.cos(x[:-1])) <= tol)
    assert s[0] == 0.0 and c[0] == 1.0 and c[1] < 1e-16 and s[2] < 1e-15
    assert np.isnan(s[-1]) and np.isnan(c[-1])


@nb.njit(error_model="numpy")  # uncached: numba's cache would keep _sincos's constants of an earlier build
def _rotated_array(x, d, s_out, c_out):
    for i in range(d.shape[0]):
        s_out[i], c_out[i] = rotate_sincos(sincos_poly(x[i]), d[i])


def test_rotate_sincos_accuracy():
    """sin and cos of x + d as the batched step makes them: sincos_poly(x) rotated by d, |d| <= ROTATE_MAX_STEP.

    Measured against long double, in units of the larger of the result's ulp
    and the ulp of the angle's size (capped at 1): at most 2.6, where
    sincos_poly of the rounded stage angle x + d, the per-stage evaluation
    it replaces, is within 1.6 ulp of the result plus the half ulp of the
    angle's own rounding. Near a zero of sin or cos both are accurate in
    absolute terms only: the angle itself carries that rounding.
    """
    assert np.finfo(np.longdouble).nmant >= 63, "needs x87 long double for an exact reference"
    rng = np.random.default_rng(11)
    n = 500_000
    # (angle range, increment range): rotating through many turns, near pi, swinging, near rest, at rest.
    ranges = [(40 * np.pi, ROTATE_MAX_STEP), (np.pi, ROTATE_MAX_STEP), (1.0, 1e-2), (1e-3, 1e-4), (1e-8, 1e-9)]
    x = np.concatenate([rng.uniform(-a, a, n) for a, _ in ranges])
    d = np.concatenate([rng.uniform(-b, b, n) for _, b in ranges])
    d[:4] = [0.0, -0.0, ROTATE_MAX_STEP, -ROTATE_MAX_STEP]
    s_out, c_out = np.empty_like(x), np.empty_like(x)
    _rotated_array(x, d, s_out, c_out)
    exact = x.astype(np.longdouble) + d.astype(np.longdouble)
    angle_ulp = np.spacing(np.minimum(np.maximum(np.abs(x), np.abs(d)), 1.0)).astype(np.longdouble)
    for approx, fn in ((s_out, np.sin), (c_out, np.cos)):
        ref = fn(exact)
        err = np.abs(approx.astype(np.longdouble) - ref)
        unit = np.maximum(angle_ulp, np.spacing(np.abs(ref.astype(np.float64))).astype(np.longdouble))
        assert (err / unit).max() <= 3.0, fn.__name__
    # Ten times the limit the series is far off: the bound documented beside ROTATE_MAX_STEP holds only inside it.
    far = np.empty(1), np.empty(1)
    _rotated_array(np.zeros(1), np.array([10 * ROTATE_MAX_STEP]), *far)
    assert abs(far[0][0] - np.sin(1.0)) > 1e-9
    nan = np.empty(2), np.empty(2)
    _rotated_array(np.zeros(2), np.array([np.nan, np.inf]), *nan)
    assert np.isnan(nan[0]).all() and np.isnan(nan[1]).all()


def test_inner_loop_is_vectorised():
    """LLVM turns the per-point loop into packed AVX(-512) double arithmetic, with nothing left scalar in it."""
    counts = vector_instructions()
    assert counts["zmm_packed_double_ops"] + counts["ymm_packed_double_ops"] > 100, counts
    assert counts["scalar_double_ops"] == counts["scalar_conversions"] == 0, counts


def _scalar_runs(params, states, transient, record, signum="step"):
    backend = EmulatedBackend(signum=signum)
    return [backend.run_point(p, s, transient, record) for p, s in zip(params, states)]


def _motion(params, run, signum):
    return classify_run(EmulatedBackend(signum=signum), params, run).label


def _perturbed_labels(params, state, transient, record, signum, spread=12):
    """Labels the scalar (libm) kernel gives from ``theta0 + k 1e-15``, ``|k| <= spread``."""
    backend = EmulatedBackend(signum=signum)
    labels = set()
    for k in range(-spread, spread + 1):
        start = np.array(state, dtype=float) + [0.0, 0.0, k * 1e-15, 0.0]
        labels.add(_motion(params, backend.run_point(params, start, transient, record), signum))
    return labels


def _assert_close(a, b, rtol):
    """Relative agreement per column; values far below the column's scale compare at rtol * scale."""
    assert np.array_equal(np.isnan(a), np.isnan(b))
    scale = np.nanmax(np.abs(b), axis=0, keepdims=True) if np.isfinite(b).any() else 1.0
    err = np.abs(a - b) / np.maximum(np.abs(b), np.where(scale > 0, scale, 1.0))
    assert np.nanmax(err, initial=0.0) <= rtol, f"max relative difference {np.nanmax(err):.3g}"


def _compare(params, states, transient, record, rtol, chunk=64, signum="step"):
    """Batched vs scalar point by point: status, motion label (``pendsweep.analysis.classify``) and records.

    Records must agree to 1e-9 relative on semi-trivial and periodic points
    (or everywhere when ``rtol`` is given, for short horizons).
    """
    batch = run_batch(params, states, transient, record, chunk=chunk, signum=signum)
    scalar = _scalar_runs(params, states, transient, record, signum)
    labels = []
    for i, run in enumerate(scalar):
        assert Status.from_code(batch.status[i]) is run.status
        assert batch.periods_done[i] == run.periods_done
        mine = PointRun(batch.records[i], batch.states[i], run.status, run.periods_done)
        label = _motion(params[i], run, signum)
        if _motion(params[i], mine, signum) != label:
            # Allowed only where the exact kernel's own label is not robust: in
            # transient chaos, last-bit differences pick among outcomes.
            outcomes = _perturbed_labels(params[i], states[i], transient, record, signum)
            assert len(outcomes) > 1 and _motion(params[i], mine, signum) in outcomes, f"point {i}: {params[i]}"
        labels.append(label)
        if rtol is not None or label == "semi-trivial" or label.startswith("periodic"):
            _assert_close(batch.records[i], run.records, rtol or 1e-9)
            _assert_close(batch.states[i][None], run.state[None], rtol or 1e-9)
    return labels


def test_batched_matches_scalar_on_an_alpha_sweep():
    """Fig. 11(a) line (fe = 2.5 Hz): rest, periodic and rotating/chaotic points, 120 periods."""
    alphas = np.linspace(2.0, 45.0, 24)
    params = [TABLE_IV.replace(alpha=a) for a in alphas]
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
    labels = _compare(params, states, 100, 20, rtol=None, chunk=16)
    assert {"semi-trivial", "periodic-2"} <= set(labels), labels  # Hopf boundary near 16 N, then period 2
    # Points that are not periodic (chaotic, quasi-periodic, transient) diverge
    # from the scalar run by nature; over five periods they still agree.
    other = [p for p, c in zip(params, labels) if c != "semi-trivial" and not c.startswith("periodic")]
    assert other, labels
    _compare(other, np.tile([0.0, 0.0, 0.1, 0.0], (len(other), 1)), 0, 5, rtol=1e-9)


def test_batched_matches_scalar_with_mixed_frequencies_and_stage_signum():
    """Points with different steps per period share chunks (rotation-recurrence forcing)."""
    fes = np.linspace(2.2, 2.8, 12)
    params = [TABLE_IV.replace(alpha=a, fe=f) for a, f in zip(np.linspace(2, 34, 12), fes)]
    states = np.tile([0.0, 0.0, 0.1, 0.0], (12, 1))
    assert len(set(EmulatedBackend().steps_per_period(p) for p in params)) == 12
    for signum in ("step", "stage"):
        labels = _compare(params, states, 100, 20, rtol=None, chunk=8, signum=signum)
        assert "periodic-2" in labels, labels
        rng = np.random.default_rng(3)
        far = np.column_stack([np.zeros(12), np.zeros(12), rng.uniform(-3, 3, 12), rng.uniform(-5, 5, 12)])
        _compare(params, far, 0, 5, rtol=1e-9, chunk=8, signum=signum)


def test_diverging_point_gets_a_status_and_others_are_unaffected():
    params = [TABLE_IV, TABLE_IV.replace(K=1e9), TABLE_IV.replace(alpha=20.0)]
    states = np.tile([0.0, 0.0, 0.1, 0.0], (3, 1))
    batch = run_batch(params, states, 5, 3, chunk=4)
    scalar = _scalar_runs(params, states, 5, 3)
    assert list(batch.status) == [STATUS_OK, STATUS_DIVERGED, STATUS_OK]
    assert batch.periods_done[1] == scalar[1].periods_done < 8
    for i in (0, 2):
        np.testing.assert_allclose(batch.records[i], scalar[i].records, rtol=1e-9, atol=1e-12)
    alone = run_batch([params[2]], states[2:], 5, 3)
    np.testing.assert_array_equal(alone.records[0], batch.records[2])


def test_chunk_bounds_keep_equal_steps_together():
    steps = np.array([1, 2, 3] + [5] * 10 + [6, 7])
    assert chunk_bounds(steps, 4).tolist() == [0, 3, 7, 11, 13, 15]
    assert chunk_bounds(np.full(100, 400), 64).tolist() == [0, 64, 100]


def test_run_batch_rejects_bad_input():
    with pytest.raises(ConfigError, match="signum"):
        run_batch([TABLE_IV], np.zeros((1, 4)), 1, 1, signum="sometimes")
    with pytest.raises(ConfigError, match="record_periods"):
        run_batch([TABLE_IV], np.zeros((1, 4)), 1, 0)


def test_fresh_and_multistart_sweeps_use_the_batched_kernel(monkeypatch):
    from pendsweep.studies.sweep import SweepConfig, run_sweep

    calls = []
    original = EmulatedBackend.run_points

    def counting(self, params, states, transient_periods, *args, **kw):
        calls.append((len(params), transient_periods))
        return original(self, params, states, transient_periods, *args, **kw)

    monkeypatch.setattr(EmulatedBackend, "run_points", counting)
    config = SweepConfig(
        "alpha", (10.0, 20.0, 30.0), mode="multistart", starts=3, transient_periods=30, record_periods=4
    )
    df = run_sweep(config, task_points=4)
    # 9 units in tasks of 4 (the classifier's staged extensions, from the final states, come on top)
    assert [n for n, transient in calls if transient == 30] == [4, 4, 1]
    backend = EmulatedBackend()
    from pendsweep.studies.sweep import multistart_initials

    for (point, start), rows in df.groupby(["point", "start"]):
        params = config.params_at(config.values[point])
        ic = multistart_initials(config, point)[start]
        ref = backend.run_point(params, backend.initial_state(params, *ic), 30, 4)
        if rows["motion"].iloc[0] == "semi-trivial" or rows["motion"].iloc[0].startswith("periodic"):
            _assert_close(rows[list(RECORD_COLUMNS)].to_numpy(), ref.records, 1e-9)
    calls.clear()
    run_sweep(SweepConfig("alpha", (10.0, 20.0), transient_periods=5, record_periods=2))  # continue mode
    assert [n for n, transient in calls if transient != 0] == []  # its points go one by one; extensions batch


def test_bench_peers_integrate_the_same_equations():
    """The numpy RK4 peer of `make bench` lands on the batched kernel's state after one period."""
    from pendsweep.bench.throughput import numpy_rk4, peer_points

    params = peer_points(4, 2)
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
    peer = numpy_rk4(params, states, 400, 1.0 / (2.5 * 400))
    np.testing.assert_allclose(peer, run_batch(params, states, 0, 1).states, rtol=0, atol=1e-13)


class _ScalarOnly(EmulatedBackend):
    """The emulated backend without its batched kernel: the contract's per-point fallback."""

    batched = False
    run_points = BackendBase.run_points


def test_hopf_simulate_rows_run_batched_in_lockstep_and_match_the_scalar_kernel(monkeypatch):
    from pendsweep.studies.hopf import HopfConfig, hopf_simulate, hopf_simulate_rows

    calls = []
    original = EmulatedBackend.run_points
    monkeypatch.setattr(
        EmulatedBackend, "run_points", lambda self, ps, *a, **k: calls.append(len(ps)) or original(self, ps, *a, **k)
    )
    config = HopfConfig(omega_hat=(0.95, 1.0, 1.05), methods=("simulate",), periods=120, tol=0.5)
    rows = [r.iloc[0] for r in hopf_simulate_rows(config, [(0, 0), (0, 1), (0, 2)])]
    assert calls[0] == 3  # the three bisections share every kernel call
    for i, row in enumerate(rows):
        ref = hopf_simulate(
            config.params_at(i, 0),
            _ScalarOnly(),
            kick=config.kick,
            periods=config.periods,
            settle_periods=config.settle_periods,
            tol=config.tol,
            alpha_max=config.alpha_max,
        )
        assert row["status"] == ref["status"] == "ok" and row["runs"] == ref["runs"]
        assert row["alpha_H"] == ref["alpha_H"]  # the same bisection decisions
        assert row["growth_above"] == pytest.approx(ref["growth_above"], rel=1e-6)
        assert row["growth_below"] == pytest.approx(ref["growth_below"], rel=1e-6)


def test_concurrent_batches_from_threads_equal_sequential_ones():
    """Hopf and sweep tasks may call the batched kernel from several threads at once."""
    from concurrent.futures import ThreadPoolExecutor

    batches = [[TABLE_IV.replace(alpha=a) for a in np.linspace(lo, lo + 10, 24)] for lo in (5.0, 25.0)]
    states = np.tile([0.0, 0.0, 0.1, 0.0], (24, 1))
    sequential = [run_batch(b, states, 3, 2).records for b in batches]
    with ThreadPoolExecutor(2) as pool:
        concurrent = list(pool.map(lambda b: run_batch(b, states, 3, 2).records, batches))
    for a, b in zip(sequential, concurrent):
        np.testing.assert_array_equal(a, b)


def test_a_point_does_not_depend_on_its_chunk_neighbours():
    """Bit-identical records alone, among equal-fe points, among other fe, at other positions.

    This is what makes a resumed sweep identical to an uninterrupted one: which
    other points share a launch depends on what was already done. A chunk of 64
    lanes runs in the vectorised loop body; a point alone runs in the scalar
    remainder loop, so the two must compute the same operations.
    """
    rng = np.random.default_rng(1)
    params = [
        TABLE_IV.replace(alpha=a, fe=f) for a, f in zip(np.linspace(36, 42, 64), np.tile([2.5, 2.5, 2.3, 2.7], 16))
    ]
    states = np.column_stack([np.zeros(64), np.zeros(64), rng.uniform(-np.pi, np.pi, 64), rng.uniform(-7, 7, 64)])
    together = run_batch(params, states, 40, 6, chunk=64)
    for i in (0, 1, 5, 37, 63):  # chaotic and rotating starts at 36-42 N amplify any difference
        alone = run_batch([params[i]], states[i : i + 1], 40, 6)
        np.testing.assert_array_equal(alone.records[0], together.records[i])
        np.testing.assert_array_equal(alone.states[0], together.states[i])


@pytest.mark.parametrize("signum", ["step", "stage"])
def test_fast_arithmetic_stays_far_below_rk4_truncation_error(signum):
    """Polynomial sin/cos, reciprocals and FMA against the exact-libm kernel, 120 periods.

    On non-chaotic points the batched kernel's departure from the scalar
    (libm, no contraction) kernel is compared with RK4's own error at
    dt = 1 ms, estimated by the same scalar kernel at dt = 0.5 ms. Measured:
    the ratio is 1e-11 to 1e-9 (departures of 1e-15 to 1e-14 against
    truncation errors of 3e-6 to 2e-4 in the records).
    """
    params = [TABLE_IV.replace(alpha=a) for a in (5.0, 26.0)] + [TABLE_IV.replace(alpha=15.0, fe=2.4)]
    states = np.tile([0.0, 0.0, 0.1, 0.0], (len(params), 1))
    fast = run_batch(params, states, 100, 20, signum=signum)
    exact, fine = EmulatedBackend(signum=signum), EmulatedBackend(dt=5e-4, signum=signum)
    for i, p in enumerate(params):
        reference = exact.run_point(p, states[i], 100, 20)
        assert classify_run(exact, p, reference).label in {"semi-trivial", "periodic-2"}
        departure = np.abs(fast.records[i][:, SECTION_COLUMNS] - reference.records[:, SECTION_COLUMNS]).max()
        halved = fine.run_point(p, states[i], 100, 20).records[:, SECTION_COLUMNS]
        truncation = np.abs(halved - reference.records[:, SECTION_COLUMNS]).max()
        assert truncation > 1e-7, "the dt/2 run must resolve RK4's error"
        assert departure <= 1e-6 * truncation, f"{p.alpha} N: {departure:.3g} against {truncation:.3g}"


@pytest.mark.parametrize("alpha", [38.0, 40.0])
def test_fast_arithmetic_on_rotating_orbits(alpha):
    """Rotating orbits move theta by up to 0.02 rad per RK4 stage (20 rad/s), the stage sin/cos's largest rotations.

    From a state on the orbit (100 periods of the exact kernel), 120 periods
    of the batched kernel against the exact-libm kernel, compared with RK4's
    truncation error (dt/2 run) over the same periods. Measured: 3e-6 of it
    (1e-12 against 1e-7 to 3e-7); the per-stage sin/cos the kernel used
    before measured 2e-6 to 3e-6: the bits lost rewrapping theta every period dominate.
    """
    p = TABLE_IV.replace(alpha=alpha)
    exact, fine = EmulatedBackend(), EmulatedBackend(dt=5e-4)
    on_orbit = exact.run_point(p, np.array([0.0, 0.0, 0.1, 0.0]), 100, 1).state
    reference = exact.run_point(p, on_orbit, 0, 120)
    assert np.all(np.abs(reference.records[:, RECORD_COLUMNS.index("rotations")]) == 1)
    assert np.abs(reference.records[:, RECORD_COLUMNS.index("thetadot_sec")]).max() > 15.0  # rad/s
    fast = run_batch([p], on_orbit[None], 0, 120)
    halved = fine.run_point(p, on_orbit, 0, 120).records[:, SECTION_COLUMNS]
    departure = np.abs(fast.records[0][:, SECTION_COLUMNS] - reference.records[:, SECTION_COLUMNS]).max()
    truncation = np.abs(halved - reference.records[:, SECTION_COLUMNS]).max()
    assert truncation > 1e-8, "the dt/2 run must resolve RK4's error"
    assert departure <= 1e-5 * truncation, f"{alpha} N: {departure:.3g} against {truncation:.3g}"


def test_evidence_whose_lyapunov_run_outlasts_the_extension():
    """The Lyapunov pair may run longer than the extension (a record over 200 periods).

    It records nothing, so the records array (sized by the extension) is
    never written past its end; its stretch samples do not depend on the
    extension's length.
    """
    params = [TABLE_IV.replace(alpha=a) for a in (38.0, 41.0)]
    finals = np.array([[0.0, 0.0, 0.4, 1.0], [0.0, 0.0, -0.3, 2.0]])
    scales = np.ones((2, 4))
    kw = dict(lyapunov_periods=40, d0=1e-8, rest=1e-3)
    short = batched_evidence(params, finals, finals, scales, extend_periods=30, **kw)
    long = batched_evidence(params, finals, finals, scales, extend_periods=60, **kw)
    for (sections_short, stretch_short), (sections_long, stretch_long) in zip(short, long):
        assert sections_short.shape == (30, 4) and sections_long.shape == (60, 4)
        np.testing.assert_array_equal(sections_short, sections_long[:30])
        assert len(stretch_short) == 40
        np.testing.assert_array_equal(stretch_short, stretch_long)


def test_run_lanes_refuses_a_schedule_longer_than_its_arrays():
    params = [TABLE_IV] * 2
    states = np.tile([0.0, 0.0, 0.1, 0.0], (2, 1))
    lanes = Lanes(
        transient=np.zeros(2, dtype=np.int64),
        total=np.array([5, 5]),
        partner=np.array([-1, 0]),
        scales=np.ones((4, 2)),
        d0=1e-8,
        rest=0.0,
    )
    with pytest.raises(ValueError, match="record_periods"):
        run_lanes(params, states, lanes, 4, 5)
    with pytest.raises(ValueError, match="stretch_periods"):
        run_lanes(params, states, lanes, 5, 4)
    run, stretch = run_lanes(params, states, lanes, 5, 5)
    assert run.records.shape == (2, 5, 8) and stretch.shape == (2, 5)


def test_parameter_columns_are_the_parameter_sets_and_know_their_step():
    """Columns built once give what the sets give; zero points give empty runs; another dt is refused."""
    from pendsweep.backends._batch import parameter_columns

    shared = TABLE_IV.replace(alpha=20.0, fe=2.2)
    params = [shared, TABLE_IV.replace(alpha=30.0), shared, TABLE_IV.replace(alpha=20.0, fe=2.2)]
    states = np.tile([0.0, 0.0, 0.3, 0.0], (len(params), 1))
    by_sets = run_batch(params, states, 2, 3)
    by_columns = run_batch(parameter_columns(params, 1e-3), states, 2, 3)
    for a, b in zip(by_sets, by_columns):
        np.testing.assert_array_equal(a, b)
    # Against each point integrated alone (no sharing of a column row to get wrong): the same records.
    for i, q in enumerate(params):
        alone = run_batch([q], states[i : i + 1], 2, 3)
        np.testing.assert_array_equal(alone.records[0], by_columns.records[i])
    assert parameter_columns(params, 1e-3).steps.tolist() == [455, 400, 455, 455]
    empty = run_batch([], np.empty((0, 4)), 2, 3)
    assert [a.shape for a in empty] == [(0, 3, 8), (0, 4), (0,), (0,)]
    with pytest.raises(ConfigError, match="dt"):
        run_batch(parameter_columns(params, 2e-3), states, 2, 3)
