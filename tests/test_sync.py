"""Synchronisation metrics on signals with known answers, and the trace/sync commands."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from pendsweep.cli import main
from pendsweep.errors import ConfigError
from pendsweep.hybrid.sync import (
    DYNAMICS_BAND,
    analyse,
    error_psd,
    online_delay,
    psd_peak,
    sync_ratio,
    tracking_indices,
    xcorr_delay,
)
from pendsweep.hybrid.trace import read_trace

DT = 1e-3
W = 2 * np.pi * 2.2


def _delayed(tau: float, seconds: float = 10.0, phase: float = 0.4):
    t = np.arange(int(seconds / DT)) * DT
    return t, 0.018 * np.sin(W * t + phase), 0.018 * np.sin(W * (t - tau) + phase)


@pytest.mark.parametrize("tau", [0.0, 0.0037, 0.018, -0.005])
def test_indices_of_a_delayed_sinusoid(tau):
    t, y, x = _delayed(tau)
    idx = tracking_indices(y, x, DT)
    assert idx.J1 == pytest.approx(tau, abs=2e-6)
    # e = y - x has amplitude 2 A sin(w tau / 2): J2 (rms) and J3 (peak) both equal it in %.
    expected = 200 * abs(np.sin(W * tau / 2))
    assert idx.J2 == pytest.approx(expected, rel=1e-3, abs=1e-9)
    assert idx.J3 == pytest.approx(expected, rel=2e-3, abs=1e-9)
    assert sync_ratio(y, x) == idx.J3


def test_online_delay_follows_a_change_of_delay():
    t, y, x1 = _delayed(0.010, 6.0)
    _, _, x2 = _delayed(0.020, 6.0)
    x = np.where(t < 3.0, x1, x2)
    est = online_delay(y, x, DT, window=1.0, every=0.25)
    early = est[est["t"] < 2.9]["delay"]
    late = est[est["t"] > 4.1]["delay"]
    # 1 s windows hold 2.2 periods only; the estimate must still be unbiased
    assert np.allclose(early, 0.010, atol=2e-6) and np.allclose(late, 0.020, atol=2e-6)
    assert est["t"].max() <= t[-1] + 1e-12  # causal: windows end inside the record


def test_error_psd_peaks_at_the_error_frequency():
    t, y, x = _delayed(0.018)
    f, pxx = error_psd(y - x, DT)
    assert f[np.argmax(pxx)] == pytest.approx(2.2, abs=0.1)
    assert xcorr_delay(y, x, DT) > 0  # x lags


def test_psd_peaks_tell_a_tone_in_the_band_from_noise_above_it():
    t = np.arange(20_000) * DT
    error = 1e-4 * np.sin(W * t) + np.random.default_rng(1).normal(0.0, 2e-5, t.size)
    f, pxx = error_psd(error, DT)
    tone = psd_peak(f, pxx, 0.0, DYNAMICS_BAND)
    noise = psd_peak(f, pxx, DYNAMICS_BAND, f[-1])
    assert tone.frequency == pytest.approx(2.2, abs=0.1) and tone.level_db > 30
    assert DYNAMICS_BAND < noise.frequency <= f[-1] and noise.level_db < 10  # white noise: no tone stands out
    assert psd_peak(f, pxx, f[-1], f[-1] + 1.0) is None  # nothing above Nyquist


def test_bad_signals_are_config_errors():
    with pytest.raises(ConfigError):
        sync_ratio([1.0, 2.0, 3.0], [1.0, 2.0])
    with pytest.raises(ConfigError):
        sync_ratio([1.0, np.nan, 3.0], [1.0, 2.0, 3.0])


def test_trace_and_sync_commands(tmp_path):
    runner = CliRunner()
    out = tmp_path / "po.parquet"
    res = runner.invoke(main, ["trace", str(out), "--periods", "5", "--transient-periods", "5", "-B", "seed=3"])
    assert res.exit_code == 0, res.output
    df, meta = read_trace(out)
    assert {"t", "Fe", "y", "command", "x", "x_meas", "theta", "theta_true", "Fs", "Fs_true", "sync_error"} <= set(
        df.columns
    )
    assert meta["backend_options"]["seed"] == 3 and meta["status"] == "ok"
    assert meta["effective_delay_s"] == pytest.approx(0.01794, abs=1e-5)
    fig = tmp_path / "sync.png"
    res = runner.invoke(main, ["sync", str(out), "-o", str(fig), "--reference", "PO"])
    assert res.exit_code == 0, res.output
    assert "Table I ratio" in res.output and "paper, Table I PO" in res.output and fig.stat().st_size > 0
    delays = pd.read_csv(tmp_path / "sync_delay.csv")
    assert list(delays.columns) == ["t", "delay"] and len(delays) > 10
    report = analyse(df)
    assert f"{report.ratio:.2f} %" in res.output
    assert "error PSD peak       2.200 Hz in 0-20 Hz" in res.output  # the delay's tone, at the forcing frequency
    assert "error PSD HF peak" in res.output


@pytest.mark.parametrize(
    "args",
    [
        ["trace", "x.parquet", "--M", "0.5"],
        ["trace", "x.parquet", "-B", "actuator=hydraulic"],
        ["trace", "x.parquet", "-B", "nonsense=1"],
        ["trace", "x.parquet", "--set", "M1"],
        ["trace", "x.parquet", "--alpha", "nan"],
        ["sync", "missing.parquet"],
    ],
)
def test_bad_input_exits_2(tmp_path, args):
    res = CliRunner().invoke(main, [str(tmp_path / a) if a.endswith(".parquet") else a for a in args])
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output


def test_sync_rejects_an_emulated_trace(tmp_path):
    out = tmp_path / "emu.parquet"
    runner = CliRunner()
    assert (
        runner.invoke(
            main, ["trace", str(out), "--backend", "emulated", "--periods", "2", "--transient-periods", "0"]
        ).exit_code
        == 0
    )
    res = runner.invoke(main, ["sync", str(out)])
    assert res.exit_code == 2 and "substructured" in res.output
    assert isinstance(read_trace(out)[0], pd.DataFrame)


def test_hybrid_figures_quick(tmp_path):
    from pendsweep.figures import make_figures

    paths = make_figures(["fig9_hybrid", "fig11_hybrid", "fig12_sync"], tmp_path, quick=True)
    assert all(p.stat().st_size > 0 for p in paths)
    table = pd.read_csv(tmp_path / "table1_sync.csv")
    assert set(table["motion"]) == {"PO", "CO"} and len(table) == 4
    predicted = table[table["prediction"] != "none"]
    assert (predicted["ratio_percent"] < 5.0).all()
    assert (predicted["paper_ratio_percent"] == 3.9).all()
