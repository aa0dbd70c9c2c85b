"""Assemble the report: read the results, the diagnosis and the flights, render every section, write one file."""

from __future__ import annotations

import datetime
from collections.abc import Sequence
from pathlib import Path

from .._progress import stage
from ..data.flight import FlightData
from . import sections as s
from .html import page
from .inputs import DiagnosisSource, ResultSource, load_diagnosis, load_flights, load_results


def build_report(
    results: Sequence[ResultSource], flights: Sequence[FlightData] = (), diagnosis: DiagnosisSource | None = None,
    *, all_flights: bool = False,
) -> str:
    """The self-contained HTML document (inline CSS, PNGs as base64) for ``results`` compared side by side; each
    model drawn on the flights it was fitted or validated on, or with ``all_flights`` on every flight
    (:func:`~jaxheli.report.sections.drawn_on`)."""
    parts = {
        "overview": s.overview(results, flights, diagnosis),
        "data-summary": s.data_summary(results, flights),
        "parameters": s.parameters(results),
        "metrics": s.metrics(results),
        "verification": s.verification(results, flights, all_flights),
        "frequency-response": s.frequency_response(results, flights, all_flights),
        "convergence": s.convergence(results),
        "diagnosis": s.diagnosis(diagnosis, results),
    }
    stamp = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
    subtitle = f"{', '.join(r.label for r in results)}; generated {stamp} by jaxheli report"
    return page("jaxheli identification report", subtitle, [(i, s.TITLES[i], parts[i]) for i in s.SECTION_IDS])


def write_report(
    results: Sequence[str | Path],
    out: str | Path,
    *,
    diagnosis: str | Path | None = None,
    data: Sequence[str | Path] = (),
    all_flights: bool = False,
) -> Path:
    """Read result folders / ``result.json`` files (and a diagnosis folder or JSON, and flight files when
    given; otherwise the flights the results name), write the report to ``out`` and return its path;
    ``all_flights`` as in :func:`build_report`."""
    loaded = load_results(results)
    with stage(f"report of {len(loaded)} result(s): tables, simulations and plots"):
        html = build_report(loaded, load_flights(loaded, data),
                            None if diagnosis is None else load_diagnosis(diagnosis), all_flights=all_flights)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(html, encoding="utf-8")
    return out
