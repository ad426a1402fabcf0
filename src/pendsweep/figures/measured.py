"""The paper's Fig. 2 procedure on the shared real free swings."""

from __future__ import annotations

from pathlib import Path

from .registry import figure


@figure("free_swing_damping")
def free_swing_damping(outdir: Path, quick: bool) -> list[Path]:
    """Envelopes of the three real records: fitted on the 135 deg record, predicted on the others.

    Writes nothing when ``shared/data/measured/free-swing-rotary-pendulum`` is absent.
    ``quick`` fits and plots the fitted record only.
    """
    from ..measured.diagnose.damping import fit_damping, predict
    from ..measured.diagnose.report import plot_envelopes
    from ..measured.records import find_free_swing_data, read_free_swing

    folder = find_free_swing_data()
    if folder is None:
        return []
    fitted = folder / "free_swing_02.txt"
    fit = fit_damping(read_free_swing(fitted))
    curves = {f"{fitted.name} (fit, {100 * fit.envelope_error:.1f} %)": (fit.measured, fit.simulated)}
    if not quick:
        for name in ("free_swing_01.txt", "free_swing_03.txt"):
            pred = predict(fit, read_free_swing(folder / name))
            curves[f"{name} (predicted, {100 * pred['envelope_error']:.1f} %)"] = (pred["measured"], pred["simulated"])
    return [plot_envelopes(curves, outdir / "free_swing_damping.png")]
