"""A Griffe extension for the API reference: Sphinx roles in docstrings (``:func:`~jaxheli.x.y```,
``:mod:`jaxheli.gap```) shown as code (``y``, ``jaxheli.gap``), as Sphinx would print them, since Markdown has
no roles. Used by ``mkdocs.yml`` (mkdocstrings' ``extensions``)."""

from __future__ import annotations

import re

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|meth|class|mod|attr|data|obj|exc|const|ref):`(~?)([^`]+)`")


def _plain(match: re.Match) -> str:
    short, target = match.group(1), match.group(2)
    return f"`{target.rsplit('.', 1)[-1] if short else target}`"


def strip_roles(text: str) -> str:
    return _ROLE.sub(_plain, text)


class SphinxRoles(griffe.Extension):
    """Rewrites each loaded docstring's Sphinx roles as code spans."""

    def _fix(self, obj: griffe.Object) -> None:
        if obj.docstring is not None:
            obj.docstring.value = strip_roles(obj.docstring.value)

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        self._fix(obj)
