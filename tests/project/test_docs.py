"""The documentation cannot go stale unnoticed: the README's and the guide's generated tables and
the technique reference pages (docs/techniques/) match the code, every relative link in
README.md and docs/ resolves, every shipped scene has its entry in the hard-case catalogue and
every metrics column its definition. No GL."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from shadowlab.docgen import tables as docs_tables
from shadowlab.docgen import technique_pages
from shadowlab.evaluation import metrics
from shadowlab.evaluation.temporal import TEMPORAL_COLUMNS, RADIANCE_TEMPORAL_COLUMNS

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
PAGES = [README, *sorted(DOCS.glob("*.md")), *sorted((DOCS / "techniques").glob("*.md"))]


@pytest.mark.parametrize("table", docs_tables.TABLES)
def test_readme_tables_are_generated_from_the_code(table):
    diffs = docs_tables.differences()
    assert table not in diffs, (
        f"{docs_tables.HOMES[table].name}'s {table} differs from the code:\n{diffs[table]}\n\n"
        f"fix: {docs_tables.FIX_COMMAND}   (e.g. .venv/bin/python -m shadowlab.docgen.tables --write)")


def test_technique_pages_are_generated_from_the_code():
    """docs/techniques/: one page per registered technique and the index, each exactly what
    shadowlab.docgen.technique_pages makes from the code now (no page missing, none left over)."""
    diffs = technique_pages.differences()
    shown = "\n\n".join(diff[:3000] for diff in diffs.values())
    assert not diffs, (f"technique pages differ from the code: {sorted(diffs)}\n{shown}\n\n"
                       f"fix: {technique_pages.FIX_COMMAND}   (e.g. .venv/bin/python -m shadowlab.docgen.tables --write)")


def test_technique_pages_read_the_declarations(registry_snapshot):
    """A page is made from what the class declares: its family folder, parameters with their
    defaults, allowed values and tune range, passes, lights, stats with their combine rules, and
    the GLSL programs it compiles with what they include."""
    from shadowlab.techniques.base import FIRST, SUM, Param, PlotStyle, TuneRange
    from shadowlab.techniques.maps.shadow_map import ShadowMap

    text = technique_pages.page(ShadowMap)
    assert text.startswith("# `shadow_map`") and "[maps](README.md#maps)" in text
    assert "| `resolution` | `2048` | int, ≥ 16, ≤ 16384 | 256 – 8192, log |" in text
    assert "| `bias_space` | `world` | `world` \\| `window` \\| `units` \\| `texels` |" in text
    assert "1. `depth`" in text and "4. `lookup`" in text
    assert "[`shadow_lookup.glsl`](../../shadowlab/techniques/maps/shadow_lookup.glsl)" in text  # the toolkit's
    assert "[`lights.glsl`](../../shadowlab/gpu/lights.glsl)" in text  # included from gpu/
    assert "## Theory" in text and "Williams 1978" in text

    class Demo(ShadowMap):  # a technique made here: its page follows its own declarations
        name = "demo_page"
        summary = "a demo"
        PARAMS = {"k": Param(3, "a knob", min=1, max=9, tune=TuneRange(1, 5))}
        PASSES = ("one", "two")
        LIGHTS = frozenset({"spot"})
        STATS = {"n": SUM, "view": FIRST}
        STYLE = PlotStyle("#000000", "x")

    demo = technique_pages.page(Demo)
    assert "| `k` | `3` | int, ≥ 1, ≤ 9 | 1 – 5 | a knob |" in demo
    assert "1. `one`\n2. `two`" in demo and "- **Lights:** `spot`" in demo
    assert "| `n` | `sum`:" in demo and "| `view` | `first`:" in demo


def test_rest_roles_become_markdown_and_paths_links():
    md = technique_pages.rest_to_markdown(
        "See :func:`shadowlab.geometry.frusta.perspective_fit` and ``x < 1``, docs/tuning.md and\n"
        "tests/techniques/maps/test_pcss.py; computed as::\n\n    a = b\n")
    assert "`shadowlab.geometry.frusta.perspective_fit`" in md and "`x < 1`" in md
    assert "[docs/tuning.md](../tuning.md)" in md
    assert "[tests/techniques/maps/test_pcss.py](../../tests/techniques/maps/test_pcss.py)" in md
    assert "computed as:\n\n    a = b" in md


def _layout_module():
    """tests/project/test_layout.py, the test that holds the layers (its LAYERS and its import graph)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("_layout_for_docs", Path(__file__).with_name("test_layout.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_layers_section_is_what_the_layout_test_holds():
    """docs/architecture.md#layers: its table lists the packages layer by layer as
    tests/project/test_layout.py's LAYERS does, and its diagram's arrows are the package imports
    with those a longer path implies left out."""
    layout = _layout_module()
    text = (DOCS / "architecture.md").read_text(encoding="utf-8").split("\n## Layers\n", 1)[1].split("\n## ", 1)[0]
    listed: dict[int, set] = {}
    for layer, cell in re.findall(r"^\| (\d+) \| (.*?) \|", text, re.M):
        names = {n.rstrip("/").removesuffix(".py") for n in re.findall(r"`([\w./]+)`", cell)}
        listed.setdefault(int(layer), set()).update(names - {"__main__"})
    assert listed == {i: set(units) for i, units in enumerate(layout.LAYERS)}, listed

    edges = set()
    for a, b in layout._package_edges():
        ua, ub = layout._unit(a), layout._unit(b)
        if ub != "shadowlab" and ua != ub:
            edges.add((ua, ub))

    def reaches(start, target, skip):
        todo, seen = [start], set()
        while todo:
            node = todo.pop()
            for p, q in edges:
                if p == node and (p, q) != skip and q not in seen:
                    if q == target:
                        return True
                    seen.add(q)
                    todo.append(q)
        return False

    reduced = {(a, b) for a, b in edges if not reaches(a, b, (a, b))}
    mermaid = text.split("```mermaid", 1)[1].split("```", 1)[0]
    drawn = set(re.findall(r"^\s+(\w+)(?:\[[^\]]*\])? --> (\w+)", mermaid, re.M))
    assert drawn == reduced, f"drawn but not imported: {sorted(drawn - reduced)}; imported but not drawn: {sorted(reduced - drawn)}"


def test_tables_round_trip_through_the_markers():
    text = "intro\n<!-- layout-table:begin -->\nold\n<!-- layout-table:end -->\nrest\n"
    table = "| module | holds |\n|---|---|\n| `a.py` | A. |"
    new = docs_tables.replace(text, "layout-table", table)
    assert docs_tables.extract(new, "layout-table") == table
    assert new.startswith("intro\n") and new.endswith("\nrest\n")
    with pytest.raises(ValueError):
        docs_tables.replace("no markers", "technique-table", table)


def test_summaries_are_one_sentence_without_doc_references():
    doc = ("Shared shading: the extended Blinn model of docs/architecture.md#the-shading-pass over the G-buffer.\n\n"
           "More text.")
    assert docs_tables.first_sentence(doc) == "Shared shading: the extended Blinn model over the G-buffer."
    assert docs_tables.first_sentence("Suites (docs/contracts.md#study-directory): which scenes. And more.") == "Suites: which scenes."
    assert docs_tables.first_sentence(None) == ""
    assert docs_tables.first_sentence("Blob shadows: an ellipse under each caster (Akenine-M\u00f6ller et al. " + "x " * 150 + ").") == "Blob shadows: an ellipse under each caster."


def _links(page: Path):
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)  # not inside code blocks
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if not re.match(r"[a-z]+:", target):
            yield target


def _anchors(page: Path) -> set[str]:
    """GitHub's anchors of a markdown page's headings."""
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    return {re.sub(r"[^\w\- ]", "", h.strip().lower()).replace(" ", "-")
            for h in re.findall(r"^#+ (.*)$", text, re.M)}


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    broken = []
    for target in _links(page):
        path, _, anchor = target.partition("#")
        file = page.parent / path if path else page
        if not file.exists() or (anchor and file.suffix == ".md" and anchor not in _anchors(file)):
            broken.append(target)
    assert not broken, f"{page.relative_to(ROOT)} has links to files or headings that do not exist: {broken}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_references_outside_the_repository(page):
    text = page.read_text(encoding="utf-8")
    assert "DESIGN.md" not in text and "DESIGN §" not in text and "shared folder" not in text, (
        f"{page.relative_to(ROOT)} refers to the project's shared design, which a clone does not have: link docs/")


def test_every_shipped_scene_is_in_the_hard_case_catalogue():
    text = (DOCS / "hard-cases.md").read_text(encoding="utf-8")
    headings = set(re.findall(r"^### `([a-z0-9_]+)`", text, re.M))
    shipped = {p.stem for p in (ROOT / "shadowlab" / "scenes").glob("*.toml")}
    assert shipped <= headings, f"docs/hard-cases.md has no entry for {sorted(shipped - headings)}"
    assert headings <= shipped, f"docs/hard-cases.md describes scenes that are not shipped: {sorted(headings - shipped)}"


def test_the_catalogue_names_the_suites_each_scene_is_in():
    """Each entry's "Suites:" line names exactly the shipped suites that run the scene."""
    from shadowlab.study.suite import builtin_suites, load_suite

    text = (DOCS / "hard-cases.md").read_text(encoding="utf-8")
    suites = builtin_suites()
    runs: dict[str, set] = {}
    for name, path in suites.items():
        for scene in load_suite(path).scenes:
            runs.setdefault(scene.name, set()).add(name)
    wrong = []
    for scene, line in re.findall(r"^### `([a-z0-9_]+)`.*?^- \*\*Suites:\*\* ([^\n]*)", text, re.M | re.S):
        listed = {s for s in re.findall(r"`(\w+)`", line) if s in suites}
        if listed != runs.get(scene, set()):
            wrong.append(f"{scene}: lists {sorted(listed)}, runs in {sorted(runs.get(scene, set()))}")
    assert not wrong, "docs/hard-cases.md: " + "; ".join(wrong)


def test_every_metric_column_is_defined_in_the_metrics_page():
    text = (DOCS / "metrics.md").read_text(encoding="utf-8")
    names = [c.name for c in metrics.COLUMNS] + list(TEMPORAL_COLUMNS) + list(RADIANCE_TEMPORAL_COLUMNS)
    missing = [n for n in names if f"`{n}`" not in text]
    assert not missing, f"docs/metrics.md does not define {missing}"


def test_readme_scene_example_runs_as_copied(tmp_path, monkeypatch):
    """The README's scene file and its compare command run exactly as a reader copies them
    (at a smaller size, to keep the test fast)."""
    import re
    import shlex

    from shadowlab import cli

    text = README.read_text(encoding="utf-8")
    toml = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    (tmp_path / "my_scene.toml").write_text(toml)
    command = next(line for line in text.splitlines() if "shadowlab compare my_scene.toml" in line)
    args = shlex.split(command)[1:]
    args[args.index("--size") + 1] = "96x72"
    monkeypatch.chdir(tmp_path)
    assert cli.main(args + ["--repeat", "1", "--out", str(tmp_path / "run")]) == 0
    assert (tmp_path / "run" / "report.html").is_file()


def test_no_file_points_outside_the_repository():
    """Code, tests, shaders, scenes and pages refer to the design by docs/ links: no "DESIGN §"
    section numbers or HARD_CASES names of documents a clone does not have, and no evidence read
    from the project's shared folder (it is copied under results/)."""
    import subprocess

    files = subprocess.run(["git", "-C", str(ROOT), "ls-files"], capture_output=True, text=True).stdout.split()
    bad = []
    for name in files:
        if name.startswith("results/") or not re.search(r"\.(py|md|toml|glsl|html|js|css|sh|txt)$|Makefile$", name):
            continue
        if name == "tests/project/test_docs.py":
            continue
        text = (ROOT / name).read_text(encoding="utf-8", errors="replace")
        for needle in ("DESIGN §", "DESIGN.md", "HARD_CASES", "../shared/gpu"):
            if needle in text:
                bad.append(f"{name}: {needle}")
    assert not bad, bad
