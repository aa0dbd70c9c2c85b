"""HTML building blocks of the report: escaping, elements, tables, embedded PNG figures and the page.

Every text that reaches the page goes through :func:`esc` unless it is already :class:`Html` (built here),
so values read from JSON files (sources, messages, effect names) cannot inject markup.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#1d232a;background:#f4f6f8}
header{background:#17324d;color:#fff;padding:18px 32px}
header h1{margin:0 0 4px;font-size:24px}header p{margin:0;opacity:.85}
nav{background:#23476b;padding:6px 32px;position:sticky;top:0}
nav a{color:#dbe8f5;margin-right:16px;text-decoration:none;font-size:14px}
main{padding:8px 32px 40px}
section{background:#fff;border-radius:8px;box-shadow:0 1px 3px rgba(0,0,0,.12);margin:18px 0;padding:14px 22px}
h2{color:#17324d;border-bottom:2px solid #d6e2ee;padding-bottom:4px}h3{color:#23476b;margin-bottom:6px}
table{border-collapse:collapse;margin:8px 0 14px;font-size:13px}
th,td{border:1px solid #d5dbe1;padding:3px 8px;text-align:right;white-space:nowrap}
th{background:#e9eff5}td.text,th.text{text-align:left;white-space:normal}
caption{caption-side:top;text-align:left;font-weight:600;padding:4px 0;color:#3a4a5a}
tr:nth-child(even) td{background:#f8fafc}
figure{margin:10px 0 18px}figure img{max-width:100%;border:1px solid #e1e6eb}
figcaption{font-size:13px;color:#4a5866}
.note{background:#fff7e0;border-left:4px solid #e0a800;padding:8px 12px;margin:8px 0}
.side-by-side{display:flex;flex-wrap:wrap;gap:24px;align-items:flex-start}
.good{color:#1b7a36;font-weight:600}.bad{color:#b3261e;font-weight:600}
code{background:#eef2f6;padding:1px 4px;border-radius:3px}
"""


class Html(str):
    """Markup that is already safe: inserted as is, never escaped again."""


def esc(value: Any) -> Html:
    """``value`` as escaped text (``Html`` passes through unchanged)."""
    return value if isinstance(value, Html) else Html(html.escape(str(value), quote=True))


def join(parts: Iterable[Any]) -> Html:
    """Concatenate parts, escaping the plain ones."""
    return Html("".join(esc(p) for p in parts))


def tag(name: str, *children: Any, **attrs: Any) -> Html:
    """``<name attrs>children</name>``; ``class_`` gives ``class``; attribute values are escaped."""
    text = "".join(f' {k.rstrip("_")}="{esc(v)}"' for k, v in attrs.items() if v is not None)
    return Html(f"<{name}{text}>{join(children)}</{name}>")


def num(value: Any, spec: str = ".4g") -> str:
    """A number for a table cell: ``spec`` format, ``inf``/``NaN`` spelled out, ``-`` for missing."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, str):
        return value
    x = float(value)
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return format(x, spec)


def table(header: Sequence[Any], rows: Iterable[Sequence[Any]], caption: Any = None, text_columns: int = 1) -> Html:
    """A table; the first ``text_columns`` columns are left-aligned text, the rest numbers."""

    def cells(row: Sequence[Any], kind: str) -> Html:
        return join(tag(kind, c, class_="text" if i < text_columns else None) for i, c in enumerate(row))

    head = tag("thead", tag("tr", cells(header, "th")))
    body = tag("tbody", join(tag("tr", cells(r, "td")) for r in rows))
    return tag("table", tag("caption", caption) if caption is not None else "", head, body)


def png_figure(png: bytes, caption: Any) -> Html:
    """A PNG embedded as a base64 ``data:`` URI, with its caption."""
    data = base64.b64encode(png).decode("ascii")
    return tag("figure", Html(f'<img src="data:image/png;base64,{data}" alt="{esc(caption)}">'),
               tag("figcaption", caption))


def note(*children: Any) -> Html:
    """A highlighted paragraph (missing inputs, how to produce them)."""
    return tag("p", *children, class_="note")


def section(ident: str, title: str, *body: Any) -> Html:
    """``<section id=ident>`` with an ``h2`` title."""
    return tag("section", tag("h2", title), *body, id=ident)


def json_view(value: Any, max_items: int = 8) -> Html:
    """Any JSON value as nested HTML: a mapping of mappings as a table, a list of mappings as a table, a
    mapping of scalars as a two-column table; numeric lists longer than ``max_items`` are summarised."""
    if isinstance(value, Mapping):
        if value and all(isinstance(v, Mapping) and v and all(_flat(x) for x in v.values()) for v in value.values()):
            cols = list(dict.fromkeys(k for v in value.values() for k in v))
            return table(["", *cols], ([k, *(_cell(v.get(c), max_items) for c in cols)] for k, v in value.items()))
        if all(_flat(v) for v in value.values()):
            return table(["name", "value"], ([k, _cell(v, max_items)] for k, v in value.items()))
        return tag("dl", join(join([tag("dt", tag("b", k)), tag("dd", json_view(v, max_items))])
                              for k, v in value.items()))
    if isinstance(value, list) and value and all(isinstance(v, Mapping) for v in value):
        if all(all(_flat(x) for x in v.values()) for v in value):
            cols = list(dict.fromkeys(k for v in value for k in v))
            return table(cols, ([_cell(v.get(c), max_items) for c in cols] for v in value), text_columns=len(cols))
        return join(json_view(v, max_items) for v in value)
    return tag("span", _cell(value, max_items))


def page(title: str, subtitle: str, sections: Sequence[tuple[str, str, Html]]) -> str:
    """The whole self-contained document: inline CSS, a navigation bar and the ``(id, title, html)`` sections."""
    links = join(tag("a", t, href=f"#{i}") for i, t, _ in sections)
    body = join(s for _, _, s in sections)
    return (
        "<!DOCTYPE html>\n"
        + tag("html",
              tag("head", Html('<meta charset="utf-8">'), tag("title", title), tag("style", Html(CSS))),
              tag("body", tag("header", tag("h1", title), tag("p", subtitle)), tag("nav", links),
                  tag("main", body)),
              lang="en")
        + "\n"
    )


def _scalar(value: Any) -> bool:
    return value is None or isinstance(value, (str, int, float, bool))


def _flat(value: Any) -> bool:
    """A scalar, or a list or mapping of scalars: fits in one table cell."""
    items = value.values() if isinstance(value, Mapping) else value if isinstance(value, list) else None
    return _scalar(value) or (items is not None and all(_scalar(v) for v in items))


def _cell(value: Any, max_items: int) -> str:
    if isinstance(value, list):
        if len(value) > max_items and all(isinstance(v, (int, float)) for v in value):
            return f"[{len(value)} values]"
        return "[" + ", ".join(_cell(v, max_items) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {_cell(v, max_items)}" for k, v in value.items()) + "}"
    return num(value)
