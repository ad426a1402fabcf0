"""Diagnosis benchmark: verdicts on independently generated records (``make bench``).

Records come from :mod:`pendsweep.measured.diagnose.testbench` (no code shared with the
replay kernels) with seeds from its ``TEST_SEEDS`` range (B); the verdict
thresholds were chosen on ``CALIBRATION_SEEDS`` (range A) only
(``python -m pendsweep.bench.diagnosis calibrate N`` prints the statistics they
were read from). Writes a confusion matrix, recall per cause, the
false-positive rate on clean records, the share of out-of-vocabulary records
flagged ``unexplained``, pairs named right, estimate-error quantiles and a
figure ``results/diagnosis_confusion.png``.
"""

from __future__ import annotations

import math
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from .registry import benchmark

#: Records in the full and the quick run, and look-alike records (issue 34) in each.
RECORDS, QUICK_RECORDS = 200, 16
LOOK_ALIKE_RECORDS, QUICK_LOOK_ALIKE_RECORDS = 60, 6
GOALS = {"single_recall": 0.95, "clean_false_positive_rate": 0.02, "oov_flagged": 0.90, "pairs_right": 0.80}
#: Look-alike records whose forcing separates them: the right cause named alone (not tied).
LOOK_ALIKE_GOAL = 0.95
FIGURE = Path("results/diagnosis_confusion.png")


def evaluate(seed: int) -> dict:
    """Generate the case of ``seed``, diagnose it, and score the verdict."""
    from ..measured.diagnose.effects import EFFECTS
    from ..measured.diagnose.pipeline import diagnose_records
    from ..measured.diagnose.populations import draw_case
    from ..measured.diagnose.testbench import generate

    category, case = draw_case(seed)
    record = generate(case)
    t0 = time.perf_counter()
    d = diagnose_records([record])  # substructured records part by part (issue 22)
    seconds = time.perf_counter() - t0
    js = d.to_json()
    tests = getattr(d, "tests", {})
    row = {
        "seed": seed,
        "category": category,
        "kind": case.kind,
        "rate": case.rate,
        "at_rest": case.theta_init == 0.0,
        "tones": len(case.tones),
        "truth": case.label,
        "extra": ",".join(case.extra),
        "verdict": js["cause"],
        "unexplained": js["unexplained"],
        "explained_share": js["explained_share"],
        "seconds": seconds,
        "error_before": js["error_before"],
        "error_after": js["error_after"],
        "noise_floor": js["noise_floor"],
        "estimate_rel_error": {},
        "estimate_z": {},
        "first_round": {k: tests["first_round"][k] for k in ("model", "explained_share", "p_value", "z")}
        if "first_round" in tests
        else {},
    }
    for cause, truth in case.effects.items():
        p = EFFECTS[cause].param
        if p in js["estimate"]:
            err = js["estimate"][p] - truth
            row["estimate_rel_error"][cause] = abs(err) / (abs(truth) if p != "theta_offset" else 0.01)
            sigma = js["uncertainty"].get(p, math.nan)
            row["estimate_z"][cause] = abs(err) / sigma if sigma > 0 else math.inf
    return row


def evaluate_look_alike(seed: int, kind: str) -> dict:
    """Generate the look-alike record of ``seed`` (:func:`~pendsweep.measured.diagnose.populations.draw_look_alike_case`),
    diagnose it as a user would, and score it: right alone (no look-alike tied), right or tied, the tie's reason."""
    from ..measured.diagnose.effects import EFFECTS
    from ..measured.diagnose.pipeline import diagnose_records
    from ..measured.diagnose.populations import LOOK_ALIKE_CAUSES, SEPARATING_FORCINGS, generate_look_alike_case

    forcing, case, record = generate_look_alike_case(seed, kind)
    t0 = time.perf_counter()
    js = diagnose_records([record]).to_json()
    seconds = time.perf_counter() - t0
    truth, value = next(iter(case.effects.items()))
    part = js["parts"]["numerical"] if "parts" in js else js
    partners = set(LOOK_ALIKE_CAUSES) - {truth}
    estimate = js["estimate"].get(EFFECTS[truth].param)
    sigma = js["uncertainty"].get(EFFECTS[truth].param)
    right = js["cause"] == truth
    return {
        "seed": seed,
        "kind": kind,
        "forcing": forcing,
        "separating": forcing in SEPARATING_FORCINGS,
        "rate": case.rate,
        "theta_init": case.theta_init,
        "truth": truth,
        "value": value,
        "verdict": js["cause"],
        "tied_with": js["tied_with"],
        "tie_reasons": part.get("tie_reasons", {}),
        "unexplained": js["unexplained"],
        "right_alone": right and not partners & set(js["tied_with"]),
        "right_or_tied": right or (truth in js["tied_with"] and js["cause"] in LOOK_ALIKE_CAUSES),
        "estimate_rel_error": abs(estimate - value) / abs(value) if right and estimate is not None else None,
        "estimate_z": abs(estimate - value) / sigma if right and sigma else None,
        "seconds": seconds,
    }


def run_look_alikes(seeds, kind: str, n_jobs: int = 2, progress: bool = True) -> list[dict]:
    """Rows of :func:`evaluate_look_alike` for ``seeds`` (joblib processes)."""
    from joblib import Parallel, delayed
    from tqdm import tqdm

    it = tqdm(list(seeds), desc=f"look-alike {kind} records", file=sys.stderr, disable=not progress)
    return list(Parallel(n_jobs=n_jobs, backend="loky")(delayed(evaluate_look_alike)(s, kind) for s in it))


def summarize_look_alikes(rows: list[dict]) -> dict:
    """Look-alikes right alone where the forcing separates them (goal :data:`LOOK_ALIKE_GOAL`), right or
    tied under one steady tone (with the tie's reason), per forcing, and the estimates' errors."""

    def rate(rs, ok):
        return sum(map(ok, rs)) / len(rs) if rs else math.nan

    separating = [r for r in rows if r["separating"]]
    steady = [r for r in rows if not r["separating"]]
    tied = [r for r in rows if r["tied_with"]]
    errors = [r["estimate_rel_error"] for r in rows if r["estimate_rel_error"] is not None]
    out = {
        "records": len(rows),
        "separating_right_alone": rate(separating, lambda r: r["right_alone"]),
        "one_tone_right_or_tied": rate(steady, lambda r: r["right_or_tied"]),
        "ties_with_reason": rate(tied, lambda r: bool(r["tie_reasons"])),
        "flagged_unexplained": rate(rows, lambda r: r["unexplained"]),
        "by_forcing": {
            f: {
                "records": len(rs),
                "right_alone": rate(rs, lambda r: r["right_alone"]),
                "right_or_tied": rate(rs, lambda r: r["right_or_tied"]),
            }
            for f in sorted({r["forcing"] for r in rows})
            for rs in [[r for r in rows if r["forcing"] == f]]
        },
        "estimate_rel_error_quantiles": (
            {q: float(np.quantile(errors, float(q))) for q in ("0.5", "0.9", "0.99")} if errors else {}
        ),
        "seconds_per_record_median": float(np.median([r["seconds"] for r in rows])) if rows else math.nan,
        "misses": [
            {k: r[k] for k in ("seed", "forcing", "rate", "theta_init", "truth", "verdict", "tied_with", "unexplained")}
            for r in rows
            if not (r["right_alone"] if r["separating"] else r["right_or_tied"])
        ],
        "goal": LOOK_ALIKE_GOAL,
    }
    out["goal_met"] = out["separating_right_alone"] >= LOOK_ALIKE_GOAL
    return out


def run_population(seeds, n_jobs: int = 2, progress: bool = True) -> list[dict]:
    """Rows of :func:`evaluate` for ``seeds`` (joblib processes)."""
    from joblib import Parallel, delayed
    from tqdm import tqdm

    seeds = list(seeds)
    it = tqdm(seeds, desc="diagnosis records", file=sys.stderr, disable=not progress)
    return list(Parallel(n_jobs=n_jobs, backend="loky")(delayed(evaluate)(s) for s in it))


def summarize(rows: list[dict]) -> dict:
    """Confusion matrix, recall per cause, false-positive rate, OOV flagged, pairs, estimate errors."""
    singles = [r for r in rows if r["category"] == "single"]
    clean = [r for r in rows if r["category"] == "clean"]
    pairs = [r for r in rows if r["category"] == "pair"]
    oov = [r for r in rows if r["category"] == "oov"]
    confusion: dict[str, dict[str, int]] = {}
    for r in singles + clean:
        confusion.setdefault(r["truth"], Counter())[r["verdict"]] += 1
    recall = {t: c[t] / sum(c.values()) for t, c in confusion.items() if t != "none"}
    errors = [e for r in singles for e in r["estimate_rel_error"].values()]
    # |estimate - truth| / stated uncertainty of right verdicts: a calibrated one-sigma gives
    # 68 % within 1, 95 % within 2, a median of 0.67.
    z = np.array([r["estimate_z"][r["truth"]] for r in singles if r["verdict"] == r["truth"]])

    def rate(rs, ok):
        return sum(map(ok, rs)) / len(rs) if rs else math.nan

    by_kind = {
        k: {
            "single_recall": rate([r for r in singles if r["kind"] == k], lambda r: r["verdict"] == r["truth"]),
            "clean_false_positive_rate": rate([r for r in clean if r["kind"] == k], lambda r: r["verdict"] != "none"),
            "oov_flagged": rate([r for r in oov if r["kind"] == k], lambda r: r["unexplained"]),
        }
        for k in ("free_decay", "forced", "substructured")
    }
    out = {
        "records": len(rows),
        "counts": {"clean": len(clean), "single": len(singles), "pair": len(pairs), "oov": len(oov)},
        "single_recall": rate(singles, lambda r: r["verdict"] == r["truth"]),
        "clean_false_positive_rate": rate(clean, lambda r: r["verdict"] != "none"),
        "clean_flagged_unexplained": rate(clean, lambda r: r["unexplained"]),
        "oov_flagged": rate(oov, lambda r: r["unexplained"]),
        "pairs_right": rate(pairs, lambda r: set(r["verdict"].split("+")) == set(r["truth"].split("+"))),
        "pairs_one_named_right": rate(pairs, lambda r: bool(set(r["verdict"].split("+")) & set(r["truth"].split("+")))),
        "single_flagged_unexplained": rate(singles, lambda r: r["unexplained"]),
        "recall_per_cause": recall,
        "by_kind": by_kind,
        "confusion": {t: dict(c) for t, c in sorted(confusion.items())},
        "estimate_rel_error_quantiles": (
            {q: float(np.quantile(errors, float(q))) for q in ("0.5", "0.9", "0.99")} if errors else {}
        ),
        "uncertainty_coverage": (
            {
                "estimates": int(z.size),
                "within_1_sigma": float(np.mean(z <= 1.0)),
                "within_2_sigma": float(np.mean(z <= 2.0)),
                "median_z": float(np.median(z)),
                "max_z": float(np.max(z)),
            }
            if z.size
            else {}
        ),
        "seconds_per_record_median": float(np.median([r["seconds"] for r in rows])),
        "misses": [
            {k: r[k] for k in ("seed", "category", "kind", "rate", "truth", "extra", "verdict", "unexplained")}
            for r in rows
            if (
                r["category"] in ("single", "clean", "pair")
                and r["verdict"] != r["truth"]
                and set(r["verdict"].split("+")) != set(r["truth"].split("+"))
            )
            or (r["category"] == "oov" and not r["unexplained"])
        ],
    }
    out["goals"] = GOALS
    out["goals_met"] = {
        "single_recall": out["single_recall"] >= GOALS["single_recall"],
        "clean_false_positive_rate": out["clean_false_positive_rate"] <= GOALS["clean_false_positive_rate"],
        "oov_flagged": out["oov_flagged"] >= GOALS["oov_flagged"],
        "pairs_right": out["pairs_right"] >= GOALS["pairs_right"],
    }
    return out


def confusion_figure(
    confusion: dict[str, dict[str, int]], path: Path, title: str, xlabel: str, ylabel: str, rotation: float = 75
) -> Path:
    """A confusion matrix (rows: truth, columns: verdict), shaded by row share and labelled by count."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    truths = sorted(confusion)
    verdicts = sorted({v for c in confusion.values() for v in c} | set(truths))
    mat = np.array([[confusion[t].get(v, 0) for v in verdicts] for t in truths], dtype=float)
    fig = Figure(figsize=(1.5 + 0.6 * len(verdicts), 1.2 + 0.45 * len(truths)))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.imshow(mat / np.maximum(mat.sum(axis=1, keepdims=True), 1), cmap="Blues", vmin=0, vmax=1)
    for i in range(len(truths)):
        for j in range(len(verdicts)):
            if mat[i, j]:
                ax.text(j, i, int(mat[i, j]), ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(verdicts)), verdicts, rotation=rotation, fontsize=7)
    ax.set_yticks(range(len(truths)), truths, fontsize=7)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def plot(summary: dict, path: Path) -> Path:
    """Confusion matrix of single-effect and clean records (rows: truth, columns: verdict)."""
    title = (
        f"single recall {summary['single_recall']:.2f}, clean FP {summary['clean_false_positive_rate']:.2f}, "
        f"OOV flagged {summary['oov_flagged']:.2f}, pairs {summary['pairs_right']:.2f}"
    )
    return confusion_figure(summary["confusion"], path, title, "verdict", "hidden effect")


@benchmark("diagnosis")
def bench_diagnosis(quick: bool) -> dict:
    """Verdicts on RECORDS independently generated records of the test seed range."""
    from ..measured.diagnose.testbench import TEST_SEEDS

    n = QUICK_RECORDS if quick else RECORDS
    t0 = time.perf_counter()
    rows = run_population(TEST_SEEDS[:n])
    summary = summarize(rows)
    summary["wall_seconds"] = time.perf_counter() - t0
    summary["seed_range"] = (
        f"TEST_SEEDS (range B) {TEST_SEEDS[0]}..{TEST_SEEDS[0] + n - 1}; thresholds chosen on CALIBRATION_SEEDS (range A)"
    )
    summary["figure"] = str(plot(summary, FIGURE))
    m = QUICK_LOOK_ALIKE_RECORDS if quick else LOOK_ALIKE_RECORDS
    t0 = time.perf_counter()
    summary["look_alikes"] = summarize_look_alikes(run_look_alikes(TEST_SEEDS[:m], "forced"))
    summary["look_alikes"]["wall_seconds"] = time.perf_counter() - t0
    summary["look_alikes"]["seed_range"] = f"TEST_SEEDS (range B) {TEST_SEEDS[0]}..{TEST_SEEDS[0] + m - 1}, forced"
    return summary


def main(argv: list[str]) -> None:
    """``python -m pendsweep.bench.diagnosis calibrate N [OUT] [KIND]``: statistics on the calibration seeds;
    KIND ``forced`` or ``substructured`` calibrates on look-alike records (issue 34) instead."""
    import json

    from ..measured.diagnose.testbench import CALIBRATION_SEEDS

    n = int(argv[1]) if len(argv) > 1 else 60
    if len(argv) > 3:
        rows = run_look_alikes(CALIBRATION_SEEDS[:n], argv[3])
        out = Path(argv[2])
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps({"rows": rows, "summary": summarize_look_alikes(rows)}, indent=1, default=float))
        print(json.dumps(summarize_look_alikes(rows), indent=1, default=float))
        return
    rows = run_population(CALIBRATION_SEEDS[:n])
    out = Path(argv[2]) if len(argv) > 2 else Path("results/diagnosis_calibration.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"rows": rows, "summary": summarize(rows)}, indent=1, default=float))
    print(json.dumps(summarize(rows), indent=1, default=float))


if __name__ == "__main__" and len(sys.argv) > 1 and sys.argv[1] == "calibrate":
    main(sys.argv[1:])
