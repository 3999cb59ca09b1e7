"""A griffe extension: the package's docstrings use a few reStructuredText spellings (``literal``,
:class:`~pkg.Name` roles, a singular ``Example:`` section) inside Google-style sections; this
turns them into the Markdown that mkdocstrings renders, before the docstrings are parsed."""

from __future__ import annotations

import re

import griffe

_ROLE = re.compile(r":(?:class|func|meth|attr|mod|data|obj|exc|py:\w+):`~?([^`]+)`")
_LITERAL = re.compile(r"``(.+?)``", re.S)
_EXAMPLE = re.compile(r"^(\s*)Example:\s*$", re.M)


def _role(m: re.Match) -> str:
    target = m.group(1)
    shown = target.rsplit(".", 1)[-1] if m.group(0).split("`", 1)[1].startswith("~") else target
    return f"`{shown}`"


def to_markdown(text: str) -> str:
    text = _ROLE.sub(_role, text)
    text = _LITERAL.sub(lambda m: "`" + m.group(1).replace("`", "") + "`", text)
    return _EXAMPLE.sub(r"\1Examples:", text)


class RstToMarkdown(griffe.Extension):
    def on_object(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = to_markdown(obj.docstring.value)
