"""Reference pages generated from the techniques themselves: one markdown page per registered
technique and an index by family, as Mitsuba's plugin reference is generated from its plugins.

The pages are ``docs/techniques/<name>.md`` and the index ``docs/techniques/README.md``; made from
the code, a page cannot say what the code does not.

Everything on a page comes from the technique's own declarations or from committed files:

- its family (the folder of ``shadowlab/techniques/`` its module sits in), module and class, and
  the classes it is built on;
- the theory: its module's docstring, reST roles turned into markdown as the generated tables
  turn them (:func:`shadowlab.util.text._markdown`), paths of the repository turned into links;
- ``PARAMS`` (default, allowed values or range, the :class:`~shadowlab.techniques.base.Param`'s
  doc, the tuner's default range ``tune``), ``PASSES``, ``LIGHTS``, ``LIGHT_SAMPLED``,
  ``STATS`` with their combine rules, ``cpu``, and what it ``READS``, ``WRITES`` and ``PROVIDES``;
- its GLSL programs — the file names its class and the classes it is built on pass to
  ``self.program(...)`` — and the files they ``#include``, found on the loader's search path
  (:func:`shadowlab.gpu.glsl.shader_files`);
- the shipped suites that measure it and their scenes (linked to the hard-case catalogue), the
  catalogue entries that name it, and the documentation pages that discuss it;
- measured figures only from committed results: its rows of the committed quick study
  (``results/quick``) and, where a claim of its code is backed by another committed file, that
  file's rows (:data:`EVIDENCE`). Figures measured once on one machine stay out of docstrings:
  a docstring says what and why, and links here or to the page that holds the numbers.

``tests/project/test_docs.py`` regenerates every page and fails, naming the fix, when a committed
page differs (or a page is left over from a technique that no longer exists).

    python -m shadowlab.docgen.technique_pages            # list the pages that differ
    python -m shadowlab.docgen.technique_pages --write    # rewrite them (also done by
                                                          # python -m shadowlab.docgen.tables --write)
"""
from __future__ import annotations

import argparse
import ast
import difflib
import functools
import inspect
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from ..gpu.frame import GBUFFER_CHANNELS
from ..util.text import _cell, _markdown, first_sentence

#: The repository of a source checkout (the package's parent folder) and its documentation.
REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
#: Where the pages go: one ``<name>.md`` per technique and the index ``README.md``.
PAGES = DOCS / "techniques"
INDEX = PAGES / "README.md"
#: The hard-case catalogue whose entries the pages link to.
CATALOGUE = DOCS / "hard-cases.md"
#: The committed quick study whose rows a page shows.
QUICK_STUDY = REPO / "results" / "quick"
#: The command that brings the pages up to date (shown when they differ).
FIX_COMMAND = "python -m shadowlab.docgen.tables --write"
#: The light types in the order the pages list them.
LIGHT_ORDER = ("point", "spot", "directional", "target_direct", "area")
#: What each combine rule of ``STATS`` means (:data:`shadowlab.techniques.base.SUM` ...).
RULES = {"sum": "summed over the light samples (work per render)",
         "max": "the largest over the light samples (a size or peak held while one sample is set up)",
         "first": "the first sample's (describes the configuration or the view)"}
GENERATED_NOTE = ("<!-- Generated from the code by `{fix}`: edit the technique's module (its docstring and "
                  "declarations), not this page. -->")


# --------------------------------------------------------------------------- evidence

@dataclass(frozen=True)
class Column:
    """One column of an :class:`Evidence` table: ``label``, the committed CSV (relative to the
    repository), the rows it takes (column → value) and the value column shown (a rate)."""

    label: str
    file: str
    where: tuple[tuple[str, str], ...]
    value: str = "error_rate"


@dataclass(frozen=True)
class Evidence:
    """A claim a technique's code makes (a default chosen, a variant kept), with the committed
    rows that back it: per (scene, light) of ``keys``, one value per :class:`Column`. The page
    reads the figures from the files, so they are the files' and nothing else's."""

    technique: str
    claim: str
    source: str
    keys: tuple[tuple[str, int], ...]
    columns: tuple[Column, ...]


#: The claims of technique code that committed results back (see :class:`Evidence`).
EVIDENCE: tuple[Evidence, ...] = (
    Evidence(
        technique="virtual_map",
        claim=("Why `bias_space` defaults to `window`: the slope term dominates the bias here, and over the "
               "shipped perspective scenes a world bias helps some scenes and hurts others — it lowers "
               "`sm_lamp_contact`'s error and raises `sv_open_mesh`'s (the error rate of light 0; "
               "[tuning](../tuning.md#near-planes-and-the-world-distance-bias))."),
        source=("`experiments/light_frusta.py` at its default size, 320×240 (provenance: "
                "[`results/light_frusta/provenance.json`](../../results/light_frusta/provenance.json))"),
        keys=(("sm_lamp_contact", 0), ("sv_open_mesh", 0)),
        columns=(
            Column("window depth (the default)", "results/light_frusta/defaults.csv",
                   (("technique", "virtual_map"),)),
            Column("world distance, bias = 0.0005 × the extent", "results/light_frusta/virtual_map_bias.csv",
                   (("technique", "virtual_map:bias=0.0005"),)),
        ),
    ),
)


# --------------------------------------------------------------------------- text

def _relative(path: Path) -> str:
    """A link from a page in docs/techniques/ to ``path`` (a file or folder of the repository)."""
    rel = path.resolve().relative_to(REPO).as_posix()
    return ("../" + rel[len("docs/"):]) if rel.startswith("docs/") else "../../" + rel


@functools.lru_cache(maxsize=None)
def _anchors(page: Path) -> frozenset[str]:
    """GitHub's anchors of a markdown page's headings (as tests/project/test_docs.py computes them)."""
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    return frozenset(re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-")
                     for h in re.findall(r"^#+ (.*)$", text, re.M))


_PATH = re.compile(r"(?<![\w/.`\[])((?:docs|tests|experiments|results|shadowlab)/[\w./\-]*[\w/](?:#[\w\-]+)?)")


def _link_target(text: str) -> str | None:
    """The page-relative link for a repository path such as ``docs/tuning.md#x`` or
    ``tests/techniques/maps/test_pcss.py``; None when nothing is there. An anchor that the page
    does not have is dropped (the link goes to the page)."""
    path, _, anchor = text.partition("#")
    file = REPO / path.rstrip("/")
    if not path or not file.exists():
        return None
    target = _relative(file) + ("/" if path.endswith("/") and file.is_dir() else "")
    if anchor and file.suffix == ".md" and anchor in _anchors(file):
        target += "#" + anchor
    return target


def _prose(text: str) -> str:
    """Markdown outside code spans: repository paths become links, and what markdown would read
    as HTML (``<`` before a letter) is escaped."""
    def link(m: re.Match) -> str:
        target = _link_target(m.group(1))
        return f"[{m.group(1)}]({target})" if target else m.group(1)

    text = re.sub(r"<(?=[A-Za-z/!])", "&lt;", text)
    return _PATH.sub(link, text)


def rest_to_markdown(doc: str) -> str:
    """A docstring (reST, as the package writes them) as markdown: roles and double backticks as
    :func:`shadowlab.util.text._markdown` turns them, ``::`` ending a paragraph as a colon,
    repository paths (bare or in backticks) as links, and the few line starts that markdown
    would read as markup of its own (a heading, a quote, a rule) escaped."""
    text = _markdown(inspect.cleandoc(doc))
    text = re.sub(r"(?<=\S)::$", ":", text, flags=re.M)
    lines = []
    for line in text.split("\n"):
        if re.match(r"\s{0,3}(#|>|[-=_*]{3,}\s*$)", line):
            line = re.sub(r"^(\s*)", r"\1\\", line, count=1)
        lines.append(line)
    text = "\n".join(lines)
    parts = re.split(r"(`[^`]*`)", text)
    out = []
    for i, part in enumerate(parts):
        if i % 2:  # a code span: a repository path in it becomes a link around it
            target = _link_target(part[1:-1]) if _PATH.fullmatch(part[1:-1]) else None
            out.append(f"[{part}]({target})" if target else part)
        else:
            out.append(_prose(part))
    return "".join(out).strip()


def _value(value) -> str:
    from ..techniques.base import format_value

    return f"`{format_value(value)}`"


def _num(x: float) -> str:
    """A bound as written in code: ``16384`` for 16384.0, ``1e-06``, ``0.5``."""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else repr(float(x))


def _allowed(param) -> str:
    """A parameter's legal values in words: its choices, true | false, or its range."""
    kind = type(param.default)
    if param.choices is not None:
        return " \\| ".join(_value(c) for c in param.choices)
    if kind is bool:
        return "`true` \\| `false`"
    if kind is str:
        return "any string"
    bounds = []
    if param.min is not None:
        bounds.append(f"{'>' if param.min_open else '≥'} {_num(param.min)}")
    if param.max is not None:
        bounds.append(f"≤ {_num(param.max)}")
    return f"{kind.__name__}" + (f", {', '.join(bounds)}" if bounds else "")


def _tune(param) -> str:
    t = param.tune
    return f"{_num(t.lo)} – {_num(t.hi)}" + (", log" if t.log else "") if t is not None else ""


# --------------------------------------------------------------------------- what the code declares

def lights_cell(cls) -> str:
    """A technique's ``LIGHTS`` as a table cell: "all" when it renders every light type a scene
    can hold ("all (area: sampled)" for a light-sampled technique, which renders an area light
    as the average of point lights on it), else the type names."""
    from ..techniques.base import ALL_LIGHTS

    if cls.LIGHTS >= ALL_LIGHTS:
        return "all" + (" (area: sampled)" if cls.LIGHT_SAMPLED else "")
    return ", ".join(sorted(cls.LIGHTS))


def family_of(cls) -> str:
    """The technique family of a class: the folder of ``shadowlab/techniques/`` its module is in."""
    parts = cls.__module__.split(".")
    return parts[2] if len(parts) > 3 and parts[1] == "techniques" else "techniques"


def _ancestors(cls) -> list[type]:
    """The class and the classes of shadowlab.techniques it is built on, the base Technique left out."""
    from ..techniques.base import Technique

    return [c for c in cls.__mro__ if c is not Technique and c.__module__.startswith("shadowlab.techniques")]


def _class_node(cls) -> ast.ClassDef | None:
    tree = ast.parse(Path(inspect.getfile(cls)).read_text(encoding="utf-8"))
    return next((n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == cls.__name__), None)


def programs(cls) -> list[str]:
    """The GLSL programs the technique compiles: the file names its class and the classes it is
    built on pass as the first argument of a ``program(...)`` call, in the order they appear."""
    found: list[str] = []
    for c in _ancestors(cls):
        node = _class_node(c)
        for call in ast.walk(node) if node else ():
            if (isinstance(call, ast.Call) and isinstance(call.func, (ast.Attribute, ast.Name))
                    and (call.func.attr if isinstance(call.func, ast.Attribute) else call.func.id) == "program"
                    and call.args and isinstance(call.args[0], ast.Constant)
                    and str(call.args[0].value).endswith(".glsl") and call.args[0].value not in found):
                found.append(call.args[0].value)
    return found


def includes(names: list[str]) -> list[str]:
    """Every file the programs ``names`` ``#include``, transitively, in first-seen order."""
    from ..gpu.glsl import shader_files

    files = shader_files()
    seen: list[str] = []
    todo = list(names)
    while todo:
        name = todo.pop(0)
        path = files.get(name)
        if path is None:
            continue
        for inc in re.findall(r'^[ \t]*#[ \t]*include[ \t]+"([^"]+)"', path.read_text(encoding="utf-8"), re.M):
            if inc not in seen and inc not in names:
                seen.append(inc)
                todo.append(inc)
    return seen


@functools.lru_cache(maxsize=1)
def _suites() -> dict[str, dict[str, list[str]]]:
    """Per shipped suite, per scene, the technique names it runs there (suite order)."""
    from ..study.suite import builtin_suites, load_suite

    out: dict[str, dict[str, list[str]]] = {}
    for name, path in sorted(builtin_suites().items()):
        suite = load_suite(path)
        out[name] = {scene: sorted({spec.split(":")[0] for spec in specs})
                     for scene, specs in suite.configurations.items()}
    return out


def suites_running(name: str) -> dict[str, list[str]]:
    """The shipped suites that measure technique ``name``, each with the scenes it runs it on."""
    return {suite: [scene for scene, names in scenes.items() if name in names]
            for suite, scenes in _suites().items() if any(name in names for names in scenes.values())}


@functools.lru_cache(maxsize=1)
def _catalogue() -> dict[str, str]:
    """The hard-case catalogue's entries: scene → its text."""
    text = CATALOGUE.read_text(encoding="utf-8")
    parts = re.split(r"^### `([a-z0-9_]+)`[^\n]*$", text, flags=re.M)
    return {parts[i]: parts[i + 1].split("\n## ", 1)[0] for i in range(1, len(parts), 2)}


def _names(name: str) -> re.Pattern:
    """`name` in backticks, alone or as the start of a spec (`name:key=value`)."""
    return re.compile(rf"`{re.escape(name)}(?::[^`]*)?`")


def catalogue_entries(name: str) -> list[str]:
    """The scenes whose catalogue entry names technique ``name`` (in backticks, or a spec of it)."""
    pattern = _names(name)
    return [scene for scene, text in _catalogue().items() if pattern.search(text)]


def discussed_in(name: str) -> list[Path]:
    """The documentation pages (docs/*.md, the catalogue and the guide included) that name the
    technique in backticks."""
    pattern = _names(name)
    return [p for p in sorted(DOCS.glob("*.md")) if pattern.search(p.read_text(encoding="utf-8"))]


def _scene_link(scene: str) -> str:
    return f"[{scene}](../hard-cases.md#{scene})" if scene in _catalogue() else f"`{scene}`"


# --------------------------------------------------------------------------- measured, committed

def _rate(value) -> str:
    from ..evaluation.metrics import COLUMN_BY_NAME

    return COLUMN_BY_NAME["error_rate"].format(value)


@functools.lru_cache(maxsize=1)
def _quick():
    import pandas as pd

    results = pd.read_csv(QUICK_STUDY / "results.csv")
    meta = json.loads((QUICK_STUDY / "study.json").read_text(encoding="utf-8"))
    return results, meta


def quick_rows(name: str) -> list[str]:
    """Technique ``name``'s rows of the committed quick study as a markdown section (empty when
    the study does not run it): per scene and configuration, the error rate and the median time."""
    from ..output.pages import fmt_ms

    results, meta = _quick()
    rows = results[(results["technique"] == name) & (results["status"] == "ok")]
    if rows.empty:
        return []
    study = _relative(QUICK_STUDY)
    lines = ["### In the committed quick study", "",
             f"From [`results/quick/`]({study}/) (`shadowlab study quick`, {meta['size'][0]}×{meta['size'][1]}, "
             f"revision {meta['revision']}, renderer {meta['device']}); error rate against the ray-traced truth, "
             f"median time of {meta['repeat']} renders. Times are CPU-rasteriser times there: compare techniques "
             f"with each other, not with a GPU.", "",
             "| scene | light | configuration | error rate | time (ms) |", "|---|---|---|---|---|"]
    for _, r in rows.iterrows():
        error = "— (the truth)" if str(r.get("reference")).lower() == "true" else _rate(r["error_rate"])
        lines.append(f"| {_scene_link(r['scene'])} | {int(r['light'])} | `{_cell(r['short_label'])}` | "
                     f"{error} | {fmt_ms(r['time_ms_median'])} |")
    return lines + [""]


def evidence_rows(name: str) -> list[str]:
    """The :data:`EVIDENCE` tables of technique ``name`` as markdown (empty when it has none)."""
    import pandas as pd

    lines: list[str] = []
    for ev in (e for e in EVIDENCE if e.technique == name):
        frames = {}
        for col in ev.columns:
            table = pd.read_csv(REPO / col.file)
            for key, value in col.where:
                table = table[table[key].astype(str) == value]
            frames[col] = table
        lines += ["### Why its defaults are what they are", "", ev.claim, "",
                  f"Rows of the committed files, written by {ev.source}:", "",
                  "| scene | light | " + " | ".join(f"{c.label} ([`{Path(c.file).name}`]({_relative(REPO / c.file)}))"
                                                  for c in ev.columns) + " |",
                  "|---|---|" + "---|" * len(ev.columns)]
        for scene, light in ev.keys:
            cells = []
            for col in ev.columns:
                t = frames[col]
                hit = t[(t["scene"] == scene) & (t["light"].astype(int) == light)]
                if len(hit) != 1:
                    raise ValueError(f"{col.file}: {len(hit)} rows for {scene} light {light} {dict(col.where)}")
                cells.append(_rate(hit.iloc[0][col.value]))
            lines.append(f"| {_scene_link(scene)} | {light} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


# --------------------------------------------------------------------------- pages

def page(cls) -> str:
    """The reference page of one registered technique class."""
    from ..gpu.glsl import shader_files
    from ..techniques.base import BUDGET_PARAMS, LIGHT_SAMPLES

    name, family = cls.name, family_of(cls)
    module = Path(inspect.getfile(cls))
    built_on = [c for c in _ancestors(cls) if c is not cls]
    out = [f"# `{name}`", "", GENERATED_NOTE.format(fix=FIX_COMMAND), "", f"{_cell(cls.summary)}.", ""]
    facts = [f"- **Family:** [{family}](README.md#{family}) — module "
             f"[`{module.relative_to(REPO).as_posix()}`]({_relative(module)}), class `{cls.__name__}`"]
    if built_on:
        facts.append("- **Built on:** " + ", ".join(
            f"`{c.__name__}` ([`{Path(inspect.getfile(c)).relative_to(REPO).as_posix()}`]"
            f"({_relative(Path(inspect.getfile(c)))}))" for c in built_on))
    lights = [t for t in LIGHT_ORDER if t in cls.LIGHTS]
    facts.append("- **Lights:** " + ", ".join(f"`{t}`" for t in lights)
                 + (" (area lights: averaged over `light_samples` point lights on the light)"
                    if cls.LIGHT_SAMPLED and "area" in cls.LIGHTS else ""))
    facts.append(f"- **Runs on:** {'the CPU (no GL finish around its timing)' if cls.cpu else 'the GPU (GL)'}")
    facts.append("- **Reads from the G-buffer:** " + (", ".join(f"`{c}`" for c in GBUFFER_CHANNELS if c in cls.READS) if cls.READS else "nothing"))
    if cls.WRITES:
        facts.append("- **Borrows from the frame:** " + ", ".join(f"`{m}`" for m in sorted(cls.WRITES))
                     + " (everything else on the frame is read-only)")
    if cls.PROVIDES:
        facts.append("- **Provides:** " + ", ".join(f"`{c}`" for c in sorted(cls.PROVIDES))
                     + " (what the metrics and the tuner ask for: `CAPABILITIES` in `shadowlab/techniques/base.py`)")
    out += facts + [""]

    doc = sys.modules[cls.__module__].__doc__
    out += ["## Theory", "", rest_to_markdown(doc) if doc else "(no module docstring)", ""]

    out += ["## Parameters", "",
            f"A spec is `{name}` or `{name}:key=value,...`; unknown keys and bad values are errors. The tune range "
            "is what `shadowlab tune --param KEY` searches when given none.", "",
            "| parameter | default | values | tune range | what |", "|---|---|---|---|---|"]
    for key, param in cls.PARAMS.items():
        what = _cell(param.doc) + (" (the pipeline's light sampling)" if param is LIGHT_SAMPLES else "")
        out.append(f"| `{key}` | {_value(param.default)} | {_allowed(param)} | {_tune(param)} | {what} |")
    if not cls.PARAMS:
        out.append("| — | | | | none |")
    out += ["", "Like every technique it also accepts a shadow budget for scenes with many lights: "
            + ", ".join(f"`{k}`" for k in BUDGET_PARAMS)
            + " ([many-lights.md](../many-lights.md#a-shadow-budget-on-any-technique)).", ""]

    out += ["## Passes", "", "Drawn in this order by `render()`, each timed on its own with `--pass-timing` "
            "(`pass_<name>_ms`) and counted by the work counters:", ""]
    out += [f"{i}. `{p}`" for i, p in enumerate(cls.PASSES, 1)] + [""]

    out += ["## Stats", "", "The cost columns `stats()` adds to each row, and how each combines over the light "
            "samples of one frame:", "", "| stat | combines |", "|---|---|"]
    out += [f"| `{k}` | `{v}`: {RULES[v]} |" for k, v in cls.STATS.items()] + [""]

    progs = programs(cls)
    if progs:
        files = shader_files()

        def glsl(n: str) -> str:
            return f"[`{n}`]({_relative(files[n])})" if n in files else f"`{n}`"

        out += ["## Shaders", "", "Programs it compiles (`self.program(...)` in its class"
                + (" and the classes it is built on" if built_on else "") + "): "
                + ", ".join(glsl(n) for n in progs) + "."]
        incs = includes(progs)
        if incs:
            out += ["", "Files they include: " + ", ".join(glsl(n) for n in incs) + "."]
        out.append("")

    suites = suites_running(name)
    entries = catalogue_entries(name)
    pages = [p for p in discussed_in(name)]
    if suites or entries or pages:
        out += ["## Where it is measured", ""]
        if suites:
            out += ["Shipped suites that run it (`shadowlab study SUITE`), and on which scenes:", ""]
            out += [f"- `{s}`: " + ", ".join(_scene_link(sc) for sc in scenes) for s, scenes in suites.items()]
            out.append("")
        if entries:
            out += ["Hard cases whose catalogue entry names it: "
                    + ", ".join(_scene_link(s) for s in entries) + ".", ""]
        if pages:
            out += ["Discussed in: " + ", ".join(f"[{p.stem}]({_relative(p)})" for p in pages) + ".", ""]

    measured = quick_rows(name) + evidence_rows(name)
    if measured:
        out += ["## Measured", ""] + measured
    return "\n".join(out).rstrip() + "\n"


def index(registry=None) -> str:
    """The index of the reference pages: per family (its package's docstring), each technique
    with its summary, light types and passes."""
    import importlib

    if registry is None:
        from ..techniques import REGISTRY as registry
    families: dict[str, list] = {}
    for cls in registry.values():
        families.setdefault(family_of(cls), []).append(cls)
    out = ["# Technique reference", "", GENERATED_NOTE.format(fix=FIX_COMMAND).replace(
               "the technique's module (its docstring and declarations)", "the techniques' modules"), "",
           "One page per registered technique, generated from its own declarations: the theory from its "
           "module's docstring, its parameters, passes, lights and stats, the GLSL it compiles, the suites and "
           "hard cases that measure it, and figures from committed results only. The families are the folders of "
           "[`shadowlab/techniques/`](../../shadowlab/techniques/); how to add a technique: "
           "[adding a technique](../adding-a-technique.md).", ""]
    out += [" · ".join(f"[{f}](#{f})" for f in sorted(families)), ""]
    for fam in sorted(families):
        package = importlib.import_module(f"shadowlab.techniques.{fam}") if fam != "techniques" else None
        summary = first_sentence(package.__doc__, limit=400) if package and package.__doc__ else ""
        out += [f"## {fam}", "", summary, "",
                "| technique | what | lights | passes |", "|---|---|---|---|"]
        for cls in sorted(families[fam], key=lambda c: c.name):
            out.append(f"| [`{cls.name}`]({cls.name}.md) | {_cell(cls.summary)} | {_cell(lights_cell(cls))} | "
                       + _cell(", ".join(f"`{p}`" for p in cls.PASSES)) + " |")
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def generated(registry=None) -> dict[Path, str]:
    """Every page, freshly made from the code: path → text (the index included)."""
    if registry is None:
        from ..techniques import REGISTRY as registry
    pages = {PAGES / f"{name}.md": page(cls) for name, cls in registry.items()}
    pages[INDEX] = index(registry)
    return pages


def differences(registry=None) -> dict[str, str]:
    """Per page that differs from its generated text, a unified diff (committed → generated); a
    missing page, and a page left over from a technique that is no longer registered, are
    reported too. Empty when every page is up to date."""
    fresh = generated(registry)
    out = {}
    for path, text in fresh.items():
        rel = path.relative_to(REPO).as_posix()
        if not path.is_file():
            out[rel] = f"{rel} is missing"
            continue
        current = path.read_text(encoding="utf-8")
        if current != text:
            out[rel] = "\n".join(difflib.unified_diff(current.splitlines(), text.splitlines(), rel, "generated",
                                                      lineterm=""))
    for path in sorted(PAGES.glob("*.md")) if PAGES.is_dir() else ():
        if path not in fresh:
            out[path.relative_to(REPO).as_posix()] = f"{path.name}: no registered technique has this page"
    return out


def write(registry=None) -> bool:
    """Write every page from the code and remove pages of techniques no longer registered;
    True when something changed."""
    fresh = generated(registry)
    PAGES.mkdir(parents=True, exist_ok=True)
    changed = False
    for path, text in fresh.items():
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")
            changed = True
    for path in sorted(PAGES.glob("*.md")):
        if path not in fresh:
            path.unlink()
            changed = True
    return changed


def main(argv: list[str] | None = None) -> int:
    """List the pages that differ from the code, or (``--write``) rewrite them."""
    p = argparse.ArgumentParser(prog="python -m shadowlab.docgen.technique_pages",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--write", action="store_true", help="rewrite docs/techniques/ from the code")
    args = p.parse_args(argv)
    if args.write:
        changed = write()
        print(f"technique pages {'updated' if changed else 'already up to date'}: {PAGES.relative_to(REPO)}/")
        return 0
    diffs = differences()
    for rel in diffs:
        print(f"differs: {rel}")
    print(f"{len(diffs)} of {len(generated()) } pages differ" + (f"; fix: {FIX_COMMAND}" if diffs else ""))
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
