"""Markdown pipe tables as ``summary.md`` and the README print them: readable as plain text too."""
from __future__ import annotations


def md_cell(value) -> str:
    """A cell's text: '' for None / NaN, pipes escaped, newlines as spaces."""
    from .format import is_missing

    text = "" if is_missing(value) else str(value)
    return text.replace("|", "\\|").replace("\n", " ")


def md_table(header: list[str], rows: list[list]) -> str:
    """A pipe table padded to aligned columns (readable as plain text)."""
    cells = [[md_cell(c) for c in header]] + [[md_cell(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = ["| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |" for r in cells]
    lines.insert(1, "|" + "|".join("-" * (w + 2) for w in widths) + "|")
    return "\n".join(lines)
