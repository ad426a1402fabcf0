"""Fig. 10 (Hopf boundary, three methods; four masses) and the coexistence figure of Fig. 11(a)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..canvas import new_figure
from ..model.params import FIG9_CO, FIG9_PO, FIG11A
from ..studies.hopf import HopfConfig, run_hopf
from ..studies.sweep import SweepConfig, run_sweep, sweep_metadata, value_range
from .plotting import draw_bifurcation
from .registry import figure

#: Masses of Fig. 10(b) [kg].
FIG10B_MASSES = (5.9, 10.9, 15.9, 20.9)
#: Kick [rad] large enough for Coulomb friction not to dominate the simulated boundary at every mass.
BIG_KICK = 0.03
#: omega_hat range of Fig. 10.
OMEGA_HAT = (0.88, 1.12)


def _grid(quick: bool) -> tuple[float, ...]:
    return tuple(np.linspace(*OMEGA_HAT, 4 if quick else 25))


def _save(fig, path: Path) -> list[Path]:
    fig.savefig(path, dpi=150)
    return [path]


@figure("fig10a")
def fig10a(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 10(a): Eq. (12), Floquet and the simulated protocol, PO/CO points, cross-section A."""
    fine = tuple(np.linspace(*OMEGA_HAT, 13 if quick else 241))
    lines = run_hopf(HopfConfig(omega_hat=fine, methods=("analytic", "floquet")), n_jobs=2)
    smooth = run_hopf(HopfConfig(omega_hat=_grid(quick), methods=("simulate",), model={"b1": 0.0, "b3": 0.0}), n_jobs=2)
    rig = run_hopf(HopfConfig(omega_hat=_grid(quick), methods=("simulate",)), n_jobs=2)
    rig_kicked = run_hopf(HopfConfig(omega_hat=_grid(quick), methods=("simulate",), kick=BIG_KICK), n_jobs=2)
    # The paper's stars: the protocol run as a (simulated) substructuring test.
    hybrid = run_hopf(
        HopfConfig(omega_hat=_grid(quick), methods=("simulate",), kick=BIG_KICK, backend="substructured"), n_jobs=2
    )
    fig = new_figure((7.5, 4.8))
    ax = fig.subplots()
    for method, style in (
        ("analytic", dict(color="0.5", lw=2.5, label="Eq. (12)")),
        ("floquet", dict(color="tab:blue", lw=1.0, label="Floquet (exact for b1 = b3 = 0)")),
    ):
        sel = lines[lines.method == method]
        ax.plot(sel.omega_hat, sel.alpha_H, **style)
    kick = rig["kick"].iloc[0]
    ax.plot(
        smooth.omega_hat,
        smooth.alpha_H,
        "o",
        mfc="none",
        color="tab:green",
        label=f"simulated, b1 = b3 = 0 (kick {kick:g} rad)",
    )
    ax.plot(rig.omega_hat, rig.alpha_H, "*", color="k", ms=8, label=f"simulated, Table IV damping (kick {kick:g} rad)")
    ax.plot(
        rig_kicked.omega_hat,
        rig_kicked.alpha_H,
        "^",
        color="tab:purple",
        ms=5,
        label=f"simulated, Table IV damping (kick {BIG_KICK:g} rad)",
    )
    ax.plot(
        hybrid.omega_hat,
        hybrid.alpha_H,
        "s",
        mfc="none",
        color="tab:orange",
        ms=6,
        label=f"substructured backend, Table IV damping (kick {BIG_KICK:g} rad)",
    )
    for params, name in ((FIG9_PO, "PO"), (FIG9_CO, "CO")):
        ax.plot(params.omega_hat, params.alpha, "x", color="tab:red", ms=9, mew=2)
        ax.annotate(name, (params.omega_hat, params.alpha), textcoords="offset points", xytext=(6, 2), color="tab:red")
    section_a = FIG11A.omega_hat
    ax.axvline(section_a, color="k", ls=":", lw=1)
    ax.annotate("A (fe = 2.5 Hz)", (section_a, 0.93), xycoords=("data", "axes fraction"), ha="right", fontsize=8)
    ax.set_xlabel(r"$\hat\omega = \omega_e / (2\omega_p)$")
    ax.set_ylabel(r"$\alpha_H$ [N]")
    ax.set_ylim(0, 1.1 * max(rig.alpha_H.max(), lines.alpha_H.max()))
    ax.set_title(
        "Fig. 10(a): Hopf boundary of the semi-trivial solution, M = 10.9 kg, C = 20 kg/s, K = 1910 N/m", fontsize=8
    )
    ax.legend(fontsize=7, loc="upper center")
    ax.grid(alpha=0.3)
    return _save(fig, outdir / f"fig10a{'-quick' if quick else ''}.png")


@figure("fig10b")
def fig10b(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 10(b): simulated boundary (Table IV damping) for four masses, with Eq. (12)."""
    masses = FIG10B_MASSES[::3] if quick else FIG10B_MASSES
    sim = run_hopf(HopfConfig(omega_hat=_grid(quick), masses=masses, methods=("simulate",), kick=BIG_KICK), n_jobs=2)
    fine = run_hopf(HopfConfig(omega_hat=tuple(np.linspace(*OMEGA_HAT, 121)), masses=masses, methods=("analytic",)))
    fig = new_figure((7.5, 4.8))
    ax = fig.subplots()
    for k, M in enumerate(masses):
        colour = f"C{k}"
        s, a = sim[sim.M == M], fine[fine.M == M]
        ax.plot(s.omega_hat, s.alpha_H, "*", color=colour, ms=7, label=f"M = {M:g} kg, simulated")
        ax.plot(a.omega_hat, a.alpha_H, color=colour, lw=0.8, alpha=0.7)
    ax.set_xlabel(r"$\hat\omega = \omega_e / (2\omega_p)$")
    ax.set_ylabel(r"$\alpha_H$ [N]")
    ax.set_ylim(0, 1.05 * sim.alpha_H.max())
    ax.set_title(
        f"Fig. 10(b): Hopf boundary for four masses, C = 20 kg/s, K = 1910 N/m\n"
        f"stars: simulated protocol, Table IV damping, kick {BIG_KICK:g} rad; lines: Eq. (12)",
        fontsize=8,
    )
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return _save(fig, outdir / f"fig10b{'-quick' if quick else ''}.png")


def coexistence_sweeps(quick: bool) -> list[SweepConfig]:
    """Fig. 11(a) section A: continuation both ways, fresh starts from 0.1 rad, seeded multistarts."""
    periods = dict(transient_periods=40, record_periods=10) if quick else {}
    model = {"fe": FIG11A.fe}
    full = value_range(30.0, 45.0, 1.0) if quick else value_range(0.0, 45.0, 0.5)
    upper = value_range(36.0, 45.0, 1.0 if quick else 0.5)
    return [
        SweepConfig("alpha", tuple(full), model, mode="continue", direction="both", **periods),
        SweepConfig("alpha", tuple(upper), model, mode="fresh", **periods),
        SweepConfig("alpha", tuple(upper[::2]), model, mode="multistart", starts=3 if quick else 8, **periods),
    ]


@figure("coexistence")
def coexistence(outdir: Path, quick: bool) -> list[Path]:
    """Fig. 11(a) with motion bands: the periodic branch past 39 N coexists with rotation and chaos."""
    results = [(run_sweep(c, n_jobs=2), sweep_metadata(c)) for c in coexistence_sweeps(quick)]
    fig = new_figure((8, 5))
    ax = fig.subplots()
    draw_bifurcation(ax, results, "theta_peak")
    ax.set_title(
        f"Fig. 11(a) section A (fe = {FIG11A.fe:g} Hz, emulated, noiseless): continuation up/down,\n"
        r"fresh starts from $\theta$ = 0.1 rad, seeded multistarts; strips: motion per branch",
        fontsize=8,
    )
    return _save(fig, outdir / f"coexistence{'-quick' if quick else ''}.png")
