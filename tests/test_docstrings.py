"""No docstring or comment under ``jaxheli/`` cites a commit: docstrings say what a thing does, and the history of how
it came about (the commit, the figures) lives in ``docs/performance_history.md`` and ``docs/blind_history.md``."""

import ast
import io
import re
import shutil
import subprocess
import tokenize
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "jaxheli"

HASH = re.compile(r"(?<![\w.])(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}(?!\w)")
"""A word that looks like an abbreviated or full commit hash: 7-40 lowercase hex digits, at least one a digit and one
a letter (not part of a dotted or ``0x`` number)."""

HEX_WORD = re.compile(r"(?<![\w.])[0-9a-f]{7,40}(?!\w)")
"""Any word of 7-40 lowercase hex digits (checked against the repository's commits)."""


def _prose(path: Path) -> Iterator[tuple[int, str]]:
    """``(line, text)`` of every comment and docstring of ``path`` (a string standing alone as a statement: a
    module's, class's or function's docstring, or an attribute docstring after an assignment)."""
    source = path.read_text()
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            yield token.start[0], token.string
    for node in ast.walk(ast.parse(source, str(path))):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            yield node.lineno, node.value.value


def _commits() -> set[str]:
    """Every commit of the repository (full hashes), or none where git or the history is not at hand."""
    if shutil.which("git") is None:
        return set()
    run = subprocess.run(["git", "-C", str(ROOT), "log", "--all", "--format=%H"], capture_output=True, text=True)
    return set(run.stdout.split()) if run.returncode == 0 else set()


def _cited(text: str, commits: set[str]) -> list[str]:
    found = [m.group() for m in HASH.finditer(text)]
    found += [m.group() for m in HEX_WORD.finditer(text) if any(c.startswith(m.group()) for c in commits)]
    return sorted(set(found))


def test_the_hash_pattern_spares_hex_constants_and_numbers() -> None:
    assert _cited("measured on main 9ed6a88 and on 97bfe5b4", set()) == ["97bfe5b4", "9ed6a88"]
    assert _cited("FMT record a3 95 80, 0x3a9580ff, 1.5e10, 12345678, deadbeef, 2.0abcdef1", set()) == []
    assert _cited("seed 12345678", {"12345678" + "0" * 32}) == ["12345678"]


def test_no_docstring_or_comment_cites_a_commit() -> None:
    commits = _commits()
    cited = [f"{path.relative_to(ROOT)}:{line}: {word}" for path in sorted(PACKAGE.rglob("*.py"))
             for line, text in _prose(path) for word in _cited(text, commits)]
    assert not cited, "commit hashes in docstrings or comments (move the history to docs/):\n" + "\n".join(cited)
