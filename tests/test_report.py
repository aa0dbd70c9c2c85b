"""``jaxheli report``: the HTML holds every section and the numbers of the results it was given, embeds all its
images, escapes text from the input files, and renders in headless Chromium.

The results are built with known, injected parameters (the truth model and a perturbed copy, trials with a
known spread, known cost histories) and written by :func:`jaxheli.save_result`, as ``jaxheli identify``
writes them; a real fit would take minutes here, and its numbers are not what the report is tested on.
"""

import argparse
import base64
import io
import json
import os
import re
import shutil
import subprocess

import matplotlib.image
import numpy as np
import pytest
import scipy.stats

from jaxheli.at_bounds import at_bounds
from jaxheli.synth.excitation import Excitation
from jaxheli.gap.consistency import check
from jaxheli.identify import IdentificationResult, intervals95
from jaxheli.io import load, save_csv
from jaxheli.model import PARAM_NAMES, PINNED, TABLE2
from jaxheli.data.preprocess import lowpass, trim
from jaxheli.cli.report import add_report_parser as add_parser
from jaxheli.report import SECTION_IDS, build_report, load_diagnosis, load_flights, load_results, write_report
from jaxheli.report.html import esc, num
from jaxheli.report.sections import data_summary
from jaxheli.results import save_result
from jaxheli.synth.piloted import piloted_flight

CHANNELS = ("p", "q", "phi", "theta")
REQUIRE_BROWSER = bool(os.environ.get("CI")) or os.environ.get("JAXHELI_REQUIRE_BROWSER", "") not in ("", "0")
HOSTILE = 'bias <b>"bold"</b> & <script>alert(1)</script>'
"""A message that would inject markup if the report did not escape it."""

POLISH = {"objective": "output-error", "objective_before": 0.4321, "objective_after": 0.1234, "cost_before": 0.0211,
          "cost_after": 0.0322, "objective_rounds": [[0.4321, 0.25], [0.3, 0.1234]]}
"""A polish record as identify writes it: its objective falls round by round while the search cost rises."""


def _block(level, cost):
    """A metrics block with known values (the report only reads and formats them)."""
    return {"pearson": {c: level - 0.01 * k for k, c in enumerate(CHANNELS)},
            "tic": {c: 1.1 - level + 0.02 * k for k, c in enumerate(CHANNELS)}, "cost": cost}


def _result(method, params, trial_params, history, train, validate, level, polish=None):
    settings = {"method": method, "iterations": history.shape[1], "trials": len(trial_params),
                "outputs": list(CHANNELS), "segment": 2.0, "hold": "zoh", "g": 9.81,
                "train_source": train.source, "validate_source": validate.source}
    stderr = {n: (float("inf") if n in PINNED else 0.01 * (abs(v) + 1)) for n, v in zip(PARAM_NAMES, params)}
    costs = np.linspace(0.01, 0.02, len(trial_params))
    return IdentificationResult(
        method=method, seed=3, settings=settings, params=params, trial_params=trial_params, trial_costs=costs,
        history=history, intervals95=intervals95(trial_params), stderr=stderr,
        train=_block(level, 0.01),
        validate={**_block(level - 0.1, 0.05), "zero_initial_state": _block(level - 0.2, 0.2)},
        polish=polish, seconds=1.5)


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    train = piloted_flight(duration=30.0, dt=0.05, seed=1)
    validate = piloted_flight(duration=30.0, dt=0.05, excitation=Excitation("3211", unit=0.3), seed=2)
    train = load(save_csv(train.select(CHANNELS + ("r",)), root / "train.csv"))
    validate = load(save_csv(validate.select(CHANNELS + ("r",)), root / "validate.csv"))
    rng = np.random.default_rng(0)
    perturbed = TABLE2 * (1 + 0.05 * rng.uniform(-1, 1, 40))
    trials = perturbed + 0.01 * rng.standard_normal((3, 40)) * (np.abs(TABLE2) + 1)
    trials[:, [PARAM_NAMES.index(n) for n in PINNED]] = 0.0
    history = np.stack([np.geomspace(1.0, 0.02 * (k + 1), 20) for k in range(3)])
    results = {
        "pem": _result("pem", TABLE2.copy(), TABLE2[None], np.zeros((1, 0)), train, validate, 0.99),
        "iwo": _result("iwo", trials[0], trials, history, train, validate, 0.9, POLISH),
    }
    folders = {}
    for name, r in results.items():
        folders[name] = root / name
        save_result(r, folders[name], train, validate)
    diag = root / "diag"
    diag.mkdir()
    findings = [f.to_json() for f in check(train)]
    findings.append({"kind": "rate_bias", "channels": ["p"], "estimate": 0.03, "uncertainty": 0.01,
                     "significant": True, "message": HOSTILE})
    diagnosis = {
        "localisation": {
            "summary": {"worst_channel": "phi", "worst_channel_nmse": 0.4321},
            "channel": {c: {"nmse": 0.1 * (k + 1), "tic": 0.05 * (k + 1)} for k, c in enumerate(CHANNELS)},
        },
        "consistency": findings,
        "ranking": [
            {"effect": "input_delay", "where": ["lat"], "params": {"delay_lat": 0.042}, "shrink_pct": 37.25,
             "shrink_by_channel": {"p": 41.5, "phi": 30.0}, "significant": True, "p_value": 1e-4,
             "summary": "lateral input delay 42 +- 6 ms", "shrink_se_pct": 4.5, "tied_with": ["actuator_lag"],
             "lr": {"statistic": 80.0, "dof": 1, "p_value": 3.7e-19, "delta_aic": -78.0}},
            {"effect": "actuator_lag", "where": ["lon"], "params": {"tau_lon": 0.01}, "shrink_pct": 1.75,
             "shrink_by_channel": {"q": 2.0}, "significant": False, "p_value": 0.4, "summary": "lag 10 ms"},
        ],
        "verdict": "input_delay: gap shrinks 37.2 % on the validation flight",
        "base_refit": {"joint": True, "shrink_pct": 12.34, "shrink_se_pct": 2.5, "under_fitted": True,
                       "settled": True},
    }
    (diag / "diagnosis.json").write_text(json.dumps(diagnosis))
    matplotlib.image.imsave(diag / "residual_bands.png", rng.uniform(size=(20, 30, 3)))
    out = write_report([folders["pem"], folders["iwo"] / "result.json"], root / "report.html", diagnosis=diag,
                       data=[validate.source])
    return {"root": root, "train": train, "validate": validate, "results": results, "folders": folders,
            "html": out.read_text(), "path": out, "diagnosis": diagnosis}


def _section(html, ident):
    match = re.search(rf'<section id="{ident}">(.*?)</section>', html, re.S)
    assert match, f"section {ident} missing"
    return match.group(1)


def _images(html):
    return [base64.b64decode(d) for d in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)]


def test_sections_present_in_order(case):
    html = case["html"]
    positions = [html.index(f'<section id="{i}">') for i in SECTION_IDS]
    assert positions == sorted(positions)
    assert html.count("<section ") == len(SECTION_IDS)


def test_self_contained(case):
    html = case["html"]
    assert not re.search(r'(src|href)="(?!data:|#)', html), "external resource referenced"
    assert "<link" not in html and "<script" not in html
    images = _images(html)
    # verification (1 flight), frequency (1 flight, both methods overlaid), convergence, diagnosis plot
    assert len(images) == 1 + 1 + 1 + 1
    for png in images:
        pixels = matplotlib.image.imread(io.BytesIO(png), format="png")
        assert pixels.shape[0] > 10 and pixels.std() > 0.01


def test_text_is_escaped(case):
    html = case["html"]
    assert "<script>alert" not in html and HOSTILE not in html
    assert str(esc(HOSTILE)) in _section(html, "diagnosis")


def test_data_summary_matches_flights(case):
    body = _section(case["html"], "data-summary")
    for flight in (case["validate"],):
        assert str(esc(flight.source)) in body
        assert f"<td>{flight.n_samples}</td>" in body
        for c, name in enumerate(flight.output_names):
            column = flight.outputs[:, c]
            for value in (np.min(column), np.max(column), np.mean(column), np.std(column)):
                assert f"<td>{value:.4g}</td>" in body, name
    assert "validation of pem; validation of iwo" in body
    assert "not loaded here" in body and str(esc(case["train"].source)) in body


def test_flights_from_result_settings(case):
    flights = load_flights(load_results([case["folders"]["pem"]]))
    assert [f.source for f in flights] == [case["train"].source, case["validate"].source]
    np.testing.assert_array_equal(flights[1].outputs, case["validate"].outputs)


def test_flights_as_fitted_not_as_recorded(case, tmp_path):
    # A result fitted on preprocessed flights: the report shows those, with their steps, not the raw files.
    train = lowpass(case["train"], 1.0)
    validate = trim(case["validate"], drop_samples=25)
    save_result(case["results"]["pem"], tmp_path / "pem", train, validate)
    flights = load_flights(load_results([tmp_path / "pem", case["folders"]["iwo"]]))
    assert [f.n_samples for f in flights] == [train.n_samples, validate.n_samples, case["train"].n_samples,
                                              case["validate"].n_samples]
    np.testing.assert_array_equal(flights[0].outputs, train.outputs)
    np.testing.assert_array_equal(flights[1].outputs, validate.outputs)
    results = load_results([tmp_path / "pem"])
    body = str(data_summary(results, load_flights(results)))
    assert "lowpass (cutoff_hz 1" in body and "drop_samples [25, 25]" in body
    assert f"<td>{validate.n_samples}</td>" in body
    assert f"<td>{np.std(train.output('p')):.4g}</td>" in body


def test_result_json_lists_modes_and_parameters_on_a_bound(case):
    content = json.loads((case["folders"]["pem"] / "result.json").read_text())
    assert [(a["name"], a["side"], a["bound"]) for a in content["at_bounds"]] == [("Mu", "upper", 0.1),
                                                                                  ("Alat", "lower", -0.1)]
    assert content["modes"][0]["name"] == "yaw-heave (heave)" and len(content["modes"]) == 10
    assert content["modes"][0]["time_to_double_s"] == pytest.approx(np.log(2) / TABLE2[PARAM_NAMES.index("Zw")])


def test_parameters_table(case):
    body = _section(case["html"], "parameters")
    iwo = case["results"]["iwo"]
    k = iwo.trial_params.shape[0]
    half = scipy.stats.t.ppf(0.975, k - 1) * iwo.trial_params.std(axis=0, ddof=1) / np.sqrt(k)
    mean = iwo.trial_params.mean(axis=0)
    rows = re.findall(r"<tr>(.*?)</tr>", body, re.S)[1:]
    assert len(rows) == 40
    iwo_sides = {a.name: a.side for a in at_bounds(iwo.params)}
    for row, name, truth, value, m, h in zip(rows, PARAM_NAMES, TABLE2, iwo.params, mean, half):
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row)
        assert cells[0].startswith(name)
        side = {"Mu": " (at upper bound)", "Alat": " (at lower bound)"}.get(name, "")  # Table 2 on the box
        assert cells[1] == f"{truth:.4g}{side}" and cells[2] == "-"  # pem: one trial, no interval
        assert cells[4] == f"{value:.4g}" + (f" (at {iwo_sides[name]} bound)" if name in iwo_sides else "")
        assert cells[5] == f"[{m - h:.4g}, {m + h:.4g}]"
        assert cells[6] == ("inf" if name in PINNED else f"{0.01 * (abs(value) + 1):.3g}")


def test_metrics_table(case):
    body = _section(case["html"], "metrics")
    for method, r in case["results"].items():
        for block in (r.train, r.validate, r.validate["zero_initial_state"]):
            expect = "".join(f"<td>{block['pearson'][c]:.4f}</td>" for c in CHANNELS)
            assert f"<td class=\"text\">Pearson</td>{expect}<td>{block['cost']:.4g}</td>" in body, method
            assert "".join(f"<td>{block['tic'][c]:.4f}</td>" for c in CHANNELS) in body, method


def test_verification_and_frequency(case):
    body = _section(case["html"], "verification")
    assert len(_images(body)) == 1
    # the truth model on its own (lightly noisy) flight, initial state estimated, matches it closely
    row = re.search(r'<td class="text">pem</td><td class="text">Pearson</td>(.*?)</tr>', body).group(1)
    pearson = [float(v) for v in re.findall(r"<td>(.*?)</td>", row)]
    assert len(pearson) == len(CHANNELS) and min(pearson) > 0.95
    freq = _section(case["html"], "frequency-response")
    assert len(_images(freq)) == 1 and "frequency responses on" in freq and "pem, iwo" in freq
    for pair in ("lat -&gt; p", "lon -&gt; q", "ped -&gt; r"):
        assert pair in freq


def test_convergence_and_diagnosis(case):
    conv = _section(case["html"], "convergence")
    (png,) = _images(conv)
    # the generations and, beside them, the polish rounds: two panels, 11 in at 110 dpi
    assert matplotlib.image.imread(io.BytesIO(png), format="png").shape[1] == 11 * 110
    assert f"<td>{num(case['results']['iwo'].trial_costs.min())}</td>" in conv
    assert "".join(f"<td>{POLISH[k]}</td>" for k in ("objective_before", "objective_after", "cost_before",
                                                     "cost_after")) in conv
    diag = _section(case["html"], "diagnosis")
    for entry in case["diagnosis"]["ranking"]:
        assert entry["effect"] in diag and f"<td>{entry['shrink_pct']:.1f}</td>" in diag
    assert "lateral input delay 42 +- 6 ms" in diag and "0.4321" in diag
    assert "<td>4.5</td>" in diag and "<td>3.7e-19</td>" in diag and "<td>actuator_lag</td>" in diag
    assert "shrinks the validation gap 12.3 +- 2.5 % (under-fitted)" in diag
    for finding in case["diagnosis"]["consistency"]:
        assert str(esc(finding["message"])) in diag


def test_without_flights_or_diagnosis(case, tmp_path):
    folder = shutil.copytree(case["folders"]["iwo"], tmp_path / "moved")
    for saved in folder.glob("*_flight.npz"):
        saved.unlink()
    content = json.loads((folder / "result.json").read_text())
    content["settings"]["train_source"] = str(tmp_path / "gone" / "train.csv")
    content["settings"]["validate_source"] = str(tmp_path / "gone" / "validate.csv")
    (folder / "result.json").write_text(json.dumps(content))
    args = parser().parse_args(["report", str(folder), "--out", str(tmp_path / "r.html")])
    assert args.func(args) == 0
    html = (tmp_path / "r.html").read_text()
    saved = (folder / "verification_validate.png").read_bytes()
    assert saved in _images(_section(html, "verification"))
    assert "jaxheli diagnose" in _section(html, "diagnosis")
    assert "--data FILE" in _section(html, "frequency-response")
    assert "gone/train.csv" in _section(html, "data-summary")


def test_each_model_is_drawn_on_its_own_flights_unless_all_are_asked_for(case, tmp_path):
    other = piloted_flight(duration=30.0, dt=0.05, seed=5).select(CHANNELS + ("r",))
    other = load(save_csv(other, tmp_path / "other.csv"))
    ga = _result("ga", TABLE2.copy(), TABLE2[None], np.zeros((1, 0)), other, other, 0.95)
    save_result(ga, tmp_path / "ga", other, other)
    results = load_results([case["folders"]["pem"], tmp_path / "ga"])
    flights = load_flights(results)
    assert [f.source for f in flights] == [case["train"].source, case["validate"].source, other.source]

    def drawn(html):
        """Per flight, the models drawn in the verification and in the frequency-response section."""
        time = [re.findall(r'<td class="text">(\w+)</td><td class="text">Pearson', block)
                for block in _section(html, "verification").split("<h3>")[1:]]
        freq = [re.findall(r"<th[^>]*>(\w+) bins</th>", block)
                for block in _section(html, "frequency-response").split("<h3>")[1:]]
        return time, freq

    own = [["pem"], ["pem"], ["ga"]]
    assert drawn(build_report(results, flights)) == (own, own)
    args = parser().parse_args(["report", str(case["folders"]["pem"]), str(tmp_path / "ga"), "--all-flights",
                                "--out", str(tmp_path / "all.html")])
    assert args.func(args) == 0
    every = [["pem", "ga"]] * 3
    assert drawn((tmp_path / "all.html").read_text()) == (every, every)


def test_bad_inputs_name_file_and_field(tmp_path):
    bad = tmp_path / "result.json"
    bad.write_text(json.dumps({"method": "pem", "parameters": {"Xu": 1.0}}))
    with pytest.raises(ValueError, match=r"result\.json: field 'parameters'"):
        write_report([tmp_path], tmp_path / "r.html")
    with pytest.raises(FileNotFoundError, match="nowhere: no diagnosis.json"):
        load_diagnosis(tmp_path / "nowhere")
    (tmp_path / "diagnosis.json").write_text(json.dumps({"ranking": {"input_delay": 1.0}}))
    with pytest.raises(ValueError, match=r"diagnosis\.json: field 'ranking'"):
        load_diagnosis(tmp_path)


def _browser():
    path = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)
    if path is None:
        message = "Chromium not found (apt-get install chromium chromium-driver)"
        if REQUIRE_BROWSER:
            pytest.fail(message + "; required because CI or JAXHELI_REQUIRE_BROWSER is set")
        pytest.skip(message)
    return path


def test_renders_in_headless_chromium(case, tmp_path):
    browser = _browser()
    url = case["path"].resolve().as_uri()
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"]
    shot = tmp_path / "report.png"
    subprocess.run([browser, *flags, f"--screenshot={shot}", "--window-size=1280,4000", url],
                   check=True, capture_output=True, timeout=120)
    pixels = matplotlib.image.imread(shot)
    assert pixels.shape[:2] == (4000, 1280)
    rows = pixels[..., :3].std(axis=(1, 2))
    assert pixels[..., :3].std() > 0.05 and (rows > 0.01).mean() > 0.3  # not blank: content on many rows
    dom = subprocess.run([browser, *flags, "--dump-dom", url], check=True, capture_output=True, text=True,
                         timeout=120).stdout
    for ident in SECTION_IDS:
        assert f'<section id="{ident}">' in dom
    assert dom.count("<img ") == len(_images(case["html"]))


def parser():
    p = argparse.ArgumentParser(prog="jaxheli")
    add_parser(p.add_subparsers(dest="command"))
    return p
