"""docs/adding-a-technique.md, followed to the letter in a copy of the repository: the files the
page gives in full (the skeleton's module, shader and test file) are written where it says, the
suite line is added, the generated pages are regenerated with the command it names, and then

- the files that were added or edited are exactly the ones the page's table lists, as many as it
  says ("touches **N files**");
- the registry-wide tests and the skeleton's own tests pass on the new technique there, run in a
  fresh process with the copy on ``PYTHONPATH`` (the docs tests included: the regenerated pages
  are what the code makes).

So the page's count, its table and its skeleton cannot drift from the code (docs/architecture.md#layers
says where each part sits)."""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "adding-a-technique.md"
#: The skeleton's names, as the page gives them (checked against the page below).
NAME, FAMILY, SUITE = "box_proxy", "geometric", "hard_shadows"


def _files_in_the_page(text: str) -> dict[str, str]:
    """The files the page gives in full: a line "`path`:" followed by a fenced code block."""
    return {m.group(1): m.group(2)
            for m in re.finditer(r"^`([\w./]+)`:\n\n```\w*\n(.*?)```", text, re.M | re.S)}


def _table_paths(text: str) -> list[str]:
    """The paths of the page's "What a new technique touches" table, placeholders filled in."""
    section = text.split("## What a new technique touches", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| `([^`]+)` \|", section, re.M)
    return [r.replace("<family>", FAMILY).replace("<name>", NAME).replace("<suite>", SUITE) for r in rows]


def _tracked_copy(dest: Path) -> None:
    """The repository's git-tracked files (as they are in the working tree) copied to ``dest``."""
    files = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], capture_output=True, text=True,
                           check=True).stdout.split("\0")
    for name in filter(None, files):
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)


def _snapshot(tree: Path) -> dict[str, str]:
    """Path → content hash of every file of ``tree`` a commit could hold (no caches)."""
    out = {}
    for path in tree.rglob("*"):
        rel = path.relative_to(tree).as_posix()
        if path.is_file() and "__pycache__" not in rel and ".pytest_cache" not in rel:
            out[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def _run(tree: Path, *args: str, timeout: int = 900) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run([sys.executable, *args], cwd=tree, env=env, capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.slow
def test_a_technique_added_as_the_page_says_touches_the_files_it_says(tmp_path):
    text = DOC.read_text(encoding="utf-8")
    given = _files_in_the_page(text)
    module = f"shadowlab/techniques/{FAMILY}/{NAME}.py"
    shader = f"shadowlab/techniques/{FAMILY}/{NAME}.glsl"
    test_file = f"tests/techniques/{FAMILY}/test_{NAME}.py"
    assert set(given) == {module, shader, test_file}, f"the page gives these files in full: {sorted(given)}"
    assert f"`shadowlab/suites/{SUITE}.toml`" in text and re.search(rf'`"{NAME}"` joins its\s+`techniques` list', text)
    stated = re.search(r"touches \*\*(\d+) files\*\*", text)
    assert stated, "the page states how many files a new technique touches"

    tree = tmp_path / "repo"
    _tracked_copy(tree)
    before = _snapshot(tree)
    for rel, content in given.items():  # the three files, exactly as the page gives them
        assert not (tree / rel).exists(), f"{rel} exists already"
        (tree / rel).write_text(content, encoding="utf-8")
    suite = tree / "shadowlab" / "suites" / f"{SUITE}.toml"  # the one suite line
    suite_text = suite.read_text(encoding="utf-8")
    new_text, n = re.subn(r'(?m)^(techniques = \[.*?)\]', rf'\1, "{NAME}"]', suite_text, count=1, flags=re.S)
    assert n == 1, f"no techniques list in {suite}"
    suite.write_text(new_text, encoding="utf-8")
    done = _run(tree, "-m", "shadowlab.docgen.tables", "--write", timeout=300)  # the command the page names
    assert done.returncode == 0, done.stdout + done.stderr
    after = _snapshot(tree)

    changed = sorted(rel for rel in after if before.get(rel) != after[rel])
    removed = sorted(set(before) - set(after))
    assert not removed, removed
    assert changed == sorted(_table_paths(text)), f"changed: {changed}; the page's table: {_table_paths(text)}"
    assert len(changed) == int(stated.group(1)), f"the page says {stated.group(1)} files, {len(changed)} changed"

    # the registry-wide tests (only their cases for the new technique where they are parametrised
    # by technique), the skeleton's own tests and the docs tests, in the copy
    nodes = [test_file, "tests/techniques/test_techniques.py",
             f"tests/gpu/test_gl_state.py::test_every_other_technique_ignores_inherited_state[{NAME}]",
             f"tests/measurement/test_pipeline.py::test_techniques_leave_the_gbuffer_untouched[{NAME}]",
             "tests/measurement/test_pipeline.py::test_only_declared_techniques_get_the_depth_stencil",
             f"tests/gpu/test_work.py::test_counters_repeat_and_every_pass_is_named[{NAME}]",
             "tests/study/test_study.py::test_shipped_suites_load_and_cover_every_family",
             "tests/project/test_layout.py",
             "tests/project/test_docs.py::test_readme_tables_are_generated_from_the_code",
             "tests/project/test_docs.py::test_technique_pages_are_generated_from_the_code",
             "tests/project/test_docs.py::test_relative_links_resolve"]
    run = _run(tree, "-m", "pytest", "-q", "-p", "no:cacheprovider", *nodes)
    assert run.returncode == 0, run.stdout[-6000:] + run.stderr[-3000:]
    assert f"{NAME}" in _run(tree, "-m", "shadowlab", "techniques", NAME, timeout=120).stdout
