"""The documentation: README is a short guide, and the site builds with ``mkdocs build --strict`` (no broken link,
anchor or reference), its API reference covering every name ``jaxheli`` exports and its Benchmarks page generated
from records that say where each figure comes from."""

import importlib.util
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

import jaxheli

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
HASH = re.compile(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")


def _module(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


hooks = _module("docs_hooks", ROOT / "docs" / "hooks.py")
gen_benchmarks = _module("docs_gen_benchmarks", ROOT / "docs" / "gen_benchmarks.py")


def test_readme_is_a_short_guide():
    text = README.read_text()
    assert len(text.splitlines()) <= 150
    assert not HASH.findall(text), "README names commits; history belongs in docs/*_history.md"
    assert not re.findall(r"\b\d+(?:\.\d+)? s\b", text), "README quotes timings; they belong in the docs"


def test_readme_links_resolve():
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README.read_text()):
        if "://" not in target:
            assert (ROOT / target).exists(), f"README links to {target}, which does not exist"


def test_hash_pattern():
    assert HASH.findall("on 7943b6d and c06d0f2") == ["7943b6d", "c06d0f2"]
    assert not HASH.findall("defaced 1000000 effaced 2026-11-28")


def test_exported_names_are_read_from_the_package():
    names = [export.name for export in hooks.exported_names()]
    assert len(names) > 20 and len(set(names)) == len(names)
    for name in names:
        assert hasattr(jaxheli, name), name
    assert {"identify", "FlightData", "TABLE2", "gap"} <= set(names)


def test_benchmark_records_say_where_each_figure_comes_from():
    records = gen_benchmarks.load_records()
    assert records, "docs/benchmarks/ holds no record"
    for name, rec in records:
        assert rec["kind"] in gen_benchmarks.RENDERERS, name
        assert rec["command"] and re.fullmatch(r"[0-9a-f]{40}", rec["commit"]), name
        assert rec["machine"]["cpus"] and rec["machine"]["processor"], name
        assert rec["label"]["measure"] in gen_benchmarks.MEASURES, name
        assert rec["label"]["sample"] in gen_benchmarks.SAMPLES, name
        assert rec["label"]["seeds"] in gen_benchmarks.SEEDS, name
        assert isinstance(rec["output"], dict), name
    page = gen_benchmarks.render(records)
    for _name, rec in records:
        assert rec["command"] in page and rec["commit"] in page
    assert not (ROOT / "docs" / "benchmarks.md").exists(), "the Benchmarks page is generated, not written by hand"


def test_a_blind_record_keeps_the_summary_and_renders_its_tables():
    """A blind check's record stores only ``summary`` (``--keep``; a missing entry is named) and renders per kind, by
    form and the controls, each figure from the summary."""
    with pytest.raises(ValueError, match=r"no entry 'summry'; it has \['records', 'summary'\]"):
        gen_benchmarks._kept({"summary": {}, "records": []}, "summry")
    settings = {"truth": "independent", "truths": "wide", "split": "test", "seed_range": [7000, 7019],
                "base": "default", "box": "authors", "duration": 30.0, "dt": 0.05}
    summary = {"settings": settings, "false_positives": 1, "controls": 40, "false_positive_ci95_pct": [0.4, 12.9],
               "kinds": {"drag": {"trials": 20, "top1_pct": 55.0, "resolvable_trials": 12, "top1_resolvable_pct": 75.0,
                                  "magnitude_error_median_resolvable": 0.31, "structure_pct": 40.0,
                                  "beyond_structure_trials": 8, "top1_beyond_structure_pct": 87.5},
                         "dryden": {"trials": 20, "top1_pct": 45.0, "resolvable_trials": 15,
                                    "top1_resolvable_pct": 60.0, "magnitude_error_median_resolvable": 0.5,
                                    "structure_pct": 35.0},
                         "none": {"trials": 40, "top1_pct": 97.5, "structure_pct": 60.0}},
               "forms": {"in-family": {"trials": 20, "top1_pct": 55.0, "resolvable_trials": 12,
                                       "top1_resolvable_pct": 75.0, "magnitude_error_median_resolvable": 0.31,
                                       "beyond_structure_trials": 8, "top1_beyond_structure_pct": 87.5}}}
    page = gen_benchmarks.render_blind({"output": gen_benchmarks._kept({"summary": summary}, "summary")})
    assert "| `drag` | in family | 20 | 55 | 12 | 75 | 31 % | 8, 88 | 40 |" in page
    assert "| `dryden` | other forms | 20 | 45 | 15 | 60 | 50 % | - | 35 |" in page  # a record without the reach
    assert "| `none` | control | 40 | 98 | - | - | - | - | 60 |" in page
    assert "| in-family | 20 | 55 | 12 | 75 | 31 % | 8, 88 |" in page
    assert "**1 of 40** (95 % Wilson interval 0-13 %)" in page and "`test` seeds 7000-7019" in page


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                         cwd=ROOT, capture_output=True, text=True, env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    seconds = time.perf_counter() - start
    assert run.returncode == 0, f"mkdocs build --strict failed:\n{run.stdout}\n{run.stderr}"
    print(f"mkdocs build --strict: {seconds:.1f} s")
    return out


def test_site_builds_strict(site):
    for page in ("index.html", "getting-started/index.html", "guide/identify/index.html", "tutorial/index.html",
                 "benchmarks/index.html", "design/index.html", "api/index.html", "performance_history/index.html"):
        assert (site / page).is_file(), page


def test_api_reference_covers_every_export(site):
    html = "\n".join(path.read_text() for path in (site / "api").rglob("*.html"))
    missing = [e.name for e in hooks.exported_names() if f'id="{hooks.identifier(e)}"' not in html]
    assert not missing, f"exported by jaxheli but not in the API reference: {missing}"


def test_tutorial_is_the_notebook(site):
    html = (site / "tutorial" / "index.html").read_text()
    assert "From a flight log to a validated hover model" in html
    assert "ITERATIONS" in html and "highlight" in html  # its code cells, shown as code


def test_command_help_is_rendered(site):
    html = (site / "guide" / "identify" / "index.html").read_text()
    assert "--polish-objective" in html and "jaxheli-help" not in html


def test_benchmarks_page_is_generated_from_the_records(site):
    html = (site / "benchmarks" / "index.html").read_text()
    for _name, rec in gen_benchmarks.load_records():
        assert rec["commit"] in html
