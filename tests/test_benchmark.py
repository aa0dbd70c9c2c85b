"""``jaxheli bench``: its NumPy baseline agrees with the library's cost, and a quick run writes its files."""

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxheli.benchmark.baseline import numpy_cost
from jaxheli.benchmark.throughput import bench_flight, candidates, flops_per_candidate
from jaxheli.cli import build_parser
from jaxheli.model import TABLE2
from jaxheli.sim.population import population_cost

ROOT = Path(__file__).resolve().parents[1]


def test_numpy_baseline_is_the_same_cost():
    """The baseline must compute what the kernels compute, or the ratios compare different work."""
    flight = bench_flight(400)
    thetas = np.concatenate([TABLE2[None], np.asarray(candidates(3, np.float64))])
    ours = np.asarray(population_cost(thetas, flight, method="scan"))
    theirs = np.array([numpy_cost(t, flight) for t in thetas])
    np.testing.assert_allclose(theirs, ours, rtol=1e-7, atol=1e-9)
    assert ours[0] < 0.01  # the flight was made by Table 2


def test_flop_count_is_dominated_by_the_recurrence():
    assert 4.0e6 < flops_per_candidate(8590) < 4.5e6  # 8590 x (2*13*13 + 2*13*4 + 24) + expm


def test_quick_bench_writes_json_markdown_and_plot(tmp_path):
    # In a process of its own, as a user runs it: late in a full `-n 2` suite run, XLA's compile of the IWO
    # chunk segfaulted in a worker that had compiled many other programs (not reproduced in a fresh process).
    run = subprocess.run([sys.executable, "-m", "jaxheli", "bench", "--quick", "--host-devices", "2", "--out",
                          str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    result = json.loads((tmp_path / "bench.json").read_text())
    assert {(r["N"], r["P"]) for r in result["rates"]} == {(300, 16), (300, 64)}
    for row in result["rates"]:
        assert row["blocked"] > 0 and row["scan"] > 0 and row["numpy"] > 0 and row["flop_limit"] > row["blocked"]
    experiment = result["experiment"]
    assert experiment["trials"] == 2 and experiment["iterations"] == 3 and len(experiment["best_cost"]) == 2
    assert experiment["trials"] * 20 < experiment["evaluations"] < experiment["buffer_slots"]  # padding not scored
    pem_row, iwo_row = result["time_to_model"]
    assert pem_row["method"] == "pem" and pem_row["steps"] <= 3 and pem_row["rss"] <= pem_row["rss_start"]
    assert pem_row["numpy_simulations"] == pem_row["steps"] * 36  # 35 free parameters + 1
    assert iwo_row["method"] == "iwo+polish" and iwo_row["samples"] == 300 and iwo_row["numpy_ratio"] > 0
    assert set(iwo_row["fit_percent"]) >= {"p", "q", "phi", "theta"} and all(r["seconds"] > 0 for r in (pem_row, iwo_row))
    # each in a fresh process with JAX's default devices, not the bench's --host-devices
    assert pem_row["devices"] == iwo_row["devices"] == 1 and iwo_row["numpy_simulations"] > 0
    # the fresh processes report their stages as the bench does: the user is told what is being timed
    assert "time to a model: iwo+polish in a fresh process" in run.stderr
    assert "polish" in run.stderr.split("time to a model: iwo+polish")[1]
    costs = result["costs"]
    assert costs["N"] == 300 and costs["P"] == 40 and len(costs["rows"]) == 5
    assert costs["rows"][0]["ratio"] == 1.0 and all(r["rate"] > 0 for r in costs["rows"])
    assert any("Tischler" in r["cost"] for r in costs["rows"]) and any("5 s runs" in r["cost"] for r in costs["rows"])
    text = (tmp_path / "bench.md").read_text()
    assert "blocked x NumPy" in text and "paper's whole experiment" in text and "Time to a model" in text
    assert "Each method in a fresh process" in text
    assert "Costs the engines minimise" in text
    assert (tmp_path / "throughput.png").stat().st_size > 10_000
    forms = result["time_forms"]  # the plain scan against the parallel form in time, and the table they select
    rows = {(r["path"], r["N"], r["steps"]) for r in forms["rows"]}
    assert rows == {("population", 300, 18), ("recursion", 300, 299)}
    assert all(r["scan_s"] > 0 and r["parallel_s"] > 0 and r["difference"] < 1e-4 for r in forms["rows"])
    assert set(forms["selection"]) == {"cpu"} and set(forms["selection"]["cpu"]) == {"population", "recursion"}
    assert experiment["time_form"] == "auto" and experiment["resolved_form"] == "scan"  # the table's CPU row
    assert iwo_row["time_form"] == "auto" and "plain scan against the parallel form" in text


def _script(name):
    """The module of ``benchmarks/<name>.py``."""
    spec = importlib.util.spec_from_file_location(f"{name}_script", ROOT / "benchmarks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_identification_recipes_map_to_identify_options():
    """Each part of a recipe of benchmarks/identification.py sets its identify option, and only that one; an unknown
    or repeated part is refused."""
    recipes = _script("identification")
    default = recipes.recipe_options("default", None, 50.0)
    assert set(default) == {"lower", "upper"}
    both = recipes.recipe_options("full+zoh", None, 50.0)
    assert both["hold"] == "zoh" and both["fit_dt"] == "full" and set(both) == {"lower", "upper", "hold", "fit_dt"}
    assert np.array_equal(both["lower"], default["lower"])
    assert "hold" not in recipes.recipe_options("full", None, 50.0)
    for bad in ("fast", "zoh+zoh"):
        with pytest.raises(ValueError, match="recipe"):
            recipes.recipe_options(bad, None, 50.0)


def test_identification_spread_over_seeds():
    """benchmarks/identification.py's table over seeds: each held-out score's median and range over the seeds of one
    training record, recipe, method and validation record, numpy's median of the rows; nothing with one seed."""
    recipes = _script("identification")

    def row(seed, shift):
        scores = {m: {c: shift + i for i, c in enumerate(recipes.REAL_CHANNELS)} for m in ("pearson", "fit_percent")}
        return {"train": "A", "recipe": "default", "method": "m", "validate": "C", "sample": "held out",
                "seed": seed, "runs": scores}

    assert recipes._spread_table([row(0, 0.1)]) == ""
    table = recipes._spread_table([row(0, 0.1), row(1, 0.5), row(2, 0.2)])
    line = next(x for x in table.splitlines() if x.startswith("| A |"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[:6] == ["A", "default", "m", "C", "held out", "3"]
    assert cells[6] == f"{np.median([0.1, 0.5, 0.2]):.3f} [0.100, 0.500]"
    assert cells[6 + len(recipes.REAL_CHANNELS)] == "0.2 [0.1, 0.5]"


@pytest.mark.parametrize("sizes", ["FULL", "TINY"])
def test_gpu_script_steps_are_valid_commands(sizes):
    """Every command benchmarks/gpu.py runs parses with jaxheli's own parser (a typo would cost a GPU run)."""
    gpu = _script("gpu")
    steps = getattr(gpu, sizes)
    assert set(steps) == set(gpu.CAPS) - {"install"}
    for name, arguments in steps.items():
        command = (["identify", *arguments, "--quiet"] if name.startswith("main-job") else
                   ["bench", *gpu.QUIET_BENCH, *arguments] if name != "throughput" else ["bench", *arguments])
        args = build_parser().parse_args(command + ["--out", "x"])
        assert args.func is not None
