"""Fig. 11(a) and (b) with continuation branches over the brute-force sweeps (issue 15)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from matplotlib.axes import Axes

from ..analysis.continuation.run import ContinuationConfig, run_continuation, write_json
from ..backends import make_backend
from ..canvas import legend_right, new_figure
from ..engine.results import read_results
from ..model.params import ModelParams
from ..studies.hopf import hopf_simulate
from ..studies.sweep import run_sweep
from ..studies.sweepfile import SWEEPS_DIR, load_sweep
from .overlay import draw_continuation, wrapped_title
from .plotting import draw_bifurcation
from .registry import figure

#: Per panel (named by its sweep file): ``(parameter value, start angle [rad], period)`` of each
#: simulated start orbit - the period-2 swing, and at 38 N the rotation of one turn per forcing
#: period that fresh starts reach - and the continuation interval.
PANELS = {
    "fig11a": dict(starts=((30.0, 0.1, 2), (38.0, 0.1, 1)), value_range=(0.0, 45.0)),
    "fig11b": dict(starts=((9.5, 0.1, 2),), value_range=(0.1, 13.0)),
}
#: Forcing periods simulated before a start orbit's section is taken (from theta = start angle).
START_SETTLE_PERIODS = 600


def simulated_start(params: ModelParams, theta0: float) -> tuple[float, ...]:
    """Section reached from ``theta0`` after :data:`START_SETTLE_PERIODS` (paper's damping, emulated backend).

    Only a Newton start: a weakly attracting orbit need not have settled.
    """
    backend = make_backend("emulated")
    run = backend.run_point(params, backend.initial_state(params, 0.0, 0.0, theta0, 0.0), START_SETTLE_PERIODS, 1)
    return tuple(run.records[-1, 2:6])


def panel_continuations(name: str, outdir: Path, quick: bool) -> list[dict]:
    """The semi-trivial branch and the branches through the simulated start orbits of panel ``name``."""
    spec = load_sweep(SWEEPS_DIR / f"{name}.toml")
    parameter, model = spec.config.parameter, dict(spec.config.model)
    lo, hi = PANELS[name]["value_range"]
    points = 120 if quick else 400
    docs = [run_continuation(ContinuationConfig(parameter, lo, hi, model, max_points=points))]
    for value, theta0, period in PANELS[name]["starts"]:
        section = simulated_start(ModelParams.from_mapping(model).replace(**{parameter: value}), theta0)
        docs.append(
            run_continuation(
                ContinuationConfig(
                    parameter, lo, hi, model, start_section=section, start_value=value, period=period, max_points=points
                )
            )
        )
    for k, doc in enumerate(docs):
        write_json(doc, outdir / f"{name}-continuation-{k}{'-quick' if quick else ''}.json")
    return docs


def panel_sweep(name: str, outdir: Path, quick: bool) -> Path:
    """The panel's brute-force sweep (the results file of ``make run`` when it is there; resumed)."""
    spec = load_sweep(SWEEPS_DIR / f"{name}.toml")
    config, output = spec.config, spec.output
    if quick:
        config = replace(config, values=config.values[::10], transient_periods=10, record_periods=5)
        output = outdir / f"{name}-quick.parquet"
    run_sweep(config, output, n_jobs=-1, overwrite=quick)
    return output


#: Pendulum kicks [rad] whose simulated growth threshold (``hopf.hopf_simulate``) panel (c) compares
#: with the amplitude of the unstable period-2 orbit.
THRESHOLD_KICKS = (0.001, 0.003, 0.01, 0.03)


def draw_threshold(ax: Axes, quick: bool) -> None:
    """Max |theta| of the period-2 branch (log scale) against alpha, with the simulated kick thresholds.

    With Coulomb friction rest stays stable; the unstable period-2 orbit
    born at the fold is the edge of its basin, so a kick of size k should
    grow exactly above the alpha where that orbit's amplitude falls to k.
    """
    spec = load_sweep(SWEEPS_DIR / "fig11a.toml")
    model = dict(spec.config.model)
    params = ModelParams.from_mapping(model)
    section = simulated_start(params.replace(alpha=30.0), 0.1)
    doc = run_continuation(
        ContinuationConfig(
            "alpha",
            10.0,
            60.0,
            model,
            start_section=section,
            start_value=30.0,
            period=2,
            max_points=120 if quick else 400,
        )
    )
    draw_continuation(ax, doc, "theta_absmax")
    backend = make_backend("emulated")
    for kick in THRESHOLD_KICKS[1:] if quick else THRESHOLD_KICKS:
        alpha_h = hopf_simulate(params, backend, kick=kick, tol=0.1)["alpha_H"]
        ax.scatter(
            [alpha_h],
            [kick],
            marker="*",
            s=80,
            color="tab:orange",
            zorder=5,
            label=None if kick != THRESHOLD_KICKS[1] else "simulated kick threshold (hopf simulate)",
        )
    ax.set_yscale("log")
    ax.set_ylim(5e-4, 3.0)
    ax.set_xlabel("alpha [N]  (forcing amplitude)")
    ax.set_ylabel(r"max $|\theta|$ over the orbit [rad]")
    ax.grid(alpha=0.3, which="both")
    ax.set_title(
        wrapped_title("(c) fe = 2.5 Hz, Table IV damping: the unstable period-2 orbit is the kick threshold", 110),
        fontsize=10,
    )


@figure("fig11_continuation")
def fig11_continuation(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 11(a) and (b): continuation branches (solid stable, dashed unstable) over the sweeps; (c) thresholds.

    One panel a row, each as wide as the page, its legends right of it: no legend reaches into another
    panel or its tick labels (tests/test_legends.py checks overlaps between panels too).
    """
    fig = new_figure((11, 15))
    axes = fig.subplots(3, 1)
    draw_threshold(axes[2], quick)
    legend_right(axes[2], fontsize=8)
    for ax, name in zip(axes, PANELS):
        draw_bifurcation(ax, [read_results(panel_sweep(name, outdir, quick))])
        for doc in panel_continuations(name, outdir, quick):
            draw_continuation(ax, doc)
        legend_right(ax, fontsize=8, markerscale=1.5)
        ax.margins(x=0.02)
        # Room beyond +-pi: the rotating branch runs along theta = +-pi, clear of the motion strip (bottom).
        ax.set_ylim(-1.12 * math.pi, 1.18 * math.pi)
        ax.set_title(
            wrapped_title(
                f"{load_sweep(SWEEPS_DIR / f'{name}.toml').description}; "
                f"branches: tanh(w/eps) damping, eps = 1e-3 rad/s",
                110,
            ),
            fontsize=10,
        )
    path = outdir / f"fig11_continuation{'-quick' if quick else ''}.png"
    fig.savefig(path, dpi=150)
    return [path]
