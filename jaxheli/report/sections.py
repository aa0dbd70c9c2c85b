"""The report's sections, one function each; every one returns a ``<section id=...>`` element.

Stable ids (tests and links rely on them): :data:`SECTION_IDS`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..at_bounds import TOLERANCE as BOUND_TOLERANCE, at_bounds
from ..cost import metrics as channel_metrics
from ..data.flight import default_outputs
from ..evaluate import simulate_as_scored
from ..data.flight import FlightData
from ..model import G_SI, PARAM_NAMES, PINNED, STATE_UNITS
from ..results import PLOT_CHANNELS
from .figures import convergence_png, frequency_png, time_domain_png
from .html import Html, esc, json_view, note, num, png_figure, section, table, tag
from .inputs import DiagnosisSource, ResultSource, recorded_sources

SECTION_IDS: tuple[str, ...] = (
    "overview", "data-summary", "parameters", "metrics", "verification", "frequency-response", "convergence",
    "diagnosis",
)
"""Ids of the report's sections, in page order."""

TITLES: dict[str, str] = {
    "overview": "Overview", "data-summary": "Data summary", "parameters": "Identified parameters",
    "metrics": "Metrics (Table 1)", "verification": "Time-domain verification",
    "frequency-response": "Frequency responses", "convergence": "Convergence", "diagnosis": "Gap diagnosis",
}
"""Section titles by id."""

_BLOCKS = (("train", "training flight"), ("validate", "validation flight, initial state estimated"),
           ("zero_initial_state", "validation flight, from rest (the paper)"))


def overview(results: Sequence[ResultSource], flights: Sequence[FlightData], diagnosis: DiagnosisSource | None) -> Html:
    """Which results are compared, how each was run, and what else went into the report."""
    rows = [[r.label, str(r.folder), r.content.get("seed", "-"), r.settings.get("iterations", "-"),
             r.settings.get("trials", "-"), ", ".join(r.settings.get("outputs", [])), num(r.settings.get("segment")),
             num(r.content.get("seconds"), ".1f")] for r in results]
    head = ["method", "result folder", "seed", "iterations", "trials", "cost channels", "segment [s]", "fit time [s]"]
    extra = [f"{len(flights)} flight(s) loaded for plots", "a gap diagnosis" if diagnosis else "no gap diagnosis"]
    return section("overview", TITLES["overview"], table(head, rows, text_columns=2),
                   tag("p", "Report built from " + ", ".join(extra) + "."))


def data_summary(results: Sequence[ResultSource], flights: Sequence[FlightData]) -> Html:
    """Flights used: source, role, samples, dt, duration, channels, preprocessing, and each channel's range."""
    body: list[Any] = []
    rows = [[f.source, _role(f.source, results), preprocessing_steps(f), f.n_samples, num(f.dt, ".4g"),
             num(f.duration, ".2f"), ", ".join(f.output_names)] for f in flights]
    if rows:
        head = ["source", "role", "preprocessing", "samples", "dt [s]", "duration [s]", "output channels"]
        body.append(table(head, rows, text_columns=3))
    missing = [s for s in recorded_sources(results) if not any(_same_file(s, f.source) for f in flights)]
    if missing:
        body.append(note("Flights recorded in the results but not loaded here (not files on this machine; pass ",
                         tag("code", "--data FILE"), "): ", "; ".join(missing), "."))
    for f in flights:
        columns = [(n, "stick", f.inputs[:, i]) for i, n in enumerate(f.input_names)]
        columns += [(n, STATE_UNITS[n], f.outputs[:, i]) for i, n in enumerate(f.output_names)]
        body.append(table(["channel", "unit", "min", "max", "mean", "std"],
                          ([n, u, num(c.min()), num(c.max()), num(c.mean()), num(c.std())] for n, u, c in columns),
                          caption=f"ranges: {f.source}", text_columns=2))
    return section("data-summary", TITLES["data-summary"], *body)


def preprocessing_steps(flight: FlightData) -> str:
    """The flight's ``metadata["preprocessing"]`` in one line: each step with its scalar settings and, for a
    consistency correction, the kinds of finding applied (``-`` for a record used as read)."""
    def value(v: Any) -> str | None:
        if isinstance(v, float):
            return f"{v:.4g}"
        if isinstance(v, int | str):
            return str(v)
        if isinstance(v, list | tuple) and all(isinstance(x, int | float) for x in v):
            return "[" + ", ".join(map(value, v)) + "]"
        return None

    steps = []
    for record in flight.metadata.get("preprocessing", []):
        shown = [f"{k} {value(v)}" for k, v in record.items() if k != "step" and value(v) is not None]
        shown += [f["kind"] for f in record.get("applied", []) if isinstance(f, dict) and "kind" in f]
        steps.append(f"{record.get('step', '?')} ({', '.join(shown)})" if shown else str(record.get("step", "?")))
    return "; ".join(steps) or "-"


def parameters(results: Sequence[ResultSource]) -> Html:
    """The 40 parameters in the paper's Table 2 order: value (marked when on a bound of the search box), 95 %
    interval over trials, standard error."""
    head = ["parameter"] + [h for r in results for h in (f"{r.label}", "95% interval", "std. error")]
    bounded = [_at_bounds(r) for r in results]
    held = [r.content.get("fixed") or {} for r in results]
    rows = []
    for i, name in enumerate(PARAM_NAMES):
        row: list[Any] = [name + (" (pinned)" if name in PINNED else "")]
        for r, on, fixed in zip(results, bounded, held):
            interval = (r.content.get("intervals95") or {}).get(name)
            value = num(r.params[i]) + (f" (at {on[name]} bound)" if name in on else "") + (
                " (fixed)" if name in fixed else "")
            row += [value, "-" if interval is None else f"[{num(interval[0])}, {num(interval[1])}]",
                    num((r.content.get("stderr") or {}).get(name), ".3g")]
        rows.append(row)
    return section("parameters", TITLES["parameters"],
                   tag("p", "SI units (m, s, rad). 95% interval: t-interval of the trial mean (needs 2 or more "
                       "trials); std. error: Cramer-Rao bound at the optimum (inf: not identifiable from the flight). "
                       f"At a bound: within {100 * BOUND_TOLERANCE:g} % of the search box's width from it; the box, "
                       "not the flight, set that value, and its interval and standard error say nothing of it. "
                       "Fixed: held by the model-structure determination (identify --structure), see below."),
                   table(head, rows), *_bounds_and_fixed(results, bounded, held))


def _bounds_and_fixed(
    results: Sequence[ResultSource], bounded: list[dict[str, str]], held: list[dict[str, dict[str, Any]]]
) -> list[Html]:
    """Two tables side by side, per result: the parameters at a bound, and those the model-structure determination
    fixed (value, where it comes from, round, reason); only where some result ran the determination."""
    ran = [r for r in results if r.content.get("fixed") is not None]
    if not ran:
        return []
    at = [[r.label, name, side] for r, on in zip(results, bounded) for name, side in on.items()]
    fixed = [[r.label, name, f.get("source", "-"), f.get("reason", ""), num(f.get("value")), str(f.get("round", "-"))]
             for r, named in zip(results, held) for name, f in named.items()]
    return [tag("div",
                table(["result", "parameter", "bound"], at or [["-", "none", "-"]], caption="parameters at bounds",
                      text_columns=3),
                table(["result", "parameter", "held at", "reason", "value", "round"],
                      fixed or [["-", "none", "-", "-", "-", "-"]], caption="fixed parameters", text_columns=4),
                class_="side-by-side")]


def _at_bounds(result: ResultSource) -> dict[str, str]:
    """``{name: side}`` of the result's parameters on a bound: ``result.json``'s ``at_bounds``, or for a result
    saved without it, those on the authors' box."""
    listed = result.content.get("at_bounds")
    found = [a.to_json() for a in at_bounds(result.params)] if listed is None else listed
    return {a["name"]: a["side"] for a in found}


def metrics(results: Sequence[ResultSource]) -> Html:
    """Pearson correlation and TIC per channel, and the paper's cost, per method: training and validation."""
    body: list[Any] = []
    for key, title in _BLOCKS:
        blocks = [(r.label, _block(r, key)) for r in results]
        blocks = [(label, b) for label, b in blocks if b is not None]
        if not blocks:
            continue
        chans = list(dict.fromkeys(c for _, b in blocks for c in b["pearson"]))
        rows = [[label, name, *(num(b[key].get(c), ".4f") for c in chans),
                 num(b.get("cost")) if key == "pearson" else ""]
                for label, b in blocks for key, name in (("pearson", "Pearson"), ("tic", "TIC"))]
        body.append(table(["method", "metric", *chans, "cost"], rows, caption=title, text_columns=2))
    if not any(r.content.get("validate") for r in results):
        body.append(note("No validation flight in these results: run ",
                         tag("code", "jaxheli identify ... --validate FILE"), " to score on held-out data."))
    return section("metrics", TITLES["metrics"],
                   tag("p", "Pearson correlation (paper Eq. 6; 1 is a perfect shape match), Theil inequality "
                       "coefficient (0 is perfect; <= 0.25-0.3 is a good time-domain match) and the paper's cost "
                       "C = sum (1 - rho)^2 (Eq. 7)."), *body)


def verification(results: Sequence[ResultSource], flights: Sequence[FlightData], all_flights: bool = False) -> Html:
    """Measured against simulated outputs on every loaded flight, overlaid for the methods drawn on it
    (:func:`drawn_on`); without flights, the verification PNGs saved beside each result."""
    body: list[Any] = [tag("p", _DRAWN)] if flights and not all_flights else []
    for f in flights:
        chans = tuple(c for c in PLOT_CHANNELS if c in f.output_names) or f.output_names
        sims = {r.label: simulate_as_scored(r.params, r.settings, f, chans) for r in drawn_on(f, results, all_flights)}
        meas = f.select(chans).outputs
        scores = {label: channel_metrics(y, meas, chans) for label, y in sims.items()}
        rows = [[label, name, *(num(s[key][c], ".4f") for c in chans)]
                for label, s in scores.items() for key, name in (("pearson", "Pearson"), ("tic", "TIC"))]
        body += [
            tag("h3", f.source, " (", _role(f.source, results), ")"),
            png_figure(time_domain_png(f, chans, sims, f.source),
                       f"flight (black) against each model on {f.source}; initial state estimated, segment "
                       "restarts as in each result's settings"),
            table(["method", "metric", *chans], rows, caption=f"scores of these plots on {f.source}", text_columns=2),
        ]
    if not flights:
        body.append(note("Flight files not available here: showing the plots saved by jaxheli identify. Pass ",
                         tag("code", "--data FILE"), " to regenerate them with all methods overlaid."))
        for r in results:
            for name, png in r.pngs.items():
                if name.startswith("verification"):
                    body.append(png_figure(png, f"{r.label}: {name} (saved in {r.folder})"))
    return section("verification", TITLES["verification"], *body)


_DRAWN = ("Each model is drawn on the flights it was fitted or validated on, every model on a flight no result "
          "names (one given with --data); jaxheli report --all-flights draws every model on every flight.")
"""The verification and frequency-response sections' note on which models they draw on which flight."""


def drawn_on(flight: FlightData, results: Sequence[ResultSource], all_flights: bool = False) -> list[ResultSource]:
    """The results drawn on ``flight``: those fitted or validated on it; all of them with ``all_flights``, or where
    none names it (a flight the caller added)."""
    own = [r for r in results if any(_same_file(r.settings.get(k), flight.source)
                                     for k in ("train_source", "validate_source"))]
    return list(results) if all_flights or not own else own


def frequency_response(
    results: Sequence[ResultSource], flights: Sequence[FlightData], all_flights: bool = False
) -> Html:
    """Flight frequency responses (Welch, conditioned on all sticks) with partial coherence against the response
    of each model drawn on the flight (:func:`drawn_on`), and the CIFER mismatch per on-axis pair."""
    from ..spectra import estimate_frequency_response, mismatch, model_frequency_response
    from ..plots import PRIMARY_PAIRS
    from ..model import INPUT_NAMES

    if not flights:
        return section("frequency-response", TITLES["frequency-response"],
                       note("Needs the flight data: pass ", tag("code", "--data FILE"), " (or keep the files named in "
                            "result.json settings where they were)."))
    body: list[Any] = [tag("p", "Dots: flight estimate (opacity = partial coherence); lines: the models. Mismatch over "
                            "bins with partial coherence >= 0.6: mean magnitude error (dB), mean phase error (deg) and "
                            "the CIFER cost J (<= 100 acceptable, <= 50 excellent).")]
    if not all_flights:
        body.append(tag("p", _DRAWN))
    for f in flights:
        drawn = drawn_on(f, results, all_flights)
        chans = default_outputs(f)
        body.append(tag("h3", f.source))
        try:
            estimate = estimate_frequency_response(f.inputs, f.select(chans).outputs, f.dt)
        except ValueError as err:
            body.append(note(f"No frequency response for this flight: {err}"))
            continue
        pairs = [(i, o) for i, o in PRIMARY_PAIRS if o in chans and o not in ("u", "v")]
        rows = {p: [f"{p[0]} -> {p[1]}"] for p in pairs}
        models = {r.label: np.asarray(model_frequency_response(r.params, estimate.freq, chans,
                                                               r.settings.get("g", G_SI))) for r in drawn}
        body.append(png_figure(frequency_png(estimate, models, chans, pairs, f"flight against the models on {f.source}"),
                               f"frequency responses on {f.source}: " + ", ".join(models)))
        for model in models.values():
            err = mismatch(estimate, model)
            for i, o in pairs:
                k, m = chans.index(o), INPUT_NAMES.index(i)
                bins = int(err["bins"][k, m])
                rows[(i, o)] += [bins] + [num(err[key][k, m] if bins else None, spec) for key, spec in
                                          (("magnitude_db", ".2f"), ("phase_deg", ".1f"), ("cifer_j", ".1f"))]
        head = ["pair"] + [h for r in drawn for h in (f"{r.label} bins", "mag [dB]", "phase [deg]", "J")]
        body.append(table(head, rows.values(), caption=f"flight against model on {f.source} "
                          f"({estimate.averages:.1f} effective Welch averages)"))
    return section("frequency-response", TITLES["frequency-response"], *body)


def convergence(results: Sequence[ResultSource]) -> Html:
    """Best cost per generation (``result.npz`` histories) and the polish's own objective per round, final trial
    costs, and the polish's objective and the search cost before and after it."""
    png = convergence_png(results)
    body: list[Any] = [png_figure(png, "best cost (paper Eq. 7) per generation, every trial; beside it, the polish's "
                                  "own objective from the start to the end of each round") if png else
                       note("No generation history in these results (PEM is a gradient method without generations).")]
    rows = []
    for r in results:
        costs = r.content.get("trial_costs") or []
        polish = r.content.get("polish") or {}
        rows.append([r.label, r.history.shape[1] or "-", len(costs), num(min(costs) if costs else None),
                     num(max(costs) if costs else None), polish.get("objective", "-"),
                     num(polish.get("objective_before")), num(polish.get("objective_after")),
                     num(polish.get("cost_before")), num(polish.get("cost_after"))])
    body.append(table(["method", "generations", "trials", "best trial cost", "worst trial cost", "polish objective",
                       "objective before polish", "objective after polish", "search cost before polish",
                       "search cost after polish"], rows,
                      caption="the polish minimises its own objective (unless it is the Pearson cost searched "
                      "too), not the search cost, which may rise through it"))
    return section("convergence", TITLES["convergence"], *body)


def diagnosis(diag: DiagnosisSource | None, results: Sequence[ResultSource]) -> Html:
    """Localisation summary, ranked effects and consistency findings from ``jaxheli diagnose`` / ``check``;
    without them, how to produce them."""
    if diag is None:
        model = results[0].folder / "result.json"
        return section("diagnosis", TITLES["diagnosis"], note(
            "No gap diagnosis given. Produce one with ",
            tag("code", f"jaxheli diagnose --model {model} --data FILE --validate FILE --out DIR"),
            " (and the data check with ", tag("code", "jaxheli check --data FILE --out DIR"), "), then rerun ",
            tag("code", "jaxheli report ... --diagnosis DIR"), "."))
    content = diag.content or {}
    body: list[Any] = [tag("p", "From ", tag("code", str(diag.path)), ".")]
    if content.get("headline"):
        body.append(tag("p", tag("b", "Found: "), content["headline"]))
    if content.get("verdict"):
        body.append(tag("p", tag("b", "Verdict: "), content["verdict"]))
    if diag.content is not None:
        body += _localisation(content.get("localisation"))
    refit = content.get("base_refit") or {}
    if refit.get("joint"):
        body.append(tag("p", tag("b", "Base model re-fitted alone: "),
                        f"shrinks the validation gap {num(refit.get('shrink_pct'), '.1f')} +- "
                        f"{num(refit.get('shrink_se_pct'), '.1f')} % "
                        f"({'under-fitted' if refit.get('under_fitted') else 'within noise'}"
                        f"{'' if refit.get('settled', True) else ', still converging: no effect credited'}); "
                        "each effect was fitted jointly with the base parameters and is credited beyond this."))
    if content.get("ranking") is not None:
        body += [tag("h3", "Ranked effects (shrink of the gap on the validation flight)"), _ranking(content["ranking"])]
    if content.get("combination"):
        c = content["combination"]
        verdict = "significant" if c.get("significant") else "not significant"
        body.append(tag("p", tag("b", "Top effects combined: "), c.get("effect", "?"),
                        f" shrinks the gap {num(c.get('shrink_pct'), '.1f')} % ({verdict})."))
    if diag.consistency is not None:
        body += [tag("h3", "Data consistency findings"), _findings(diag.consistency)]
    elif diag.content is not None:
        body.append(note("No consistency findings: run ", tag("code", "jaxheli check --data FILE --out DIR"), "."))
    body += [png_figure(png, f"{name} (from {diag.path})") for name, png in diag.pngs.items()]
    return section("diagnosis", TITLES["diagnosis"], *body)


def _localisation(loc: Any) -> list[Any]:
    if not isinstance(loc, dict):
        return [note("The diagnosis holds no localisation.")] if loc is None else [json_view(loc)]
    out: list[Any] = [tag("h3", "Where the gap lies")]
    for key, title in (("summary", "summary"), ("channel", "by channel"),
                       ("frequency_response", "by input-output pair")):
        if key in loc:
            out += [tag("h4", title), json_view(loc[key])]
    if isinstance(loc.get("band"), list):
        out += [tag("h4", "by frequency band"), _bands(loc["band"])]
    return out


def _bands(bands: list[dict[str, Any]]) -> Html:
    """Per band and channel: share of the channel's residual energy, and the input-residual coherence verdict."""
    names = list(dict.fromkeys(n for b in bands for n in b.get("channels") or {}))
    rows = []
    for b in bands:
        lo, hi = b.get("range_hz") or (None, None)
        cells = [f"{num(lo, '.3g')}-{num(hi, '.3g')} Hz"]
        for n in names:
            coherence = (b.get("coherence") or {}).get(n) or {}
            cells += [num(((b.get("channels") or {}).get(n) or {}).get("share"), ".3f"), coherence.get("verdict", "-")]
        rows.append(cells)
    head = ["band"] + [h for n in names for h in (f"{n} share", f"{n} coherence")]
    return table(head, rows, caption="share of residual energy and what drives it (structure: input-correlated)")


def _ranking(ranking: list[dict[str, Any]]) -> Html:
    head = ["rank", "effect", "where", "summary", "shrink [%]", "+- [%]", "shrink by channel [%]", "significant",
            "tied with", "LR p-value", "window p-value"]
    rows = []
    for k, e in enumerate(ranking, 1):
        by_channel = ", ".join(f"{c} {num(v, '.1f')}" for c, v in (e.get("shrink_by_channel") or {}).items())
        where = e.get("where")
        rows.append([k, e.get("effect", "?"), ", ".join(map(str, where)) if isinstance(where, list) else num(where),
                     e.get("summary") or json_view(e.get("params", {})), num(e.get("shrink_pct"), ".1f"),
                     num(e.get("shrink_se_pct"), ".1f"), by_channel,
                     tag("span", num(bool(e.get("significant"))), class_="good" if e.get("significant") else "bad"),
                     ", ".join(e.get("tied_with") or []), num((e.get("lr") or {}).get("p_value"), ".3g"),
                     num(e.get("p_value"), ".3g")])
    return table(head, rows, text_columns=4)


def _findings(findings: list[dict[str, Any]]) -> Html:
    rows = [[f.get("kind"), ", ".join(f.get("channels", [])), json_view(f.get("estimate")),
             json_view(f.get("uncertainty")), num(bool(f.get("significant"))), f.get("message")] for f in findings]
    return table(["kind", "channels", "estimate", "uncertainty (1 sigma)", "significant", "message"], rows,
                 text_columns=6)


def _block(result: ResultSource, key: str) -> dict[str, Any] | None:
    if key == "zero_initial_state":
        return (result.content.get("validate") or {}).get(key)
    return result.content.get(key)


def _role(source: str, results: Sequence[ResultSource]) -> Html:
    roles = [f"{kind} of {r.label}" for r in results
             for kind, key in (("training", "train_source"), ("validation", "validate_source"))
             if _same_file(r.settings.get(key), source)]
    return esc("; ".join(roles) or "extra flight (--data)")



def _same_file(recorded: str | None, source: str) -> bool:
    """Whether a source recorded in a result names the loaded flight (same path, or same file name when the
    result was made on another machine; any of the records of a fit to several, ``a + b``)."""
    return recorded is not None and any(r == source or Path(r).name == Path(source).name
                                        for r in recorded.split(" + "))
