"""Documentation tables generated from the code and data, so that they cannot go stale: the
technique table (from the registry, each name linked to its reference page) and the code-layout
table (from the modules' docstrings) in docs/guide.md, the README's headline verdicts (from
the committed quick study in results/quick), and the engine presets' per-value sources in
docs/your-scenes.md (from :mod:`shadowlab.techniques.maps.presets`).

Each page holds each table between marker comments (``<!-- technique-table:begin -->`` …
``<!-- technique-table:end -->``); ``tests/project/test_docs.py`` regenerates them and fails, showing
the difference, when a page's copy differs. ``--write`` also rewrites the technique reference
pages in docs/techniques/ (:mod:`.technique_pages`), so one command brings every generated page
up to date.

    python -m shadowlab.docgen.tables            # print the tables
    python -m shadowlab.docgen.tables --write    # rewrite them in README.md and docs/guide.md,
                                                 # and the pages in docs/techniques/
"""
from __future__ import annotations

import argparse
import ast
import difflib
import functools
import pkgutil
import re
import sys
from pathlib import Path

from ..util.text import MAX_SUMMARY, _cell, first_sentence  # noqa: F401  (MAX_SUMMARY: the layout table's limit)
from . import technique_pages
from .technique_pages import lights_cell

#: The README of a source checkout (the package's parent folder), and the user's guide in docs/.
README = Path(__file__).resolve().parents[2] / "README.md"
GUIDE = README.parent / "docs" / "guide.md"
#: The page that walks a user through their own scenes (it holds the engine presets' sources).
YOUR_SCENES = README.parent / "docs" / "your-scenes.md"
#: The committed run of the quick study the README's headline verdicts are generated from.
HEADLINE_STUDY = README.parent / "results" / "quick"
#: The generated tables, by marker name → the page that holds them.
HOMES = {"technique-table": GUIDE, "layout-table": GUIDE, "headline-verdicts": README,
         "preset-sources": YOUR_SCENES}
TABLES = tuple(HOMES)
#: The command that brings the generated tables and pages up to date (shown when they differ).
FIX_COMMAND = "python -m shadowlab.docgen.tables --write"


# --------------------------------------------------------------------------- technique table

def technique_table(registry=None) -> str:
    """The markdown table of every registered technique, in registry order: name (a link to its
    generated reference page, :mod:`.technique_pages`), summary, named passes in drawing order and
    the light types it renders for (all declared by the technique)."""
    if registry is None:
        from ..techniques import REGISTRY as registry
    lines = ["| technique | what | passes (drawing order) | lights |", "|---|---|---|---|"]
    pages = technique_pages.PAGES.relative_to(GUIDE.parent).as_posix()
    for name, cls in registry.items():
        cells = [f"[`{name}`]({pages}/{name}.md)", _cell(cls.summary), _cell(", ".join(f"`{p}`" for p in cls.PASSES)),
                 _cell(lights_cell(cls))]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


# --------------------------------------------------------------------------- layout table

def _module_doc(path: Path) -> str | None:
    """The docstring of the Python file ``path``, read without importing it."""
    try:
        return ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    except (OSError, SyntaxError, UnicodeDecodeError):
        return None


def _data_files(folder: Path) -> str:
    """What a package without a docstring holds besides Python: ``*.toml``, ``*.glsl`` …"""
    kinds = sorted({"*" + p.suffix for p in folder.iterdir() if p.is_file() and p.suffix and p.suffix != ".py"})
    return f"package data: {', '.join(f'`{k}`' for k in kinds)}" if kinds else ""


def walk_modules(folder: Path | None = None, prefix: str = "") -> list[tuple[str, bool, Path]]:
    """Every public module and sub-package under ``folder`` (default: this package), depth
    first, each package before its modules, sorted by name within a package: (relative name
    such as ``study/cache.py`` or ``study/``, is-package, path of its source file). Modules and
    packages whose name starts with ``_`` are private and left out."""
    folder = folder or Path(__file__).resolve().parents[1]
    out = []
    for info in sorted(pkgutil.iter_modules([str(folder)]), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        if info.ispkg:
            sub = folder / info.name
            out.append((f"{prefix}{info.name}/", True, sub / "__init__.py"))
            out.extend(walk_modules(sub, f"{prefix}{info.name}/"))
        else:
            out.append((f"{prefix}{info.name}.py", False, folder / f"{info.name}.py"))
    return out


def layout_table(folder: Path | None = None) -> str:
    """The markdown table of the package's modules and sub-packages (paths relative to
    ``shadowlab/``), each with the first sentence of its docstring."""
    lines = ["| module | holds |", "|---|---|"]
    for name, ispkg, path in walk_modules(folder):
        summary = first_sentence(_module_doc(path))
        if not summary and ispkg:
            summary = _data_files(path.parent)
        lines.append(f"| `{name}` | {_cell(summary) or '—'} |")
    return "\n".join(lines)


# --------------------------------------------------------------------------- the README's copies

def headline_verdicts(study: Path = HEADLINE_STUDY) -> str:
    """The README's headline: the verdicts of the committed quick study (``results/quick``:
    results.csv, study.json and the tiles.npz its ties are tested on), as summary.md opens with
    them, and where they come from."""
    import json

    import pandas as pd

    from ..study.report import verdict_markdown
    from ..study.tiles import read_tiles

    results = pd.read_csv(study / "results.csv")
    meta = json.loads((study / "study.json").read_text())
    lines = verdict_markdown(results, meta, read_tiles(study))[2:]  # without its "## Verdicts" heading
    source = (f"From the committed run in [`results/quick/`](results/quick/) (`shadowlab study quick`, "
              f"{meta['size'][0]}×{meta['size'][1]}, revision {meta['revision']}, renderer {meta['device']}). "
              f"Times are CPU-rasteriser times there: compare techniques with each other, not with a GPU.")
    return "\n".join([source, ""] + lines).strip()


def preset_sources() -> str:
    """Every engine preset value with the engine setting it stands for, where that default is
    written (repository@commit:path:line, or the documentation page) and how faithful the lab's
    mapping is: the rows of :func:`shadowlab.techniques.maps.presets.table_rows`, so that the page
    says exactly what the code holds (issue 41: a mapping that is uncertain says so)."""
    from ..techniques.maps.presets import PRESETS, table_rows

    lines = ["Read: " + "; ".join(f"`{p.name}`: {_cell(p.version)}" for p in PRESETS.values()) + ".", "",
             "| preset | technique | light | parameter | value | engine setting | source | fidelity | note |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in table_rows():
        lines.append("| " + " | ".join(_cell(r[k]) for k in ("preset", "technique", "light", "parameter", "value",
                                                              "setting", "source", "fidelity", "note")) + " |")
    return "\n".join(lines)


@functools.lru_cache(maxsize=1)
def generated() -> dict[str, str]:
    """Each generated table, freshly made, by marker name."""
    return {"technique-table": technique_table(), "layout-table": layout_table(),
            "headline-verdicts": headline_verdicts(), "preset-sources": preset_sources()}


def _markers(name: str) -> tuple[str, str]:
    return f"<!-- {name}:begin -->", f"<!-- {name}:end -->"


def extract(text: str, name: str) -> str | None:
    """The table between ``name``'s markers in ``text`` (stripped), or None without markers."""
    begin, end = _markers(name)
    m = re.search(re.escape(begin) + r"\n?(.*?)\n?" + re.escape(end), text, re.S)
    return m.group(1).strip() if m else None


def replace(text: str, name: str, table: str) -> str:
    """``text`` with the table between ``name``'s markers replaced by ``table`` (ValueError if
    the markers are missing)."""
    begin, end = _markers(name)
    pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.S)
    if not pattern.search(text):
        raise ValueError(f"no {begin} … {end} markers")
    return pattern.sub(lambda _: f"{begin}\n{table}\n{end}", text, count=1)


def differences(homes: dict[str, Path] | None = None) -> dict[str, str]:
    """Per table whose copy in its page (:data:`HOMES`) differs from the generated one, a unified
    diff (page → generated); a table whose markers are missing is reported too. Empty when up
    to date."""
    out = {}
    for name, table in generated().items():
        page = (homes or HOMES)[name]
        current = extract(page.read_text(encoding="utf-8"), name)
        if current is None:
            out[name] = f"{page.name} has no <!-- {name}:begin --> … <!-- {name}:end --> markers"
        elif current != table.strip():
            out[name] = "\n".join(difflib.unified_diff(current.splitlines(), table.splitlines(),
                                                       f"{page.name} ({name})", "generated", lineterm=""))
    return out


def write(homes: dict[str, Path] | None = None) -> bool:
    """Rewrite every generated table in its page from the code; True when something changed."""
    changed = False
    tables = generated()
    for page in dict.fromkeys((homes or HOMES).values()):
        text = page.read_text(encoding="utf-8")
        new = text
        for name, home in (homes or HOMES).items():
            if home == page:
                new = replace(new, name, tables[name])
        if new != text:
            page.write_text(new, encoding="utf-8")
            changed = True
    return changed


def main(argv: list[str] | None = None) -> int:
    """Print the tables, or (``--write``) update them in the README."""
    p = argparse.ArgumentParser(prog="python -m shadowlab.docgen.tables", description=__doc__.split("\n\n")[0])
    p.add_argument("--write", action="store_true", help="rewrite the tables between the markers of README.md "
                                                        "and docs/guide.md, and the technique pages in docs/techniques/")
    args = p.parse_args(argv)
    if args.write:
        changed = write()
        print(f"{'tables updated' if changed else 'tables already up to date'}: {', '.join(map(str, dict.fromkeys(HOMES.values())))}")
        pages = technique_pages.write()
        print(f"technique pages {'updated' if pages else 'already up to date'}: {technique_pages.PAGES}")
        return 0
    for name, table in generated().items():
        begin, end = _markers(name)
        print(f"{begin}\n{table}\n{end}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
