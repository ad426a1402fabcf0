"""Malformed input, every subcommand: exit 2, one line naming the offending value, never a traceback.

A table of malformed invocations runs in-process through click's CliRunner
(each fails before any simulation starts), then Hypothesis fuzzes the two
file readers a user feeds by hand: TOML sweep definitions and measured-data
records (CSV + JSON sidecar).
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pendsweep.cli import main
from pendsweep.errors import PendsweepError

GOOD_TOML = 'parameter = "alpha"\nfrom = 0.0\nto = 1.0\nstep = 0.5\n'


def _parquet(path: Path, metadata: bytes | None) -> None:
    table = pa.table({"x": [1.0, 2.0]})
    if metadata is not None:
        table = table.replace_schema_metadata({b"pendsweep": metadata})
    pq.write_table(table, path)


def _record(folder: Path, name: str, csv: bytes | str, sidecar: object | bytes | None) -> None:
    data = csv if isinstance(csv, bytes) else csv.encode()
    (folder / f"{name}.csv").write_bytes(data)
    if sidecar is None:
        return
    side = sidecar if isinstance(sidecar, bytes) else json.dumps(sidecar).encode()
    (folder / f"{name}.json").write_bytes(side)


GOOD_CSV = "t,theta\n" + "".join(f"{0.01 * i:.2f},{0.1 * (1 - 0.01 * i):.4f}\n" for i in range(50))
FREE = {"format": 1, "kind": "free_decay", "params": {}}


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, str]:
    """Every malformed (and a few well-formed) input file the table refers to as {name}."""
    d = tmp_path_factory.mktemp("fuzz")
    f: dict[str, Path] = {}

    def toml(name: str, text: str | bytes) -> None:
        f[name] = d / f"{name}.toml"
        f[name].write_bytes(text if isinstance(text, bytes) else text.encode())

    for name, text in TOML_CASES.items():
        toml(name, text[0])
    toml("good", GOOD_TOML)
    toml("binary", bytes(range(256)) * 4)
    toml("latin1", 'parameter = "\xe9"\n'.encode("latin-1"))
    toml("empty", b"")
    for name, meta in {
        "hopf": json.dumps({"kind": "hopf", "config": {}}).encode(),
        "trace": json.dumps({"kind": "trace", "backend": "substructured"}).encode(),
        "record": json.dumps(FREE).encode(),
        "badjson": b"{not json",
        "listmeta": b"[1, 2]",
        "sweepbogus": json.dumps({"kind": "sweep", "config": {"bogus": 1}}).encode(),
        "sweep": json.dumps({"kind": "sweep", "config": {"parameter": "alpha", "values": [1.0]}}).encode(),
        "plain": None,
    }.items():
        f[name] = d / f"{name}.parquet"
        _parquet(f[name], meta)
    f["garbage"] = d / "garbage.parquet"
    f["garbage"].write_bytes(b"PAR1 this is not parquet at all")
    f["emptyparquet"] = d / "emptyparquet.parquet"
    f["emptyparquet"].write_bytes(b"")
    records = {
        "rec_empty": ("", FREE),
        "rec_binary": (bytes(range(256)), FREE),
        "rec_latin1": ("t,theta\n0,\xe9\n".encode("latin-1"), FREE),
        "rec_nosidecar": (GOOD_CSV, None),
        "rec_params_list": (GOOD_CSV, {"format": 1, "kind": "free_decay", "params": [1, 2]}),
        "rec_params_str": (GOOD_CSV, {"format": 1, "kind": "free_decay", "params": {"m": "heavy"}}),
        "rec_alpha_str": (GOOD_CSV, {"format": 1, "kind": "forced", "params": {}, "forcing": {"alpha": "loud"}}),
        "rec_forcing_list": (GOOD_CSV, {"format": 1, "kind": "forced", "params": {}, "forcing": [5]}),
        "rec_tau_str": (GOOD_CSV, {"format": 1, "kind": "substructured", "params": {"tau": "late"}}),
        "rec_sidecar_bad": (GOOD_CSV, b"{broken"),
        "rec_sidecar_binary": (GOOD_CSV, bytes(range(256))),
        "rec_sidecar_list": (GOOD_CSV, [1, 2, 3]),
        "rec_kind": (GOOD_CSV, {"format": 1, "kind": "wobbly", "params": {}}),
        "rec_nokind": (GOOD_CSV, {"format": 1, "params": {}}),
        "rec_textcol": ("t,theta\n0,a\n0.01,b\n0.02,c\n0.03,d\n", FREE),
        "rec_nan": ("t,theta\n0,0.1\n0.01,nan\n0.02,0.1\n0.03,0.1\n", FREE),
        "rec_short": ("t,theta\n0,0.1\n0.01,0.1\n", FREE),
        "rec_nocol": ("t,angle\n0,0.1\n0.01,0.1\n0.02,0.1\n0.03,0.1\n", FREE),
        "rec_ragged": ("t,theta\n0,0.1\n0.01,0.1,7\n0.02,0.1\n", FREE),
        "rec_time": ("t,theta\n0,0.1\n0.02,0.1\n0.01,0.1\n0.03,0.1\n", FREE),
        "rec_good": (GOOD_CSV, FREE),
    }
    for name, (csv, side) in records.items():
        _record(d, name, csv, side)
        f[name] = d / f"{name}.csv"
    f["rec_good_sidecar"] = d / "rec_good.json"
    f["fs_bad"] = d / "fs_bad.txt"
    f["fs_bad"].write_text("trigger_start_deg, sample_rate, duration_sec\n135, fast, 20\n1\n2\n")
    f["fs_rate"] = d / "fs_rate.txt"
    f["fs_rate"].write_text("trigger_start_deg, sample_rate, duration_sec\n135, -5, 20\n1\n2\n3\n")
    models = {
        "model_notjson": b"alpha: 5",
        "model_list": b"[1, 2]",
        "model_str": b'{"alpha": "five"}',
        "model_unknown": b'{"length": 1.0}',
        "model_nan": b'{"alpha": NaN}',
        "model_range": b'{"l": -1.0}',
        "model_binary": bytes(range(256)),
    }
    for name, data in models.items():
        f[name] = d / f"{name}.json"
        f[name].write_bytes(data)
    f["blocker"] = d / "blocker"
    f["blocker"].write_text("a file where a folder should be")
    f["adir"] = d / "adir.parquet"
    f["adir"].mkdir()
    f["missing"] = d / "missing.csv"
    from pendsweep.analysis.continuation.run import ContinuationConfig, run_continuation, write_json

    cont = ContinuationConfig("alpha", 15.5, 16.5, model={"b1": 0.0, "b3": 0.0}, max_points=20, max_period=1)
    f["cont"] = d / "cont.json"
    write_json(run_continuation(cont), f["cont"])
    continuations = {
        "cont_noconfig": {"kind": "continuation", "bifurcations": []},
        "cont_badbif": {"kind": "continuation", "config": json.loads(f["cont"].read_text())["config"],
                        "bifurcations": [{"type": "period-doubling", "value": "x", "period": 1, "section": [0] * 4}]},
    }  # fmt: skip
    for name, doc in continuations.items():
        f[name] = d / f"{name}.json"
        f[name].write_text(json.dumps(doc))
    return {k: str(v) for k, v in f.items()}


# -- the table -------------------------------------------------------------------------------------------------------
# (name -> TOML text, the text the message must contain)
TOML_CASES: dict[str, tuple[str, str]] = {
    "t_from_str": ('parameter = "alpha"\nfrom = "zero"\nto = 1.0\n', "from = 'zero'"),
    "t_transient_str": (GOOD_TOML + 'transient_periods = "ten"\n', "transient_periods = 'ten'"),
    "t_transient_neg": (GOOD_TOML + "transient_periods = -1\n", "transient_periods = -1"),
    "t_transient_huge": (GOOD_TOML + "transient_periods = 100000000\n", "transient_periods = 100000000"),
    "t_record_zero": (GOOD_TOML + "record_periods = 0\n", "record_periods = 0"),
    "t_initial_int": (GOOD_TOML + "initial = 5\n", "initial = 5"),
    "t_initial_short": (GOOD_TOML + "initial = [1.0, 2.0, 3.0]\n", "initial = [1.0, 2.0, 3.0]"),
    "t_initial_str": (GOOD_TOML + 'initial = [0.0, 0.0, "a", 0.0]\n', "initial = 'a'"),
    "t_initial_huge": (GOOD_TOML + "initial = [0.0, 0.0, 1e300, 0.0]\n", "theta = 1e+300"),
    "t_initial_nan": (GOOD_TOML + "initial = [0.0, 0.0, nan, 0.0]\n", "initial = nan"),
    "t_points_float": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\npoints = 2.5\n', "points = 2.5"),
    "t_points_zero": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\npoints = 0\n', "points = 0"),
    "t_points_bool": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\npoints = true\n', "points = True"),
    "t_points_huge": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\npoints = 100000000\n', "points = 100000000"),
    "t_step_str": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\nstep = "x"\n', "step = 'x'"),
    "t_step_tiny": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\nstep = 1e-300\n', "step = 1e-300"),
    "t_step_sign": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\nstep = -0.5\n', "wrong sign"),
    "t_step_zero": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\nstep = 0.0\n', "step = 0.0"),
    "t_span_huge": ('parameter = "alpha"\nfrom = -1e308\nto = 1e308\nstep = 1.0\n', "step = 1.0 gives more than"),
    "t_to_nan": ('parameter = "alpha"\nfrom = 0.0\nto = nan\nstep = 0.5\n', "to = nan"),
    "t_to_inf": ('parameter = "alpha"\nfrom = 0.0\nto = inf\nstep = 0.5\n', "to = inf"),
    "t_values_empty": ('parameter = "alpha"\nvalues = []\n', "values = []"),
    "t_values_str": ('parameter = "alpha"\nvalues = ["a"]\n', "values = 'a'"),
    "t_values_scalar": ('parameter = "alpha"\nvalues = 5\n', "values = 5"),
    "t_values_and_range": ('parameter = "alpha"\nvalues = [1.0]\nfrom = 0.0\nto = 1.0\n', "not both"),
    "t_step_and_points": ('parameter = "alpha"\nfrom = 0.0\nto = 1.0\nstep = 0.5\npoints = 3\n', "not both"),
    "t_param_int": ("parameter = 5\nfrom = 0.0\nto = 1.0\n", "parameter = 5"),
    "t_param_unknown": ('parameter = "length"\nfrom = 0.0\nto = 1.0\nstep = 0.5\n', "'length'"),
    "t_param_missing": ("from = 0.0\nto = 1.0\n", "'parameter'"),
    "t_to_missing": ('parameter = "alpha"\nfrom = 0.0\n', "missing key(s) to"),
    "t_unknown_key": (GOOD_TOML + "transient = 5\n", "unknown key(s) transient"),
    "t_mode_bad": (GOOD_TOML + 'mode = "sideways"\n', "'sideways'"),
    "t_mode_int": (GOOD_TOML + "mode = 3\n", "mode = 3"),
    "t_direction_bad": (GOOD_TOML + 'direction = "left"\n', "'left'"),
    "t_starts_continue": (GOOD_TOML + "starts = 4\n", "starts = 4"),
    "t_starts_zero": (GOOD_TOML + 'mode = "multistart"\nstarts = 0\n', "starts = 0"),
    "t_direction_fresh": (GOOD_TOML + 'mode = "fresh"\ndirection = "up"\n', "direction = 'up'"),
    "t_kick_multistart": (GOOD_TOML + 'mode = "multistart"\nkick = 0.2\n', "kick = 0.2"),
    "t_kick_neg": (GOOD_TOML + "kick = -1.0\n", "kick = -1.0"),
    "t_kick_big": (GOOD_TOML + "kick = 7.0\n", "kick = 7.0"),
    "t_rest_str": (GOOD_TOML + 'rest_threshold = "x"\n', "rest_threshold = 'x'"),
    "t_seed_neg": (GOOD_TOML + "seed = -1\n", "seed = -1"),
    "t_seed_float": (GOOD_TOML + "seed = 1.5\n", "seed = 1.5"),
    "t_model_scalar": ("model = 5\n" + GOOD_TOML, "[model] must be a table"),
    "t_model_str": (GOOD_TOML + '[model]\nfe = "fast"\n', "model.fe = 'fast'"),
    "t_model_unknown": (GOOD_TOML + "[model]\nlength = 1.0\n", "'length'"),
    "t_model_swept": (GOOD_TOML + "[model]\nalpha = 10.0\n", "model.alpha = 10.0"),
    "t_model_range": (GOOD_TOML + "[model]\nl = -1.0\n", "l = -1.0"),
    "t_backend_name_int": (GOOD_TOML + "[backend]\nname = 5\n", "backend.name = 5"),
    "t_backend_name_bad": (GOOD_TOML + '[backend]\nname = "warp"\n', "'warp'"),
    "t_backend_option": (GOOD_TOML + "[backend]\nwobble = 1\n", "wobble"),
    "t_backend_list": (GOOD_TOML + "[backend]\ndt = [1]\n", "backend.dt = [1]"),
    "t_backend_dt": (GOOD_TOML + "[backend]\ndt = -1.0\n", "dt = -1.0"),
    "t_output_csv": (GOOD_TOML + 'output = "x.csv"\n', "'x.csv'"),
    "t_output_int": (GOOD_TOML + "output = 5\n", "output = 5"),
    "t_plot_txt": (GOOD_TOML + 'plot = "x.txt"\n', "'x.txt'"),
    "t_description_int": (GOOD_TOML + "description = 5\n", "description = 5"),
    "t_invalid": ("parameter = \n", "not valid TOML"),
}

SWEEP_BASES = {
    "alpha": ["alpha", "--from", "0", "--to", "1"],
    "fe": ["fe", "--from", "2.4", "--to", "2.5"],
    "mass": ["mass", "--from", "5", "--to", "6"],
    "sweep": ["sweep", "K", "--from", "1800", "--to", "1900", "--step", "100"],
}
# Bad options shared by every sweep command: (arguments, text the message must contain).
SWEEP_BAD: list[tuple[list[str], str]] = [
    (["--from", "abc"], "'abc' is not a number"),
    (["--to", "nan"], "'nan' is not finite"),
    (["--to", "inf"], "'inf' is not finite"),
    (["--step", "0"], "non-zero"),
    (["--step", "1e-300"], "--step 1e-300 gives more than"),
    (["--step", "-1"], "wrong sign"),
    (["--points", "0"], "0 is not in the range"),
    (["--points", "2.5"], "'2.5' is not a valid integer"),
    (["--points", "10000000"], "10000000 is not in the range"),
    (["--step", "1", "--points", "3"], "not both"),
    (["--theta0", "1e300"], "'1e300' rad is outside the accepted range"),
    (["--theta0", "nan"], "'nan' is not finite"),
    (["--thetadot0", "1e5"], "'1e5' rad/s is outside"),
    (["--kick", "-1"], "'-1' rad is outside"),
    (["--kick", "4"], "'4' rad is outside"),
    (["--rest-threshold", "-0.1"], "'-0.1' rad is outside"),
    (["--seed", "-1"], "-1 is not in the range"),
    (["--seed", "1.5"], "'1.5' is not a valid integer"),
    (["--seed", "99999999999999999999"], "99999999999999999999 is not in the range"),
    (["--dt", "1e-12"], "'1e-12' s is outside"),
    (["--dt", "10"], "'10' s is outside"),
    (["--transient-periods", "-1"], "-1 is not in the range"),
    (["--transient-periods", "1e9"], "'1e9' is not a valid integer"),
    (["--record-periods", "0"], "0 is not in the range"),
    (["--mode", "multistart", "--starts", "0"], "0 is not in the range"),
    (["--starts", "4"], "--starts 4 applies only to --mode multistart"),
    (["--mode", "fresh", "--direction", "down"], "--direction down applies only to --mode continue"),
    (["--mode", "multistart", "--kick", "0.2"], "--kick 0.2 applies only to --mode continue"),
    (["--mode", "sideways"], "'sideways'"),
    (["--direction", "left"], "'left'"),
    (["--backend", "warp"], "'warp'"),
    (["-B", "wobble=1"], "wobble"),
    (["-B", "signum"], "'signum' must look like NAME=VALUE"),
    (["--set", "length=2"], "'length'"),
    (["--set", "l=0"], "l = 0.0 m"),
    (["--set", "l=abc"], "'abc'"),
    (["--set", "l=nan"], "l=nan: value is not finite"),
    (["--set", "=5"], "'=5' must look like NAME=VALUE"),
    (["--set", "b1"], "'b1' must look like NAME=VALUE"),
    (["--C", "-1"], "C = -1.0"),
    (["--alpha", "1e400"], "'1e400' is not finite"),
    (["--model", "{missing}"], "missing.csv"),
    (["--model", "{model_notjson}"], "model_notjson.json"),
    (["--model", "{model_list}"], "model_list.json"),
    (["--model", "{model_str}"], "alpha = 'five'"),
    (["--model", "{model_unknown}"], "'length'"),
    (["--model", "{model_nan}"], "alpha = nan"),
    (["--model", "{model_range}"], "l = -1.0"),
    (["--model", "{model_binary}"], "model_binary.json"),
    (["--model", "{adir}"], "adir.parquet"),
    (["-o", "out.csv"], "'out.csv' must end in .parquet"),
    (["-o", ""], "'' is not a file name"),
    (["-o", "{adir}"], "is a directory"),
    (["-o", "{blocker}/x.parquet"], "blocker"),
    (["-o", "/proc/pendsweep/x.parquet"], "/proc/pendsweep/x.parquet"),
    (["--plot", "x.txt"], "'x.txt' must end in .png or .pdf or .svg"),
    (["--plot", "{blocker}/x.png"], "blocker"),
    (["--plot", "/proc/pendsweep.png"], "/proc/pendsweep.png"),
    (["-j", "abc"], "'abc' is not a valid integer"),
    (["--executor", "spark"], "'spark'"),
    (["--from", "-1e308", "--to", "1e308", "--step", "1"], "-1e+308"),
    (["--wobble"], "No such option '--wobble'"),
]
# The swept parameter given a fixed value: refused, never stored as if it took effect.
SWEPT_FIXED = [
    (["alpha", "--from", "0", "--to", "1", "--alpha", "10"], "--alpha 10 fixes the swept parameter 'alpha'"),
    (["alpha", "--from", "0", "--to", "1", "--set", "alpha=99"], "--set alpha=99 fixes the swept parameter"),
    (["mass", "--from", "5", "--to", "6", "--M", "3"], "--M 3 fixes the swept parameter 'M'"),
    (["mass", "--from", "5", "--to", "6", "--set", "M=3"], "--set M=3 fixes"),
    (["fe", "--from", "2.4", "--to", "2.5", "--fe", "2.3"], "--fe 2.3 fixes"),
    (["sweep", "K", "--from", "1800", "--to", "1900", "--step", "100", "--K", "5"], "--K 5 fixes"),
    (["sweep", "K", "--from", "1800", "--to", "1900", "--step", "100", "--set", "K=5"], "--set K=5 fixes"),
    (["alpha", "--from", "0", "--to", "1", "--fe", "2", "--set", "fe=2.1"], "--set fe=2.1 both fix fe"),
    (["sweep", "length", "--from", "0", "--to", "1", "--step", "1"], "'length'"),
    (["sweep", "K", "--from", "1800", "--to", "1900"], "'K'"),
]
OTHER: list[tuple[list[str], str]] = [
    # run
    *[(["run", "{" + name + "}"], text) for name, (_, text) in TOML_CASES.items()],
    (["run", "{binary}"], "is not a text (UTF-8) TOML file"),
    (["run", "{latin1}"], "is not a text (UTF-8) TOML file"),
    (["run", "{empty}"], "missing key 'parameter'"),
    (["run", "{adir}"], "adir.parquet"),
    (["run", "fig99"], "'fig99'"),
    (["run", "{missing}"], "missing.csv"),
    (["run"], "give a sweep"),
    (["run", "{hopf}", "-o", "x.parquet"], "is a Hopf scan"),
    (["run", "{trace}", "-o", "x.parquet"], "is a time series from `pendsweep trace`"),
    (["run", "{record}", "-o", "x.parquet"], "is a measured-data record"),
    (["run", "{plain}", "-o", "x.parquet"], "carries no pendsweep metadata"),
    (["run", "{badjson}", "-o", "x.parquet"], "is not valid JSON"),
    (["run", "{listmeta}", "-o", "x.parquet"], "listmeta.parquet"),
    (["run", "{garbage}", "-o", "x.parquet"], "garbage.parquet"),
    (["run", "{emptyparquet}", "-o", "x.parquet"], "emptyparquet.parquet"),
    (["run", "{sweepbogus}", "-o", "x.parquet"], "bogus"),
    (["run", "{sweep}"], "needs -o/--output"),
    (["run", "{sweep}", "-o", "{sweep}"], "is the results file being regenerated"),
    (["run", "{good}", "-o", "out.csv"], "'out.csv' must end in .parquet"),
    (["run", "{good}", "-o", ""], "'' is not a file name"),
    (["run", "{good}", "-o", "{blocker}/x.parquet"], "blocker"),
    (["run", "{good}", "-j", "abc"], "'abc'"),
    # plot
    (["plot", "{hopf}"], "is a Hopf scan"),
    (["plot", "{trace}"], "is a time series"),
    (["plot", "{record}"], "is a measured-data record"),
    (["plot", "{plain}"], "carries no pendsweep metadata"),
    (["plot", "{badjson}"], "is not valid JSON"),
    (["plot", "{garbage}"], "garbage.parquet"),
    (["plot", "{emptyparquet}"], "emptyparquet.parquet"),
    (["plot", "{missing}"], "missing.csv"),
    (["plot", "{adir}"], "adir.parquet"),
    (["plot", "{sweep}", "-o", "x.txt"], "'x.txt' must end in"),
    (["plot", "{sweep}", "-o", "{blocker}/x.png"], "blocker"),
    (["plot", "{sweep}", "--observable", "speed"], "'speed'"),
    (["plot", "{model_list}"], "is not a continuation result"),
    (["plot", "{model_binary}"], "is not a text (UTF-8) JSON file"),
    (["plot", "{model_notjson}"], "is not valid JSON"),
    # figures
    (["figures", "fig99"], "fig99"),
    (["figures", "fig8", "-o", "{blocker}"], "blocker"),
    (["figures", "fig8", "-o", "{blocker}/sub"], "blocker"),
    (["figures", "fig8", "-o", ""], "''"),
    (["figures", "fig8", "-o", "/proc/pendsweep-figures"], "/proc/pendsweep-figures"),
    # params, unknown command
    (["params", "extra"], "unexpected extra argument (extra)"),
    (["nosuch"], "No such command 'nosuch'"),
    # continue
    (["continue", "wobble", "--from", "0", "--to", "1"], "'wobble'"),
    (["continue", "alpha", "--from", "abc", "--to", "1"], "'abc' is not a number"),
    (["continue", "alpha", "--from", "0", "--to", "nan"], "'nan' is not finite"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--alpha", "5"], "alpha is the continued parameter"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--set", "alpha=5"], "alpha is the continued parameter"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--fe", "2", "--set", "fe=2.1"], "both fix fe"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--set", "l=abc"], "'abc'"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--model", "{model_str}"], "alpha = 'five'"),
    (["continue", "alpha", "--from", "0", "--to", "1", "-o", "x.txt"], "'x.txt' must end in .json"),
    (["continue", "alpha", "--from", "0", "--to", "1", "-o", "{blocker}/x.json"], "blocker"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--json", "x.txt"], "'x.txt' must end in .json"),
    (
        ["continue", "alpha", "--from", "0", "--to", "1", "-o", "a.json", "--json", "b.json"],
        "give the result file once",
    ),
    (["continue", "alpha", "--from", "0", "--to", "1", "--plot", "x.txt"], "'x.txt' must end in"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--overlay", "{hopf}"], "is a Hopf scan"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--start", "{missing}"], "missing.csv"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--start-value", "5"], "--start-value needs --start FILE"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--max-points", "0"], "0 is not in the range"),
    # curve, tolerance
    (["curve", "{missing}", "--second", "fe", "--from", "2", "--to", "3"], "missing.csv"),
    (["curve", "{garbage}", "--second", "fe", "--from", "2", "--to", "3"], "garbage.parquet"),
    (["curve", "{model_binary}", "--second", "fe", "--from", "2", "--to", "3"], "not a readable UTF-8"),
    (["curve", "{model_list}", "--second", "fe", "--from", "2", "--to", "3"], "not a continuation result"),
    (["curve", "{cont_noconfig}", "--second", "fe", "--from", "2", "--to", "3"], "'parameter'"),
    (["curve", "{cont_badbif}", "--second", "fe", "--from", "2", "--to", "3"], "value 'x'"),
    (["curve", "{cont}", "--second", "fe", "--from", "nan", "--to", "3"], "'nan' is not finite"),
    (["curve", "{cont}", "--second", "fe", "--from", "2", "--to", "3", "--max-points", "0"], "0 is not in the range"),
    (["curve", "{cont}", "--second", "fe", "--from", "2", "--to", "3", "--ds", "5"], "ds = 5"),
    (["curve", "{cont}", "--second", "fe", "--from", "2", "--to", "3", "--limits", "20", "10"], "--limits 20 10"),
    (["curve", "{cont}", "--second", "fe", "--from", "2", "--to", "3", "-o", "x.txt"], "'x.txt' must end in"),
    (["curve", "{cont}", "--second", "fe", "--from", "2", "--to", "3", "--plot", "x.txt"], "'x.txt' must end in"),
    (["curve", "{cont}", "--second", "M", "--from", "-2", "--to", "3"], "M"),
    (["tolerance", "{missing}"], "missing.csv"),
    (["tolerance", "{cont}", "--orders", "a,b"], "--orders 'a,b'"),
    (["tolerance", "{cont}", "--orders", "1,1"], "each order once"),
    (["tolerance", "{cont}", "--within", "0"], "--within 0"),
    (["tolerance", "{cont}", "--delay-to", "5"], "--delay-to 5"),
    (["tolerance", "{cont}", "-B", "servo_bandwidth=fast"], "servo_bandwidth='fast'"),
    (["tolerance", "{cont}", "-B", "nonsense=1"], "nonsense"),
    (["tolerance", "{cont}", "--delay-step", "0"], "--delay-step 0"),
    (["tolerance", "{cont_badbif}"], "value 'x'"),
    (["tolerance", "{cont}", "-o", "x.csv"], "'x.csv' must end in"),
    # basins, map
    (["basins", "--alpha", "40", "--samples", "abc"], "'abc' is not a valid integer"),
    (["basins", "--alpha", "40", "--grid", "0x5"], "--grid '0x5'"),
    (["basins", "--alpha", "40", "--grid", "ax5"], "--grid 'ax5'"),
    (["basins", "--alpha", "40", "--theta", "1:0"], "--theta '1:0'"),
    (["basins", "--alpha", "40", "--backend", "warp"], "'warp'"),
    (["basins", "--alpha", "40", "--set", "length=1"], "'length'"),
    (["basins", "wobble", "--from", "0", "--to", "1"], "'wobble'"),
    (["basins", "alpha", "--from", "0", "--to", "1", "--step", "0.5", "--alpha", "3"], "drop its fixed value 3.0"),
    (["basins", "--from", "0"], "need a PARAMETER"),
    (["map", "alpha", "alpha"], "both are 'alpha'"),
    (["map", "alpha", "fe", "--alpha", "0:45:2"], "give the fe axis"),
    (["map", "alpha", "wobble", "--alpha", "0:45:2"], "'wobble'"),
    # hopf
    (["hopf", "--what", "abc"], "--what = 'abc'"),
    (["hopf", "--what", ""], "--what = ''"),
    (["hopf", "--what", "1:2"], "--what = '1:2'"),
    (["hopf", "--what", "1:2:0"], "N = 0"),
    (["hopf", "--what", "1:2:2.5"], "'1:2:2.5'"),
    (["hopf", "--what", "1:2:10000000"], "N = 10000000"),
    (["hopf", "--what", "0"], "omega_hat = 0.0"),
    (["hopf", "--what", "-1"], "omega_hat = -1.0"),
    (["hopf", "--what", "nan"], "omega_hat = nan"),
    (["hopf", "--what", "1.1", "--M", "0"], "M = 0.0"),
    (["hopf", "--what", "1.1", "--M", "abc"], "--M = 'abc'"),
    (["hopf", "--what", "1.1", "--method", "guess"], "guess"),
    (["hopf", "--what", "1.1", "--method", ","], "methods"),
    (["hopf", "--what", "1.1", "--set", "alpha=5"], "--set alpha=5 is ignored by a Hopf scan"),
    (["hopf", "--what", "1.1", "--set", "fe=2"], "--set fe=2 is ignored"),
    (["hopf", "--what", "1.1", "--set", "M=3"], "--set M=3 is ignored"),
    (["hopf", "--what", "1.1", "--set", "l=0"], "l = 0.0 m"),
    (["hopf", "--what", "1.1", "--set", "l"], "'l' must look like NAME=VALUE"),
    (["hopf", "--what", "1.1", "--kick", "0"], "'0' rad is outside"),
    (["hopf", "--what", "1.1", "--kick", "10"], "'10' rad is outside"),
    (["hopf", "--what", "1.1", "--periods", "1"], "1 is not in the range"),
    (["hopf", "--what", "1.1", "--tol", "0"], "'0' N is outside"),
    (["hopf", "--what", "1.1", "--alpha-max", "-1"], "'-1' N is outside"),
    (["hopf", "--what", "1.1", "-o", "x.csv"], "'x.csv' must end in .parquet"),
    (["hopf", "--what", "1.1", "-o", ""], "'' is not a file name"),
    (["hopf", "--what", "1.1", "-o", "{blocker}/x.parquet"], "blocker"),
    (["hopf", "--what", "1.1", "-B", "wobble=1"], "wobble"),
    (["hopf", "--what", "1.1", "--backend", "warp"], "'warp'"),
    (["hopf", "--what", "1.1", "--executor", "spark"], "'spark'"),
    # trace
    (["basins", "--alpha", "40", "--grid", "100000x100000"], "GiB of memory"),
    (["basins", "--alpha", "40", "--grid", "100x100", "--max-work", "1e6"], "pass --max-work 4e9"),
    (["map", "alpha", "fe", "--alpha", "0:45:100000", "--fe", "2:3:100000"], "GiB of memory"),
    (["synth", "s.csv", "--duration", "1e5", "--rate", "1e6"], "GiB of memory, more than this machine's"),
    (["trace", "t.parquet", "--periods", "100000", "--fe", "0.5"], "GiB of memory, more than this machine's"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--max-points", "1000000000"], "pass --max-work"),
    (["continue", "alpha", "--from", "0", "--to", "1", "--max-period", "1000000"], "pass --max-work"),
    (["site", "--port", "70000"], "70000 is not in the range"),
    (["site", "-B", "seed=-1"], "seed = -1"),
    (["site", "-o", "{blocker}/log.parquet"], "blocker"),
    (["site", "--host", "256.1.1.1", "--port", "0"], "--host '256.1.1.1' is not an address"),
    (["site", "--port", "-1"], "-1 is not in the range"),
    (["site", "--timeout", "nan"], "'nan' is not finite"),
    (["site", "--timeout", "0"], "'0' s is outside"),
    (["site", "--theta0", "1e300"], "'1e300' rad is outside"),
    (["site", "--thetadot0", "inf"], "'inf' is not finite"),
    (["site", "-o", "log.csv"], "'log.csv' must end in .parquet"),
    (["site", "--set", "m=-1"], "m = -1"),
    (["site", "--set", "bogus=1"], "'bogus'"),
    (["site", "-B", "predictor_order=1"], "predictor_order: not an option of the rig"),
    (["site", "-B", "actuator=magic"], "actuator = 'magic'"),
    (["site", "-B", "report_mass=maybe"], "report_mass='maybe'"),
    (["site", "-B", "force_limit=nan"], "-B force_limit=nan N"),
    (["site", "-B", "velocity_limit=0"], "-B velocity_limit=0.0 m/s"),
    (["site", "-B", "stroke=-1"], "stroke = -1.0 m"),
    (["site", "-B", "noequals"], "must look like NAME=VALUE"),
    (["wait"], "Missing argument 'tcp://HOST:PORT'"),
    (["wait", "udp://127.0.0.1:8090"], "URL 'udp://127.0.0.1:8090'; give tcp://HOST:PORT"),
    (["wait", "tcp://127.0.0.1"], "URL 'tcp://127.0.0.1'; give tcp://HOST:PORT"),
    (["wait", "tcp://127.0.0.1:99999"], "URL 'tcp://127.0.0.1:99999'; give tcp://HOST:PORT"),
    (["wait", "tcp://127.0.0.1:8090", "--timeout", "nan"], "'nan' is not finite"),
    (["warmup", "--jobs", "2"], "No such option '--jobs'"),
    (["wait", "tcp://127.0.0.1:8090", "--timeout", "-1"], "'-1' s is outside"),
    (["trace", "x.csv"], "'x.csv' must end in .parquet"),
    (["trace", ""], "'' is not a file name"),
    (["trace", "{blocker}/x.parquet"], "blocker"),
    (["trace", "{adir}"], "is a directory"),
    (["trace", "t.parquet", "--theta0", "1e300"], "'1e300' rad is outside"),
    (["trace", "t.parquet", "--thetadot0", "1e9"], "'1e9' rad/s is outside"),
    (["trace", "t.parquet", "--y0", "100"], "'100' m is outside"),
    (["trace", "t.parquet", "--alpha", "nan"], "'nan' is not finite"),
    (["trace", "t.parquet", "--alpha", "5", "--set", "alpha=4"], "--alpha 5 and --set alpha=4 both fix alpha"),
    (["trace", "t.parquet", "--periods", "0"], "0 is not in the range"),
    (["trace", "t.parquet", "--stride", "0"], "0 is not in the range"),
    (["trace", "t.parquet", "--transient-periods", "-1"], "-1 is not in the range"),
    (["trace", "t.parquet", "--backend", "warp"], "'warp'"),
    (["trace", "t.parquet", "-B", "wobble=1"], "wobble"),
    (["trace", "t.parquet", "--set", "l=-1"], "l = -1.0"),
    (["trace", "t.parquet", "--fe", "0"], "fe = 0.0"),
    # sync
    (["sync", "{missing}"], "missing.csv"),
    (["sync", "{adir}"], "adir.parquet"),
    (["sync", "{hopf}"], "'hopf'"),
    (["sync", "{garbage}"], "garbage.parquet"),
    (["sync", "{badjson}"], "is not valid JSON"),
    (["sync", "{hopf}", "-o", "x.txt"], "'x.txt' must end in"),
    (["sync", "{hopf}", "--window", "0"], "0"),
    (["sync", "{hopf}", "--reference", "Z"], "'Z'"),
    # margin
    (["margin", "--dt", "10"], "'10' s is outside"),
    (["margin", "--dt", "0"], "'0' s is outside"),
    (["margin", "--M1", "0"], "'0' kg is outside"),
    (["margin", "--K", "-1"], "'-1' N/m is outside"),
    (["margin", "--C1", "nan"], "'nan' is not finite"),
    (["margin", "--servo-bandwidth", "0"], "'0' Hz is outside"),
    (["margin", "--servo-damping", "-1"], "'-1' is outside"),
    (["margin", "--predictor", "1"], "--predictor '1'"),
    (["margin", "--predictor", "a,b"], "--predictor 'a,b'"),
    (["margin", "--predictor", "1,nan"], "--predictor '1,nan'"),
    (["margin", "--predictor", "1,5", "--tau-hat", "soon"], "--tau-hat 'soon'"),
    (["margin", "--predictor", "1,5", "--tau-hat", "5"], "--tau-hat '5'"),
    (["margin", "--tau-hat", "0.01"], "--tau-hat needs --predictor"),
    (["margin", "--filter-band", "1"], "--filter-band '1'"),
    (["margin", "--filter-band", "1,inf"], "--filter-band '1,inf'"),
    (["margin", "--filter-order", "9"], "9 is not in the range"),
    (["margin", "--tau-max", "0"], "'0' s is outside"),
    (["margin", "--roots-at", "-1"], "'-1' s is outside"),
    (["margin", "--plot", "x.txt"], "'x.txt' must end in"),
    (["margin", "--plot", "/proc/pendsweep.png"], "/proc/pendsweep.png"),
    (["margin", "--actuator", "magic"], "'magic'"),
    # diagnose
    (["diagnose", "{missing}"], "missing.csv"),
    (["diagnose", "{adir}"], "adir.parquet"),
    (["diagnose", "{rec_empty}"], "rec_empty.csv"),
    (["diagnose", "{rec_binary}"], "is not a text (UTF-8) file"),
    (["diagnose", "{rec_latin1}"], "is not a text (UTF-8) file"),
    (["diagnose", "{rec_nosidecar}"], "has no metadata sidecar"),
    (["diagnose", "{rec_good}", "--json", "{rec_good_sidecar}"], "would overwrite the input"),
    (["fit-damping", "{rec_good}", "--params-out", "{rec_good_sidecar}"], "would overwrite the input"),
    (["diagnose", "{rec_params_list}"], "metadata 'params' must be a JSON object"),
    (["diagnose", "{rec_params_str}"], "params.m = 'heavy'"),
    (["diagnose", "{rec_alpha_str}"], "forcing.alpha = 'loud'"),
    (["diagnose", "{rec_forcing_list}"], "metadata 'forcing' must be a JSON object"),
    (["diagnose", "{rec_tau_str}"], "params.tau = 'late'"),
    (["diagnose", "{rec_sidecar_bad}"], "rec_sidecar_bad.json"),
    (["diagnose", "{rec_sidecar_binary}"], "rec_sidecar_binary.json"),
    (["diagnose", "{rec_sidecar_list}"], "metadata must be a JSON object"),
    (["diagnose", "{rec_kind}"], "'wobbly'"),
    (["diagnose", "{rec_nokind}"], "no 'kind'"),
    (["diagnose", "{rec_textcol}"], "column 'theta' holds non-numeric values"),
    (["diagnose", "{rec_nan}"], "column 'theta' has 1 NaN/inf"),
    (["diagnose", "{rec_short}"], "2 samples"),
    (["diagnose", "{rec_nocol}"], "missing column(s) theta"),
    (["diagnose", "{rec_ragged}"], "line 3 has 3 fields"),
    (["diagnose", "{rec_time}"], "not strictly increasing"),
    (["diagnose", "{garbage}"], "garbage.parquet"),
    (["diagnose", "{badjson}"], "is not valid JSON"),
    (["diagnose", "{hopf}"], "'hopf'"),
    (["diagnose", "{fs_bad}"], "fs_bad.txt"),
    (["diagnose", "{fs_rate}"], "sample_rate = -5.0"),
    (["diagnose", "{rec_good}", "--json", "x.txt"], "'x.txt' must end in .json"),
    (["diagnose", "{rec_good}", "--json", "{blocker}/x.json"], "blocker"),
    (["diagnose", "{rec_good}", "--report", "{blocker}"], "is a file"),
    (["diagnose", "{rec_good}", "--folds", "1"], "1 is not in the range"),
    (["diagnose", "{rec_good}", "{rec_binary}"], "is not a text (UTF-8) file"),
    (["diagnose", "{rec_good}", "--horizon", "0"], "'0' s is outside"),
    (["diagnose", "{rec_good}", "-j", "0"], "--jobs = 0: give a number of workers from 1 to 1024"),
    (["diagnose", "{rec_good}", "--max-work", "0"], "'0' steps is outside the accepted range"),
    (["diagnose", "{rec_good}", "--max-work", "nan"], "'nan' is not finite"),
    (["alpha", "--from", "0", "--to", "45", "--max-work", "nan"], "'nan' is not finite"),
    (["basins", "--alpha", "40", "--grid", "10x10", "--max-work", "inf"], "'inf' is not finite"),
    (["hopf", "--what", "1", "--method", "analytic,analytic"], "--method lists analytic twice"),
    (["trace", "t.parquet", "--periods", "100", "--max-work", "10"], "this trace needs about"),
    (["alpha", "--from", "1e308", "--to", "-1e308", "--points", "3"], "spans more than a float holds"),
    (
        ["hopf", "--what", "1:2:1000", "--method", "floquet", "--max-work", "1e6"],
        "needs about 2e+07 integration steps,",
    ),
    (["hopf", "--what", "1", "--method", "analytic", "--set", "l=1e-300"], "l = 1e-300 m is outside"),
    (["basins", "--alpha", "40", "--backend", "substructured", "--grid", "1000x1000"], "more than the limit of 1e+11"),
    (["map", "alpha", "fe", "--alpha", "10:30:4", "--fe", "2.2:2.6:4", "--theta0", "1e300"], "'1e300' rad is outside"),
    (["hopf", "--what", "1:2:1000", "--max-work", "10"], "pass --max-work"),
    (["diagnose", "{rec_good}", "--model", "{model_notjson}"], "model_notjson.json"),
    (["diagnose", "{rec_good}", "--model", "{model_str}"], "alpha = 'five'"),
    # fit-damping
    (["fit-damping", "{missing}"], "missing.csv"),
    (["fit-damping", "{rec_empty}"], "rec_empty.csv"),
    (["fit-damping", "{rec_binary}"], "is not a text (UTF-8) file"),
    (["fit-damping", "{rec_params_list}"], "metadata 'params' must be a JSON object"),
    (["fit-damping", "{rec_alpha_str}"], "forcing.alpha = 'loud'"),
    (["fit-damping", "{rec_good}", "{missing}"], "missing.csv"),
    (["fit-damping", "{rec_good}", "--json", "x.txt"], "'x.txt' must end in .json"),
    (["fit-damping", "{rec_good}", "--params-out", "x.txt"], "'x.txt' must end in .json"),
    (["fit-damping", "{rec_good}", "--plot", "x.txt"], "'x.txt' must end in"),
    (["fit-damping", "{rec_good}", "--mass", "0"], "'0' kg is outside"),
    (["fit-damping", "{rec_good}", "--skip", "11"], "11 is not in the range"),
    # synth
    (["synth", "x.txt"], "'x.txt' must end in .csv or .parquet"),
    (["synth", ""], "'' is not a file name"),
    (["synth", "{blocker}/x.csv"], "blocker"),
    (["synth", "s.csv", "--kind", "wobbly"], "'wobbly'"),
    (["synth", "s.csv", "--effect", "viscous_damping"], "'viscous_damping' must look like NAME=VALUE"),
    (["synth", "s.csv", "--effect", "viscous_damping=abc"], "'abc' is not a number"),
    (["synth", "s.csv", "--effect", "viscous_damping=nan"], "'nan' is not finite"),
    (["synth", "s.csv", "--set", "l=0"], "l = 0.0 m"),
    (["synth", "s.csv", "--set", "length=1"], "'length'"),
    (["synth", "s.csv", "--param", "l=0"], "l = 0.0 m"),
    (["synth", "s.csv", "--duration", "0"], "'0' s is outside"),
    (["synth", "s.csv", "--rate", "0"], "'0' Hz is outside"),
    (["synth", "s.csv", "--seed", "-1"], "-1 is not in the range"),
    (["synth", "s.csv", "--theta0", "1e300"], "'1e300' rad is outside"),
    (["synth", "s.csv", "--theta-init", "1e300"], "'1e300' rad is outside"),
    (["synth", "s.csv", "--thetadot0", "1e9"], "'1e9' rad/s is outside"),
    (["synth", "s.csv", "--transient", "-1"], "'-1' s is outside"),
    (["synth", "s.csv", "--tone2", "1", "nan"], "'nan' is not finite"),
    (["synth", "s.csv", "--theta0", "1", "--theta-init", "1"], "give --theta0 once"),
]
TABLE = [(base + bad, text) for base in SWEEP_BASES.values() for bad, text in SWEEP_BAD] + SWEPT_FIXED + OTHER


def test_table_is_large_and_covers_every_subcommand():
    assert len(TABLE) >= 200
    covered = {args[0] for args, _ in TABLE}
    assert set(main.commands) <= covered, set(main.commands) - covered


@pytest.mark.parametrize("args, text", TABLE, ids=[" ".join(a)[:60] for a, _ in TABLE])
def test_malformed_invocation_exits_2_naming_the_value(args, text, files, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # relative outputs (t.parquet, s.csv) land in a scratch folder
    argv = [a.format(**files) if "{" in a else a for a in args]
    text = text.format(**files) if "{" in text else text
    r = CliRunner().invoke(main, argv)
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    assert "Traceback" not in r.output
    assert r.exit_code == 2, r.output
    assert text in r.output, r.output
    assert len([line for line in r.output.splitlines() if line.startswith("Error")]) == 1, r.output
    assert not any(tmp_path.iterdir()), "a refused command must not leave files behind"


# -- property-based fuzzing of the two hand-written inputs -------------------------------------------------------------
_toml_scalars = st.one_of(
    st.integers(-3, 300),
    st.sampled_from([0.0, 0.5, 1.0, 2.5, -1.0, 1e-300, 1e300, float("nan"), float("inf")]),
    st.booleans(),
    st.sampled_from(["alpha", "fe", "M", "K", "continue", "fresh", "multistart", "up", "both", "x", "", "out.parquet"]),
)
_toml_values = st.one_of(_toml_scalars, st.lists(_toml_scalars, max_size=5))
_keys = st.sampled_from(
    ["parameter", "from", "to", "step", "points", "values", "mode", "direction", "transient_periods",
     "record_periods", "initial", "kick", "rest_threshold", "starts", "seed", "output", "plot", "description",
     "model", "backend", "bogus"]
)  # fmt: skip


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    data=st.dictionaries(_keys, _toml_values, max_size=10),
    model=st.dictionaries(st.sampled_from(["alpha", "fe", "M", "l", "bogus"]), _toml_scalars, max_size=3),
    backend=st.dictionaries(st.sampled_from(["name", "dt", "signum", "bogus"]), _toml_values, max_size=2),
)
def test_toml_loader_accepts_or_names_the_problem(data, model, backend):
    """Any table of TOML-able values loads, or raises the package's one-line error; nothing else escapes."""
    from pendsweep.studies.sweepfile import parse_sweep

    data = dict(data)
    if "model" in data:
        data["model"] = model
    if "backend" in data:
        data["backend"] = backend
    data.pop("transient_periods", None), data.pop("record_periods", None)  # keep accepted sweeps cheap to build
    try:
        spec = parse_sweep(data, "fuzz.toml")
    except PendsweepError as exc:
        assert str(exc) and "\n" not in str(exc)
    else:
        assert spec.config.parameter == data["parameter"] and len(spec.config.values) >= 1


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=400))
def test_toml_file_of_arbitrary_bytes(blob):
    from pendsweep.studies.sweepfile import load_sweep

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s.toml"
        path.write_bytes(blob)
        try:
            load_sweep(path)
        except PendsweepError as exc:
            assert "\n" not in str(exc).strip() or "TOML" in str(exc)


_json = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), st.text(max_size=5)),
    lambda inner: st.one_of(st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=6), inner, max_size=3)),
    max_leaves=8,
)
_sidecar = st.one_of(
    _json,
    st.fixed_dictionaries(
        {"format": st.just(1), "kind": st.sampled_from(["free_decay", "forced", "substructured", "x"])},
        optional={"params": st.one_of(_json, st.dictionaries(st.sampled_from(["m", "l", "tau", "alpha", "zz"]), _json, max_size=3)),
                  "forcing": st.one_of(_json, st.dictionaries(st.sampled_from(["alpha", "fe", "zz"]), _json, max_size=2))},
    ),
)  # fmt: skip
_csv = st.one_of(
    st.binary(max_size=200),
    st.text(max_size=200).map(str.encode),
    st.lists(st.tuples(st.floats(-1, 10), st.floats(allow_nan=True, allow_infinity=True)), max_size=12).map(
        lambda rows: ("t,theta\n" + "".join(f"{a!r},{b!r}\n" for a, b in rows)).encode()
    ),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(csv=_csv, sidecar=st.one_of(_sidecar.map(lambda v: json.dumps(v).encode()), st.binary(max_size=60)))
def test_measured_record_reader_accepts_or_names_the_problem(csv, sidecar):
    """Arbitrary CSV bytes with an arbitrary sidecar: a valid Record or the package's one-line error."""
    from pendsweep.measured.records import read_record

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "r.csv"
        path.write_bytes(csv)
        path.with_suffix(".json").write_bytes(sidecar)
        try:
            record = read_record(path)
        except PendsweepError as exc:
            assert str(exc)
        else:
            assert len(record.data) >= 3 and record.data["t"].is_monotonic_increasing
