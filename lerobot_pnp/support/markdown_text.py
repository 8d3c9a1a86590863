"""User text (run names, suite names, paths, labels) placed into generated markdown, as literal text.

A name such as ``<script>``, ``a|b`` or one holding a line break would otherwise become HTML, split a table
row into more cells, or start a new line of the page. ``text`` is for prose and table cells, ``code`` for a code
span. Both leave ordinary names (letters, digits, ``_``, ``-``, ``.``, ``/``, spaces) unchanged. This module
depends on nothing of the package, so every page writer can use it.
"""

from __future__ import annotations

import re

_LINE_BREAKS = re.compile(r"\r\n|[\r\n\v\f\x1c\x1d\x1e\x85\u2028\u2029]")
_TEXT = str.maketrans({"\\": "\\\\", "&": "&amp;", "<": "&lt;", ">": "&gt;", "|": "\\|"})


def one_line(value: object) -> str:
    """``value`` as text, every line break (``\\n``, ``\\r``, Unicode's) a space."""
    return _LINE_BREAKS.sub(" ", str(value))


def text(value: object) -> str:
    """``value`` as literal inline markdown: on one line, ``\\`` and ``|`` backslash-escaped (a table cell stays
    one cell), ``&``, ``<`` and ``>`` as HTML entities (no tag, comment or entity of the user's is rendered)."""
    return one_line(value).translate(_TEXT)


def code(value: object, table: bool = False) -> str:
    """``value`` as a code span, shown exactly as written (on one line): the fence is one backtick longer than
    the longest run of backticks inside it, padded with a space where the text starts or ends with a backtick or
    a space. ``table``: the span sits in a table cell, where a ``|`` must be backslash-escaped even in code."""
    body = one_line(value)
    fence = "`" * (max((len(run) for run in re.findall(r"`+", body)), default=0) + 1)
    if body[:1] in ("`", " ") or body[-1:] in ("`", " "):
        body = f" {body} "
    if table:
        body = body.replace("|", "\\|")
    return f"{fence}{body}{fence}"
