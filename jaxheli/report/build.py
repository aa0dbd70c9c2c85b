"""Assemble the report: read the results, the diagnosis and the flights, render every section, write one file."""

from __future__ import annotations

import datetime
from collections.abc import Sequence
from pathlib import Path

from ..data.flight import FlightData
from . import sections as s
from .html import page
from .inputs import DiagnosisSource, ResultSource, load_diagnosis, load_flights, load_results


def build_report(
    results: Sequence[ResultSource], flights: Sequence[FlightData] = (), diagnosis: DiagnosisSource | None = None
) -> str:
    """The self-contained HTML document (inline CSS, PNGs as base64) for ``results`` compared side by side."""
    parts = {
        "overview": s.overview(results, flights, diagnosis),
        "data-summary": s.data_summary(results, flights),
        "parameters": s.parameters(results),
        "metrics": s.metrics(results),
        "verification": s.verification(results, flights),
        "frequency-response": s.frequency_response(results, flights),
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
) -> Path:
    """Read result folders / ``result.json`` files (and a diagnosis folder or JSON, and flight files when
    given; otherwise the flights the results name), write the report to ``out`` and return its path."""
    loaded = load_results(results)
    html = build_report(loaded, load_flights(loaded, data), None if diagnosis is None else load_diagnosis(diagnosis))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(html, encoding="utf-8")
    return out
