"""Text helpers for generated tables and one-line summaries: a docstring's first sentence as one
line of markdown (:func:`first_sentence`), shortened the same way everywhere (:func:`_shorten`),
and a string made safe for one markdown table cell (:func:`_cell`)."""
from __future__ import annotations

import re

#: A layout-table summary longer than this is shortened (:func:`_shorten`).
MAX_SUMMARY = 200


def _cell(text: str) -> str:
    """``text`` made safe for one markdown table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _markdown(text: str) -> str:
    """Sphinx/reST inline markup as markdown: ``:mod:`x```, ``:mod:`.x``` and ````x```` → ```x```."""
    text = re.sub(r":[a-z]+:`~?\.?([^`]+)`", r"`\1`", text)
    return text.replace("``", "`")


def _without_doc_references(text: str) -> str:
    """Drop references to the documentation pages from a one-line summary, where they read as
    noise: ``(docs/metrics.md)``, ``(docs/contracts.md#scene-files: ...)``, ``, docs/tuning.md``,
    ``of docs/architecture.md``; the pages link them where it helps."""
    ref = r"(?:docs/[\w\-]+\.md(?:#[\w\-]+)?)"
    text = re.sub(rf"\s*\(\s*(?:the contract of\s+)?{ref}(?:\s*[,;]\s*{ref})*(?:\s*:[^()]*)?\s*\)", "", text)
    text = re.sub(rf"\s*[,;]\s*{ref}", "", text)
    text = re.sub(rf"\(\s*{ref}\s*[,;]\s*", "(", text)
    text = re.sub(rf"\s+(?:of|in|from)\s+{ref}", "", text)
    return text


def _shorten(sentence: str, limit: int = MAX_SUMMARY) -> str:
    """A summary longer than ``limit`` (:data:`MAX_SUMMARY`) without its parentheses (citations,
    asides); if still too long, cut before its first dash or colon, or else at a word boundary."""
    if len(sentence) <= limit:
        return sentence
    while True:
        bare = re.sub(r"\s*\([^()]*\)", "", sentence)
        if bare == sentence:
            break
        sentence = bare
    if len(sentence) <= limit:
        return sentence
    for sep in (" — ", ": "):
        head = sentence.split(sep, 1)[0]
        if 30 <= len(head) <= limit:
            return head.rstrip(",;:") + "."
    return sentence[:limit].rsplit(" ", 1)[0].rstrip(",;:") + " …"


def first_sentence(doc: str | None, limit: int = MAX_SUMMARY) -> str:
    """The summary of a docstring: its first sentence (of its first paragraph), as one line of
    markdown, without references to the documentation pages, shortened to ``limit``
    characters (:func:`_shorten`); "" for no docstring."""
    if not doc:
        return ""
    paragraph = " ".join(doc.strip().split("\n\n", 1)[0].split())
    # a sentence ends at ". " before a capital letter or a markup character (not at "e.g. ",
    # "et al. ", an initial "D. B. ")
    m = re.search(r"(?<=[a-z0-9)\]`*])[.!?](?=\s+[A-Z`*(])", paragraph)
    sentence = paragraph[: m.end()] if m else paragraph
    return _shorten(_markdown(_without_doc_references(sentence)).strip(), limit)
