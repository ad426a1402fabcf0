"""Hybrid-test figures: Fig. 9, Fig. 11 and Fig. 12, substructured against emulated.

All substructured runs use the backend's defaults (servo with about 18 ms of
total delay, paper-level noise, first-order 5-point prediction with
``tau_hat`` = the total delay) from the rest state ``(0, 0, 0.1, 0)``.

Lengths and delays are drawn in the unit that suits them (mm, um, ms): tick
labels of ``0.005 m`` steps would run into each other.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.ticker import MaxNLocator

from ..backends import make_backend
from ..canvas import new_figure
from ..hybrid.sync import DYNAMICS_BAND, TABLE_I, SyncReport, error_psd, sync_ratio
from ..hybrid.trace import run_trace
from ..model.params import FIG9_CO, FIG9_PO, ModelParams
from ..studies.sweep import run_sweep, sweep_metadata
from ..studies.sweepfile import SWEEPS_DIR, load_sweep
from .plotting import draw_bifurcation
from .registry import figure

INITIAL = (0.0, 0.0, 0.1, 0.0)
CASES = {"PO": FIG9_PO, "CO": FIG9_CO}
#: Display units of an SI quantity: (factor applied to the SI value, prefix), the largest unit first.
PREFIXES = ((1.0, ""), (1e3, "m"), (1e6, "\u00b5"))


def display_unit(values, si: str) -> tuple[float, str]:
    """The largest unit (``si``, milli, micro) in which the largest ``|values|`` is at least 0.1: (factor, name).

    A platform moving 18 mm reads 5, 10, 15 mm; an error of 0.7 mm stays in
    mm, one of 85 um reads in um; a delay of 0.47 ms in ms.
    """
    largest = float(np.nanmax(np.abs(np.asarray(values, dtype=float)), initial=0.0))
    for factor, prefix in PREFIXES:
        if largest * factor >= 0.1:
            return factor, prefix + si
    factor, prefix = PREFIXES[-1]
    return factor, prefix + si


def _draw_subspace(ax, y_star: pd.Series, x: pd.Series) -> None:
    """Measured ``x`` against target ``y*`` with the sync subspace ``x = y*``, both in one unit, square."""
    scale, unit = display_unit(y_star, "m")
    lim = 1.05 * scale * y_star.abs().max()
    ax.plot(scale * y_star, scale * x, "k-", lw=0.6)
    ax.plot([-lim, lim], [-lim, lim], "r--", lw=0.8, label="x = y* (sync subspace)")
    ax.set(xlabel=f"target y* [{unit}]", ylabel=f"measured x [{unit}]")
    ax.set_aspect("equal")
    for axis in (ax.xaxis, ax.yaxis):  # a square panel: few ticks, on round steps
        axis.set_major_locator(MaxNLocator(nbins=5, steps=[1, 2, 5, 10]))


def _periods(params: ModelParams, seconds: float) -> int:
    return max(1, int(round(seconds * params.fe)))


def hybrid_pair(params: ModelParams, quick: bool, **options) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Substructured and emulated traces of 10 s (2 s when quick) after 100 (10) periods."""
    transient = 10 if quick else 100
    periods = _periods(params, 2.0 if quick else 10.0)
    sub = run_trace(make_backend("substructured", **options), params, INITIAL, transient, periods)
    emu = run_trace(make_backend("emulated"), params, INITIAL, transient, periods)
    return sub, emu


@figure("fig9_hybrid")
def fig9_hybrid(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 9: PO and CO time series, substructured (solid) against emulated (dashed)."""
    fig = new_figure((11, 6), layout=None)
    axes = fig.subplots(2, 2, sharex=True)
    for col, (label, params) in enumerate(CASES.items()):
        sub, emu = hybrid_pair(params, quick)
        ax_y, ax_t = axes[0, col], axes[1, col]
        scale, unit = display_unit(emu["y"], "m")
        ax_y.plot(sub["t"], scale * sub["y"], "k-", lw=1.0, label="substructured y*")
        ax_y.plot(emu["t"], scale * emu["y"], "r--", lw=1.0, label="emulated y")
        ax_t.plot(sub["t"], sub["theta"], "k-", lw=1.0, label=r"substructured $\theta_x$")
        ax_t.plot(emu["t"], emu["theta"], "r--", lw=1.0, label=r"emulated $\theta$")
        ax_y.set_title(f"({'ab'[col]}) {label}: alpha = {params.alpha:g} N, fe = {params.fe:g} Hz")
        ax_y.set_ylabel(f"displacement [{unit}]")
        ax_t.set_ylabel("angle [rad]")
        ax_t.set_xlabel("time after the transient [s]")
    # one legend for the four panels, under them: the time series fill every panel
    handles = axes[0, 0].get_legend_handles_labels()[0] + axes[1, 0].get_legend_handles_labels()[0]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    path = outdir / "fig9_hybrid.png"
    fig.savefig(path, dpi=120)
    return [path]


def _hybrid_sweeps(name: str, quick: bool):
    """The built-in sweep ``<name>`` (``pendsweep run --list``) run with the emulated and the substructured backend.

    The substructured sweep skips values with ``M <= M2`` (no numerical mass left).
    """
    config = load_sweep(SWEEPS_DIR / f"{name}.toml").config
    if quick:
        config = replace(config, values=config.values[::10], transient_periods=10, record_periods=5)
    out = {}
    for backend in ("substructured", "emulated"):
        values = config.values
        if backend == "substructured" and config.parameter == "M":
            values = tuple(v for v in values if v > config.base_params.M2)
        cfg = replace(config, backend=backend, backend_options={}, values=values)
        out[backend] = (run_sweep(cfg, None, n_jobs=1), sweep_metadata(cfg))
    return out


@figure("fig11_hybrid")
def fig11_hybrid(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 11 (a1)/(a2) and (b1)/(b2): theta peaks, substructured (theta_x) and emulated, side by side.

    Below M ~ 4 kg (mass ratio (M2 + m)/M1 > 0.38) the default substructured loop
    trips; those points are marked as unstable (see docs/substructured.md).
    """
    fig = new_figure((12, 8), layout=None)
    axes = fig.subplots(2, 2, sharey=True)
    for row, name in enumerate(("fig11a", "fig11b")):
        for col, (backend, result) in enumerate(_hybrid_sweeps(name, quick).items()):
            ax = axes[row, col]
            draw_bifurcation(ax, [result])
            ax.set_title(f"({'ab'[row]}{col + 1}) {backend}, fe = 2.5 Hz", fontsize=9)
            if col == 0:
                ax.set_ylabel(r"$\theta_{x}$ peaks [rad] (encoder)")
    fig.tight_layout()
    path = outdir / "fig11_hybrid.png"
    fig.savefig(path, dpi=120)
    return [path]


def table_i_rows(quick: bool) -> tuple[pd.DataFrame, dict[str, pd.DataFrame]]:
    """Table I from simulated PO and CO tests, with and without prediction, next to the paper's.

    Returns the table and the default (predicted) substructured traces by motion.
    """
    rows = []
    traces = {}
    for label, params in CASES.items():
        for predictor, opts in (("1st order, 5 points", {}), ("none", {"predictor_order": -1})):
            sub, _ = hybrid_pair(params, quick, **opts)
            traces.setdefault(label, sub)
            e = (sub["y"] - sub["x_meas"]).abs().max()
            paper = TABLE_I[label] if predictor != "none" else (np.nan, np.nan, np.nan)  # the paper predicted
            rows.append(
                {
                    "motion": label,
                    "prediction": predictor,
                    "max_sync_error_m": e,
                    "max_target_m": sub["y"].abs().max(),
                    "ratio_percent": sync_ratio(sub["y"], sub["x_meas"]),
                    "paper_max_error_m": paper[0],
                    "paper_max_target_m": paper[1],
                    "paper_ratio_percent": paper[2],
                }
            )
    return pd.DataFrame(rows), traces


def _table_text(table: pd.DataFrame) -> str:
    lines = ["Table I      prediction            max err [m]  max y* [m]  ratio   | paper: err [m], y* [m], ratio"]
    for r in table.itertuples():
        paper = (
            "(the paper's tests all used prediction)"
            if np.isnan(r.paper_ratio_percent)
            else f"{r.paper_max_error_m}, {r.paper_max_target_m}, {r.paper_ratio_percent} %"
        )
        lines.append(
            f"{r.motion:<12} {r.prediction:<20} {r.max_sync_error_m:>10.4f}  {r.max_target_m:>10.4f}  "
            f"{r.ratio_percent:5.2f} % | {paper}"
        )
    return "\n".join(lines)


@figure("fig12_sync")
def fig12_sync(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 12 (a) sync subspace of PO, (b) sync error and (c) its PSD for PO and CO, with Table I."""
    table, traces = table_i_rows(quick)
    fig = new_figure((13, 6.5), layout=None)
    grid = fig.add_gridspec(2, 3, height_ratios=[4, 1])
    ax_a, ax_b, ax_c = (fig.add_subplot(grid[0, i]) for i in range(3))
    po = traces["PO"]
    _draw_subspace(ax_a, po["y"], po["x_meas"])
    ax_a.set_title("(a) PO synchronisation subspace")
    ax_a.legend(fontsize=7)
    errors = {label: tr["y"] - tr["x_meas"] for label, tr in traces.items()}
    scale, unit = display_unit(pd.concat(errors.values()), "m")
    for label, style in (("PO", "k-"), ("CO", "b-")):
        tr, e = traces[label], errors[label]
        ax_b.plot(tr["t"], scale * e, style, lw=0.6, label=label)
        f, pxx = error_psd(e.to_numpy(), float(tr["t"].iloc[1] - tr["t"].iloc[0]))
        ax_c.semilogy(f, pxx, style, lw=0.8, label=label)
    ax_b.set(xlabel="time [s]", ylabel=f"y* - x [{unit}]", title="(b) synchronisation error")
    # the band of the dynamics, where the paper reads the error's predominant frequency (fe)
    ax_c.set(
        xlabel="frequency [Hz]",
        ylabel="PSD [m$^2$/Hz]",
        title=f"(c) error PSD (dotted: fe = {FIG9_PO.fe:g} Hz)",
        xlim=(0, DYNAMICS_BAND),
    )
    ax_c.axvline(FIG9_PO.fe, color="0.6", ls=":", lw=0.8)
    ax_b.legend(fontsize=7)
    ax_c.legend(fontsize=7)
    text_ax = fig.add_subplot(grid[1, :])
    text_ax.axis("off")
    text = _table_text(table)
    text_ax.text(0.0, 1.0, text, family="monospace", fontsize=8, va="top")
    fig.tight_layout()
    path = outdir / "fig12_sync.png"
    fig.savefig(path, dpi=120)
    csv = outdir / "table1_sync.csv"
    table.to_csv(csv, index=False)
    print(text)
    return [path, csv]


def draw_sync(trace: pd.DataFrame, report: SyncReport, path: Path) -> Path:
    """Four panels of one trace: subspace, error, error PSD, online delay estimate.

    The PSD is drawn over its whole band (log axes, 0 Hz left out), the band
    of the dynamics shaded, and the peaks that ``report`` names (within that
    band and above it) marked; the title names them as ``pendsweep sync``
    prints them.
    """
    fig = new_figure((10, 8), layout=None)
    axes = fig.subplots(2, 2)
    y, x = trace["y"], trace["x_meas"]
    _draw_subspace(axes[0, 0], y, x)
    axes[0, 0].set_title(f"sync subspace (ratio {report.ratio:.2f} %)")
    e = y - x
    scale, unit = display_unit(e, "m")
    axes[0, 1].plot(trace["t"], scale * e, "k-", lw=0.4)
    axes[0, 1].set(
        xlabel="time [s]",
        ylabel=f"y* - x [{unit}]",
        title=f"J2 {report.indices.J2:.2f} %, J3 {report.indices.J3:.2f} %",
    )
    _draw_error_psd(axes[1, 0], e.to_numpy(), float(np.median(np.diff(trace["t"]))), report)
    od = report.delay_online
    scale, unit = display_unit(od["delay"], "s")
    axes[1, 1].plot(od["t"], scale * od["delay"], "k.-", ms=3)
    axes[1, 1].set(
        xlabel="time [s]",
        ylabel=f"delay [{unit}]",
        title=f"online delay estimate (J1 {scale * report.indices.J1:.2f} {unit})",
    )
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return Path(path)


def _draw_error_psd(ax, error: np.ndarray, dt: float, report: SyncReport) -> None:
    """The error PSD on log axes from its first bin to Nyquist, the dynamics band shaded, the peaks marked."""
    f, pxx = error_psd(error, dt)
    f, pxx = f[1:], pxx[1:]  # 0 Hz is the mean, and has no place on a log axis
    ax.loglog(f, pxx, "k-", lw=0.6)
    peaks = [p for p in (report.peak, report.high_peak) if p is not None]
    ax.axvspan(f[0], report.peak.high, color="0.92", lw=0)
    for peak in peaks:  # a marker just above each peak, pointing down at it, whole even at Nyquist
        ax.plot([peak.frequency], [1.5 * pxx[np.argmin(np.abs(f - peak.frequency))]], "rv", ms=6, clip_on=False)
    low = report.peak
    title = f"error PSD: peak {low.frequency:.2f} Hz (+{low.level_db:.0f} dB) in 0-{low.high:g} Hz (shaded)"
    if report.high_peak is not None:
        title += f"\nabove {low.high:g} Hz: {report.high_peak.frequency:.1f} Hz (+{report.high_peak.level_db:.0f} dB)"
    ax.set(xlabel="frequency [Hz]", ylabel="PSD [m$^2$/Hz]", xlim=(f[0], f[-1]))
    ax.set_title(title, fontsize=9)


__all__ = ["draw_sync", "fig9_hybrid", "fig11_hybrid", "fig12_sync", "hybrid_pair", "table_i_rows"]
