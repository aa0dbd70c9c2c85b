"""identify as a chain of stages: every named method is a chain of the one table, every option keyword lands on
the stages that use it, and one that the chain does not use is refused (by identify and by the command line)
before anything runs."""

import re

import numpy as np
import pytest

from jaxheli.benchmark.throughput import bench_flight
from jaxheli.cli import build_parser, main
from jaxheli.cli.identify import _FREQ_OPTIONS, _KEYWORDS, _identify_options
from jaxheli.identify import identify
from jaxheli.model import LOWER, TABLE2, UPPER
from jaxheli.stages import (CHAINS, KEYWORDS, METHODS, PEM, FrequencyFit, Polish, Search, Structure, check_chain,
                            method_chain, uses)

SAMPLES = {
    "outputs": ("p", "q"), "segment": 2.0, "hold": "foh", "g": 9.8, "lower": LOWER, "upper": UPPER,
    "cost": "output-error", "search_precision": "float64", "iterations": 3, "engine_options": {"sigma_final": 0.002},
    "chunk": 5, "checkpoint": "run.eqx", "resume": True, "progress": False, "start": TABLE2, "pem_segment": 4.0,
    "freq_options": {"starts": 2}, "polish_objective": "pem", "polish_steps": 3, "polish_rounds": 2,
    "cv_windows": 2, "prior": "table2", "prior_sd": 20.0, "structure": True,
}
"""A value of every option keyword (one the option's stages accept)."""

IGNORED_BEFORE = {
    "pem": ["iterations", "engine_options", "chunk", "checkpoint", "resume", "progress"],
    "freq": ["iterations", "engine_options", "chunk", "checkpoint", "resume", "progress", "polish_steps"],
    "iwo": ["start", "freq_options", "pem_segment", "polish_steps", "polish_rounds"],
    "ga": ["start", "freq_options", "pem_segment", "polish_steps", "polish_rounds"],
    "iwo+polish": ["start", "freq_options", "pem_segment"],
    "iwo+freq+polish": ["start", "pem_segment"],
}
"""Options identify once accepted and ignored with these methods: now refused."""


def test_the_table_covers_every_keyword_and_method():
    assert set(SAMPLES) == set(KEYWORDS) and set(METHODS) == set(CHAINS)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("keyword", sorted(KEYWORDS))
def test_an_option_is_used_by_the_chain_or_refused(method, keyword):
    options = {keyword: SAMPLES[keyword], **({"prior": "table2"} if keyword == "prior_sd" else {})}
    if not uses(method, keyword):
        refusal = f"identify: method '{method}' does not use '{keyword}' (used by: "
        with pytest.raises(ValueError, match=re.escape(refusal)) as e:
            method_chain(method, options)
        assert "\n" not in str(e.value) and method not in str(e.value).split("used by: ")[1].split(", ")
        return
    name, chain = method_chain(method, options)
    assert name == method and len(chain) == len(CHAINS[method])
    stages, field = KEYWORDS[keyword]
    if keyword == "structure":
        assert isinstance(chain[-1], Structure) and isinstance(chain[-1].fit, stages)
    elif isinstance(field, str):
        set_on = [getattr(s, field) for s in chain if isinstance(s, stages)]
        assert any(v is SAMPLES[keyword] for v in set_on), (keyword, chain)


def test_the_options_once_ignored_are_refused():
    for method, keywords in IGNORED_BEFORE.items():
        assert not any(uses(method, k) for k in keywords), method


def test_identify_refuses_before_reading_anything():
    with pytest.raises(ValueError, match="method 'pem' does not use 'iterations' \\(used by: iwo, ga, iwo\\+polish, "
                                         "iwo\\+freq\\+polish\\)"):
        identify("no such flight", method="pem", iterations=10**6)
    with pytest.raises(TypeError, match="unknown option 'iteration'"):
        identify("no such flight", method="iwo", iteration=3)


def test_a_named_method_is_its_chain_of_stages():
    assert method_chain("iwo+polish", {"iterations": 200, "polish_steps": 20, "progress": False}) == (
        "iwo+polish", (Search(iterations=200, progress=False), Polish(steps=20)))
    assert method_chain("ga", {}) == ("ga", (Search(engine="ga"),))
    assert method_chain("pem", {"structure": True, "pem_segment": 4.0}) == ("pem", (Structure(PEM(segment=4.0)),))


@pytest.mark.slow  # two PEM fits and their scores
def test_a_chain_of_stages_runs_as_the_named_method():
    flight = bench_flight(200)
    named = identify(flight, "pem", pem_segment=1.0, prior="table2")
    built = identify(flight, (PEM(segment=1.0, prior="table2"),))
    assert built.method == "pem" and built.settings == named.settings and built.settings["prior"] == "table2"
    assert np.array_equal(built.params, named.params) and built.stderr == named.stderr


def test_a_chain_of_stages_takes_the_problem_settings_it_uses_only():
    assert method_chain((Search(engine="ga"), Polish()), {"cost": "output-error"})[0] == "ga+polish"
    assert method_chain((FrequencyFit(), Structure(Polish())), {"cost": "output-error"})[0] == "freq+polish"
    with pytest.raises(ValueError, match="'iterations' is a named method's option; set it on the chain's stage"):
        method_chain((Search(),), {"iterations": 3})
    with pytest.raises(ValueError, match="method 'pem' does not use 'search_precision'"):
        method_chain((PEM(),), {"search_precision": "float64"})


@pytest.mark.parametrize("stages, message", [
    ((), "a chain is one or more stages"),
    ((Polish(),), "stage 'polish' needs a stage before it"),
    ((Search(), PEM()), "stage 'pem' begins a chain"),
    ((Search(), FrequencyFit(start=TABLE2)), "start is for the head of a chain"),
])
def test_a_stage_out_of_place_is_refused(stages, message):
    with pytest.raises(ValueError, match=message):
        check_chain(stages)


@pytest.mark.parametrize("make, message", [
    (lambda: Polish(objective="pearson", rounds=2), "rounds and cv_windows need the output-error objective"),
    (lambda: Polish(objective="pem", cv_windows=3), "rounds and cv_windows need the output-error objective"),
    (lambda: PEM(prior_sd=20.0), "prior_sd=20.0 needs a prior model"),
    (lambda: Structure(Polish(objective="pearson")), "needs a least-squares fit to repeat"),
    (lambda: Structure(FrequencyFit()), "fit must be a PEM or Polish stage"),
    (lambda: FrequencyFit(options={"start": TABLE2}), "unknown options \\['start'\\]"),
    (lambda: Search(iterations=0), "iterations and chunk must be >= 1"),
    (lambda: Search(engine="ga", options={"modulation": 3.0}), "unknown options \\['modulation'\\] of GA"),
])
def test_a_stage_refuses_options_it_cannot_use(make, message):
    with pytest.raises(ValueError, match=message):
        make()


CLI_SAMPLES = {
    "--iterations": ["3"], "--resume": [], "--checkpoint-every": ["5"], "--search-precision": ["float64"],
    "--cost": ["output-error"], "--polish-objective": ["pem"], "--polish-steps": ["3"], "--polish-rounds": ["2"],
    "--cv-windows": ["2"], "--structure": [], "--prior": ["table2"], "--prior-sd": ["20"], "--freq-starts": ["2"],
    "--freq-screen": ["10"], "--freq-steps": ["5"], "--freq-band": ["0.1", "2"],
}
"""A value of every option of ``jaxheli identify`` that gives one of identify's option keywords."""


def _keyword(option: str) -> str:
    return "freq_options" if option in _FREQ_OPTIONS.values() else next(k for k, o in _KEYWORDS.items() if o == option)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("option", sorted(CLI_SAMPLES))
def test_the_command_line_passes_an_option_the_method_uses_and_refuses_the_rest(method, option, capsys):
    argv = ["identify", "--method", method, option, *CLI_SAMPLES[option]]
    keyword = _keyword(option)
    if uses(method, keyword):
        argv += ["--prior", "table2"] if option == "--prior-sd" else []
        args = build_parser().parse_args(argv)
        assert keyword in _identify_options(args)
        return
    assert main(argv + ["--data", "no-such-flight.csv"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"jaxheli identify: error: {option}: method '{method}' does not use it (used by: ")
    assert err.count("\n") == 1


@pytest.mark.parametrize("method", METHODS)
def test_the_command_line_passes_nothing_the_method_does_not_use(method):
    options = _identify_options(build_parser().parse_args(["identify", "--method", method]))
    assert all(uses(method, k) for k in options)
    assert ("freq_options" in options) == uses(method, "freq_options")
    if "freq_options" in options:  # every one, as the result's settings have always recorded them
        assert options["freq_options"] == {"starts": 4, "screen": 2000, "max_steps": 100, "band": None}


def test_the_command_line_passes_only_what_was_given():
    args = build_parser().parse_args(["identify", "--method", "pem", "--prior", "table2"])
    assert _identify_options(args) == {"prior": "table2"}
