"""``pendsweep margin``: delay margin of the substructured loop before a test."""

from __future__ import annotations

import dataclasses
import math

import click

from ..model.params import TABLE_IV, LoopParams
from ._app import PATH, STEP_S, FiniteFloat, UsageFailure, main
from ._checks import FIGURE_SUFFIXES, check_output

_RIG = LoopParams.from_model(TABLE_IV)


def _pair(text: str | None, name: str, cast) -> tuple | None:
    if text is None:
        return None
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        a, b = (cast(p.strip()) for p in parts)
        if not (math.isfinite(a) and math.isfinite(b)):
            raise ValueError
    except ValueError:
        raise UsageFailure(f"{name} {text!r} must be two comma-separated numbers, e.g. {name} 1,5") from None
    return a, b


@main.command("margin")
@click.option(
    "--M1",
    "M1",
    type=FiniteFloat(1e-6, 1e6, "kg"),
    default=_RIG.M1,
    show_default=True,
    help="Numerical-model mass M1 [kg].",
)
@click.option(
    "--C1",
    "C1",
    type=FiniteFloat(0.0, 1e6, "kg/s"),
    default=_RIG.C1,
    show_default=True,
    help="Numerical-model damping C1 [kg/s].",
)
@click.option(
    "--K",
    "K",
    type=FiniteFloat(1e-6, 1e9, "N/m"),
    default=_RIG.K,
    show_default=True,
    help="Numerical-model stiffness K [N/m].",
)
@click.option(
    "--ms",
    "ms",
    type=FiniteFloat(1e-6, 1e6, "kg"),
    default=_RIG.ms,
    show_default=True,
    help="Mass carried by the actuator, m_s = M2 + m [kg].",
)
@click.option(
    "--C2",
    "C2",
    type=FiniteFloat(0.0, 1e6, "kg/s"),
    default=_RIG.C2,
    show_default=True,
    help="Platform damping C2 [kg/s].",
)
@click.option(
    "--actuator",
    type=click.Choice(["servo", "delay"]),
    default="servo",
    show_default=True,
    help="Transfer system of the backend-loop section: servo lag after the delay, or pure (interpolated) delay.",
)
@click.option(
    "--dt", type=STEP_S, default=1e-3, show_default=True, help="Controller step of the backend loop [s], 1e-6 to 0.01."
)
@click.option(
    "--servo-bandwidth",
    type=FiniteFloat(0.1, 1e4, "Hz"),
    default=30.0,
    show_default=True,
    help="Servo natural frequency [Hz], 0.1 to 1e4.",
)
@click.option(
    "--servo-damping",
    type=FiniteFloat(0.01, 100.0),
    default=0.7,
    show_default=True,
    help="Servo damping ratio [-], 0.01 to 100.",
)
@click.option(
    "--predictor",
    default=None,
    metavar="n,N",
    help="Polynomial forward prediction: order n (0-4) fitted to N points (e.g. 1,5, the paper's).",
)
@click.option(
    "--tau-hat",
    default=None,
    metavar="SECONDS|matched",
    help="Prediction horizon [s]; 'matched' sets it to the total effective delay of the actuator at --filter-frequency (the transport delay for --actuator delay) (default 0.018 s, the paper's).",
)
@click.option(
    "--filter-band",
    default=None,
    metavar="LOW,HIGH",
    help="Butterworth band-pass on the measured force, edges [Hz] (default: no filter).",
)
@click.option(
    "--filter-order",
    type=click.IntRange(1, 8),
    default=1,
    show_default=True,
    help="Butterworth order of the force filter.",
)
@click.option(
    "--filter-frequency",
    type=FiniteFloat(1e-3, 1e4, "Hz"),
    default=2.5,
    show_default=True,
    help="Frequency [Hz] where the filter's phase lag sets the force-prediction horizon (the forcing frequency).",
)
@click.option(
    "--tau-max",
    type=FiniteFloat(1e-6, 5.0, "s"),
    default=0.5,
    show_default=True,
    help="Largest transport delay scanned for the backend loop [s], up to 5.",
)
@click.option(
    "--roots-at",
    "roots_at",
    type=FiniteFloat(0.0, 10.0, "s"),
    default=None,
    metavar="TAU",
    help="Also list the rightmost exact roots [1/s] and the spectral abscissa at this delay [s].",
)
@click.option("--table2", is_flag=True, help="Print Table II (ours next to the paper's two rows) and stop.")
@click.option(
    "--plot",
    type=PATH,
    default=None,
    help="Write a Bode diagram with the margins (.png/.pdf/.svg).",
)
def margin(M1, C1, K, ms, C2, actuator, dt, servo_bandwidth, servo_damping, predictor, tau_hat, filter_band,
           filter_order, filter_frequency, tau_max, roots_at, table2, plot) -> None:  # fmt: skip
    """Phase margins, stability-switch delays and the critical delay tau*.

    First the paper's loop 1 + F_s N_m exp(-s tau) = 0 (Eqs. 6-9): every gain
    crossover, its phase margin psi and switch delay tau_i = psi/omega, the
    critical delay tau* with its frequency, checked against the exact
    characteristic roots. Then the loop exactly as the substructured backend
    runs it (sampled at dt, servo or delay actuator, optional predictor and
    force filter): the critical transport delay without and with compensation.
    """
    from ..analysis.stability import (
        SampledLoop,
        delay_margin,
        format_crossings,
        format_table_ii,
        rightmost_roots,
        sampled_delay_margin,
        spectral_abscissa,
    )

    check_output(plot, "--plot", FIGURE_SUFFIXES)
    if table2:
        click.echo(format_table_ii())
        return
    loop = LoopParams(M1=M1, C1=C1, K=K, ms=ms, C2=C2)
    pred = _pair(predictor, "--predictor", int)
    band = _pair(filter_band, "--filter-band", float)
    if tau_hat is not None and pred is None:
        raise UsageFailure("--tau-hat needs --predictor n,N")
    if tau_max <= 0:
        raise UsageFailure(f"--tau-max {tau_max!r} s must be > 0")
    horizon: float | None = 0.018
    if tau_hat == "matched":
        horizon = None
    elif tau_hat is not None:
        try:
            horizon = float(tau_hat)
        except ValueError:
            raise UsageFailure(f"--tau-hat {tau_hat!r} must be a delay in seconds or 'matched'") from None
        if not 0.0 <= horizon <= 1.0:
            raise UsageFailure(f"--tau-hat {tau_hat!r} s is outside the accepted range [0, 1] s (or 'matched')")
    base = SampledLoop(dt=dt, actuator=actuator, servo_bandwidth=servo_bandwidth, servo_damping=servo_damping,
                       filter_band=band, filter_order=filter_order, filter_frequency=filter_frequency)  # fmt: skip
    comp = None
    if pred is not None:
        comp = dataclasses.replace(base, predictor_order=pred[0], predictor_points=pred[1], tau_hat=horizon)

    click.echo(
        f"loop: M1 = {loop.M1:g} kg, C1 = {loop.C1:g} kg/s, K = {loop.K:g} N/m, m_s = {loop.ms:g} kg, "
        f"C2 = {loop.C2:g} kg/s (p = m_s/M1 = {loop.mass_ratio:.4g})"
    )
    click.echo("\npure delay T(s) = exp(-s tau), Eqs. (6)-(9):")
    result = delay_margin(loop)
    click.echo(format_crossings(result))
    if result.has_number:
        root = complex(rightmost_roots(loop, result.tau_star, count=1)[0])
        lo, hi = spectral_abscissa(loop, 0.99 * result.tau_star), spectral_abscissa(loop, 1.01 * result.tau_star)
        click.echo(
            f"exact roots at tau*: rightmost s = {root.real:.2e} + {root.imag:.6g}i; spectral abscissa "
            f"{lo:+.4g} 1/s at 0.99 tau*, {hi:+.4g} 1/s at 1.01 tau*"
        )
    if roots_at is not None:
        if roots_at < 0:
            raise UsageFailure(f"--roots-at {roots_at!r} s must be >= 0")
        roots = rightmost_roots(loop, roots_at, count=6)
        listed = ", ".join(f"{r.real:.5g} {'+' if r.imag >= 0 else '-'} {abs(r.imag):.6g}i" for r in roots)
        click.echo(f"rightmost roots at tau = {roots_at:g} s (conjugates implied): {listed}")
        click.echo(f"spectral abscissa at tau = {roots_at:g} s: {spectral_abscissa(loop, roots_at):+.6g} 1/s")

    what = (
        f"servo {servo_bandwidth:g} Hz, zeta {servo_damping:g}"
        if actuator == "servo"
        else "pure delay, Hermite command"
    )
    click.echo(f"\nsubstructured backend loop (sampled at dt = {dt:g} s, {what}; tau = transport delay):")
    rows = [("no compensation", base)] + ([(_describe(comp), comp)] if comp else [])
    for label, cfg in rows:
        r = sampled_delay_margin(loop, cfg, tau_max)
        if r.tau_star is None:
            click.echo(f"  {label}: {r.reason}")
        elif r.tau_star == 0.0:
            click.echo(f"  {label}: {r.reason} (growing at {r.omega_star:.5g} rad/s)")
        else:
            click.echo(f"  {label}: tau* = {r.tau_star:.6g} s, omega* = {r.omega_star:.6g} rad/s")
    if plot is not None:
        from ..figures.stability import bode_figure

        bode_figure(loop, plot, comp or base)
        click.echo(f"wrote {plot}")


def _describe(cfg) -> str:
    """One line naming a :class:`~pendsweep.analysis.stability.SampledLoop`'s predictor."""
    horizon = "tau_hat matched to the effective delay" if cfg.tau_hat is None else f"tau_hat = {cfg.tau_hat:g} s"
    return f"predictor n = {cfg.predictor_order}, N = {cfg.predictor_points}, {horizon}"
