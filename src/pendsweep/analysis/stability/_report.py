"""Text reports: the margin table of ``pendsweep margin`` and Table II."""

from __future__ import annotations

from ...model.params import TABLE_II_FREQ_EXPERIMENT_PAPER, TABLE_II_FREQ_THEORY_PAPER, TABLE_II_LOOPS, TABLE_II_P
from ._margins import DelayMargin, delay_margin

__all__ = ["table_ii", "format_table_ii", "format_crossings"]


def table_ii() -> list[tuple[float, float, float, float, float]]:
    """Table II: ``(p, omega* ours, paper theory, paper experiment, tau* ours)`` per mass ratio.

    Frequencies in rad/s, delays in s.
    """
    rows = []
    for p, loop, theory, experiment in zip(
        TABLE_II_P, TABLE_II_LOOPS, TABLE_II_FREQ_THEORY_PAPER, TABLE_II_FREQ_EXPERIMENT_PAPER
    ):
        m = delay_margin(loop)
        rows.append((p, float(m.omega_star), theory, experiment, float(m.tau_star)))
    return rows


def format_table_ii() -> str:
    """Table II with our theoretical row printed between the paper's two rows."""
    rows = table_ii()
    lines = [
        "Table II: instability frequencies [rad/s], M1 = 4 kg, C1 = 10 kg/s, K = 3000 N/m, C2 = C1",
        "p                    " + "".join(f"{r[0]:>9.4f}" for r in rows),
        "paper, experimental  " + "".join(f"{r[3]:>9.0f}" for r in rows),
        "paper, theoretical   " + "".join(f"{r[2]:>9.0f}" for r in rows),
        "pendsweep, theory    " + "".join(f"{r[1]:>9.2f}" for r in rows),
        "  experiment/ours - 1" + "".join(f"{r[3] / r[1] - 1:>+9.1%}" for r in rows),
        "pendsweep tau* [s]   " + "".join(f"{r[4]:>9.4f}" for r in rows),
    ]
    return "\n".join(lines)


def format_crossings(margin: DelayMargin) -> str:
    """The crossover table and the verdict of :func:`delay_margin` as text."""
    lines = [f"{'omega [rad/s]':>14} {'psi [deg]':>10} {'tau_i [s]':>11}  crossing as tau grows"]
    for c in margin.crossings:
        way = "destabilising (roots move right)" if c.destabilising else "stabilising (roots move left)"
        lines.append(f"{c.omega:>14.6g} {c.psi_deg:>10.2f} {c.tau:>11.6g}  {way}, repeats every {c.period:.6g} s")
    if not margin.crossings:
        lines.append(f"{'(no gain crossover)':>14}")
    if margin.has_number:
        lines.append(f"critical delay tau* = {margin.tau_star:.6g} s at omega* = {margin.omega_star:.6g} rad/s")
    else:
        lines.append(f"no critical delay: {margin.reason}")
    return "\n".join(lines)
