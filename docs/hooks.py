"""MkDocs hooks: the pages generated at build time (``mkdocs.yml`` ``hooks:``).

- ``api/*.md``: the API reference, one ``::: jaxheli.NAME`` block for every name ``jaxheli/__init__.py``
  re-exports (read with :mod:`ast`, so the pages follow that file when names come or go), grouped by the
  module each name comes from (:data:`GROUPS`); the nav entry ``API reference`` lists the pages.
- ``tutorial.md``: ``notebooks/walkthrough.py`` (jupytext percent format) as markdown, not executed.
- ``benchmarks.md``: the tables :mod:`gen_benchmarks` renders from the records in ``docs/benchmarks/*.json``.
- ``<!-- jaxheli-help: COMMAND -->`` in a page: replaced by ``jaxheli COMMAND --help`` as the parser prints it.
"""

from __future__ import annotations

import ast
import importlib.util
import os
from functools import cache
from pathlib import Path
from typing import NamedTuple

from mkdocs.structure.files import File

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
INIT = ROOT / "jaxheli" / "__init__.py"
NOTEBOOK = ROOT / "notebooks" / "walkthrough.py"

GROUPS: tuple[tuple[str, str, tuple[str, ...], str], ...] = (
    ("model", "Model and search box", ("model", "bounds"),
     "Mettler's hover model: parameter and state names, the reference models, the search box, `build_ab`."),
    ("data", "Flight data", ("data", "io"),
     "`FlightData`, the readers and writers, preprocessing."),
    ("synth", "Synthetic flights", ("synth",),
     "Excitation signals and piloted synthetic flights."),
    ("simulation", "Simulation and cost", ("sim", "cost", "problem"),
     "Discretisation, simulators, the population cost, initial states, metrics and the `Problem` every engine takes."),
    ("optim", "Optimisers", ("optim", "distributed"),
     "IWO, GA, the run driver, PEM, the polish, uncertainty, structure determination, cross-validation."),
    ("identify", "Identify, evaluate, verify", ("identify", "evaluate", "verify", "modes", "at_bounds", "results"),
     "The entry points that return typed results, and what they write."),
    ("gap", "Gap diagnosis", ("gap",),
     "Data consistency, preparation, the diagnosis's records."),
    ("report", "Report and utilities", ("report", "_progress", "_compile_cache"),
     "The HTML report, progress lines and the compile cache."),
)
"""``(page, title, source modules, blurb)``: each re-exported name goes to the page of the first component of the
module it is imported from; a name from a module no group lists goes to the page ``other``."""

MODULE_OPTIONS = "    options:\n      members: false\n      show_root_heading: true\n"


class Export(NamedTuple):
    """A name ``jaxheli/__init__.py`` re-exports: ``source`` the module it is imported from (relative to
    ``jaxheli``), ``module`` whether it is a module itself (``from . import gap as gap``)."""

    name: str
    source: str
    module: bool


def exported_names(init: Path = INIT) -> list[Export]:
    """Every public name ``init`` re-exports, in file order.

    Re-exports are the ``from .module import name as name`` lines (and ``from . import module as module``); names
    starting with ``_`` are private. Where ``__all__`` is defined it is the list, each name's source still taken
    from its import line."""
    tree = ast.parse(init.read_text())
    found: dict[str, Export] = {}
    declared: list[str] | None = None
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            for alias in node.names:
                name = alias.asname or alias.name
                if alias.asname in (None, alias.name) and name not in found:
                    found[name] = Export(name, node.module or alias.name, node.module is None)
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            declared = list(ast.literal_eval(node.value))
    if declared is not None:
        return [found.get(name, Export(name, "", False)) for name in declared]
    return [export for name, export in found.items() if not name.startswith("_")]


def identifier(export: Export) -> str:
    """The path the reference renders ``export`` under (and its HTML anchor): ``jaxheli.NAME``, except where a
    function shares its name with the submodule that defines it (``jaxheli.identify``, the function, comes from
    ``jaxheli/identify.py``): the static analysis sees the submodule there, so the function is rendered at its
    definition, ``jaxheli.identify.identify``."""
    shadowed = (ROOT / "jaxheli" / export.name).is_dir() or (ROOT / "jaxheli" / f"{export.name}.py").is_file()
    if shadowed and not export.module:
        return f"jaxheli.{export.source}.{export.name}"
    return f"jaxheli.{export.name}"


def group_of(source: str) -> str:
    head = source.split(".")[0]
    for page, _title, modules, _blurb in GROUPS:
        if head in modules:
            return page
    return "other"


def api_pages() -> dict[str, tuple[str, str]]:
    """``{page: (title, markdown)}`` of the API reference, the index included."""
    by_page: dict[str, list[Export]] = {}
    for export in exported_names():
        by_page.setdefault(group_of(export.source), []).append(export)
    titles = {page: (title, blurb) for page, title, _m, blurb in GROUPS}
    titles["other"] = ("Other", "Names from modules the reference has no group for yet.")
    pages: dict[str, tuple[str, str]] = {}
    index = [
        "# API reference\n",
        "Every name `import jaxheli` exports, rendered from its docstring. The pages are generated when the site is",
        "built, from the names `jaxheli/__init__.py` re-exports, so the reference follows that file.\n",
        "| page | names |", "|---|---|",
    ]
    for page in [p for p, *_ in GROUPS] + ["other"]:
        if page not in by_page:
            continue
        title, blurb = titles[page]
        members = by_page[page]
        index.append(f"| [{title}]({page}.md) | " + ", ".join(f"`{e.name}`" for e in members) + " |")
        body = [f"# {title}\n", f"{blurb}\n"]
        for export in members:
            body.append(f"::: {identifier(export)}")
            if export.module:
                body.append(MODULE_OPTIONS)
            body.append("")
        pages[page] = (title, "\n".join(body))
    pages["index"] = ("Overview", "\n".join(index) + "\n")
    return pages


def notebook_markdown(path: Path = NOTEBOOK) -> str:
    """The notebook as markdown: its markdown cells as they are, its code cells as ``python`` blocks (not run)."""
    import jupytext

    notebook = jupytext.read(path)
    parts = []
    for cell in notebook.cells:
        source = cell.source.strip("\n")
        if not source:
            continue
        if cell.cell_type == "markdown":
            parts.append(source)
        elif cell.cell_type == "code":
            parts.append(f"```python\n{source}\n```")
    note = (
        "!!! note \"Run it yourself\"\n"
        "    This page is `notebooks/walkthrough.py` (jupytext percent format), shown without its outputs. "
        "Open it as a notebook with `pip install -e \".[test]\" && jupytext --to ipynb notebooks/walkthrough.py`; "
        "`tests/test_notebook.py` executes it and checks its numbers. It reads the real flights from "
        "`$JAXHELI_DATA`."
    )
    title, _, rest = parts[0].partition("\n")
    return "\n\n".join([title, note, rest.strip(), *parts[1:]]) + "\n"


def _load_gen_benchmarks():
    spec = importlib.util.spec_from_file_location("gen_benchmarks", DOCS / "gen_benchmarks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@cache
def _parser_choices() -> dict:
    os.environ.setdefault("COLUMNS", "110")
    from jaxheli.cli import build_parser

    parser = build_parser()
    (sub,) = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
    return sub.choices


def command_help(command: str) -> str:
    """``jaxheli COMMAND --help`` (``jaxheli --help`` for ``jaxheli``) as the parser prints it."""
    if command == "jaxheli":
        from jaxheli.cli import build_parser

        return build_parser().format_help()
    return _parser_choices()[command].format_help()


# --- hooks -----------------------------------------------------------------------------------------------------


def on_config(config):
    """Fill the nav entry ``API reference`` with the generated pages."""
    pages = api_pages()
    entries = [{"Overview": "api/index.md"}] + [
        {title: f"api/{page}.md"} for page, (title, _md) in pages.items() if page != "index"
    ]
    for item in config["nav"] or []:
        if isinstance(item, dict) and "API reference" in item:
            item["API reference"] = entries
    return config


def on_files(files, config):
    for page, (_title, markdown) in api_pages().items():
        files.append(File.generated(config, f"api/{page}.md", content=markdown))
    files.append(File.generated(config, "tutorial.md", content=notebook_markdown()))
    gen = _load_gen_benchmarks()
    files.append(File.generated(config, "benchmarks.md", content=gen.render(gen.load_records())))
    return files


def on_page_markdown(markdown, page, config, files):
    marker = "<!-- jaxheli-help: "
    if marker not in markdown:
        return markdown
    out = []
    for line in markdown.splitlines():
        if line.startswith(marker) and line.rstrip().endswith("-->"):
            command = line[len(marker):].rstrip()[:-3].strip()
            out.append(f"```text\n{command_help(command).rstrip()}\n```")
        else:
            out.append(line)
    return "\n".join(out) + "\n"
