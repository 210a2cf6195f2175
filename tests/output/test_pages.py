"""The HTML pages (docs/architecture.md#pages-shadowlaboutput) as a reader's browser gets them: a compare page, a study page and an
animate page, made once per module at PAGE_SIZE with two or three configurations.

* Always (standard-library parser, no browser, a few seconds): one <h1>; every <img src>, every
  image a view button swaps in (``data-*`` attributes), every CSS ``url(...)`` (style attributes
  and <style>) and every relative link names a readable file next to the page; every
  ``href="#..."`` has its target and ids are unique; strings the user controls (a scene name, a
  study's name and description, a failed run's message, with ``<b>``, ``<script>``, ``&`` and
  ``"``) come out as text, never as markup.
* With headless Chromium (``slow``; skipped without it): each page loads without an uncaught
  error, a failed resource load or a console.error, also after every view button is clicked; every
  image (lazy ones included) and every inset's background decodes; the study's verdict table —
  on a table shaped like the shipped quick suite's (its scenes, families and description) — ends
  within the first screen at 1400×900.

The animate page is found as whatever .html the animate run directory holds, so the test does not
depend on the name or template that page is written with.
"""
from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pandas as pd
import pytest

from shadowlab.gpu import gl
from shadowlab.commands.animate import animate
from shadowlab.commands.compare import compare
from shadowlab.scene import resolve_scene_path, scene_purpose
from shadowlab.output.pictures import save_png
from shadowlab.study.report import write_study_html
from shadowlab.study.suite import load_suite

#: Strings a user controls, each with markup, an ampersand and a quote: the scene name (scene file),
#: the study's name and description (suite file) and a failed run's error message.
SCENE_NAME = "a<b>&c \"q\" <script>alert('scene')</script>"
STUDY_NAME = "t<u>x</u> & \"co\""
DESCRIPTION = "<script>alert('description')</script> & <b>bold</b>"
FAIL_MESSAGE = "RuntimeError: <i>boom</i> & \"more\" <script>alert('failed')</script>"
#: The configurations of the compare run (the study's scenes all show its images): a shadow map
#: (footprint map), shadow volumes, planar shadows (signed map).
SPECS = ["shadow_map:resolution=256", "shadow_volume", "planar"]
#: The pages' image size: small, the pages' structure does not depend on it (80x60 keeps the module
#: fixture near 3 s of the inner loop).
PAGE_SIZE = (80, 60)
#: The browser's window (the study's first screen).
WINDOW = (1400, 900)
IMAGE_SUFFIXES = (".png", ".gif", ".jpg", ".jpeg", ".svg", ".webp")


def _scene_file(folder: Path) -> Path:
    """The shipped animated scene tm_rotating_sun (directional light, builtin meshes only) under
    :data:`SCENE_NAME`."""
    text = resolve_scene_path("tm_rotating_sun").read_text()
    text, n = re.subn(r'^name = ".*"$', lambda _: f"name = {json.dumps(SCENE_NAME)}", text, count=1, flags=re.M)
    assert n == 1
    path = folder / "odd_scene.toml"
    path.write_text(text)
    return path


def _study_results(run: Path, run_dir: str) -> tuple[pd.DataFrame, dict]:
    """A results table shaped like the shipped quick suite's study (its scenes, their families,
    every technique family it runs, its description) from one real compare run: every scene
    shows that run's images; the first scene is named :data:`SCENE_NAME`; one configuration
    failed with :data:`FAIL_MESSAGE`."""
    quick = load_suite("quick")
    families = list(dict.fromkeys(spec.split(":")[0] for specs in quick.configurations.values() for spec in specs))
    measured = pd.read_csv(run / "metrics.csv")
    truth = measured[measured["reference"].astype(bool)].iloc[0]
    configs = measured[~measured["reference"].astype(bool)]
    rows, scenes = [], {}
    for i, entry in enumerate(quick.scenes):
        name = SCENE_NAME if i == 0 else entry.name
        scenes[name] = {"family": entry.family, "metric": entry.metric, "purpose": scene_purpose(entry.path)}
        rows.append({**truth.to_dict(), "scene": name})
        for k, family in enumerate(families):
            row = {**configs.iloc[k % len(configs)].to_dict(), "scene": name, "technique": family, "params": "",
                   "label": family, "short_label": family, "reference": False}
            row["error_rate"] = 0.001 * ((i + k) % 7)
            row["time_ms_median"] = 1.0 + (3 * i + k) % 5
            if i == 1 and k == len(families) - 1:
                row.update(status="failed", error=FAIL_MESSAGE)
            rows.append(row)
    df = pd.DataFrame(rows)
    df["scene_family"] = [scenes[s]["family"] for s in df["scene"]]
    df["status"] = df.get("status", pd.Series(index=df.index, dtype=object)).fillna("ok")
    df["error"] = df.get("error", pd.Series(index=df.index, dtype=object)).fillna("")
    failed = df["status"] == "failed"
    for c in ("evaluated_pixels", "error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px",
              "visibility_mae", "time_ms_median", "time_ms_iqr"):
        df.loc[failed, c] = np.nan
    df["run_dir"] = np.where(failed, "", run_dir)
    df["revision"] = "abc123"
    df["renderer"] = gl.renderer()
    meta = {"name": STUDY_NAME, "description": f"{quick.description} {DESCRIPTION}", "size": list(PAGE_SIZE),
            "repeat": 1, "warmup": 0, "device": gl.device(), "renderer": gl.renderer(), "revision": "abc123",
            "date": "2026-01-01T00:00:00+00:00", "timing": "wall clock", "workers": 1, "elapsed_s": 1.0,
            "runs": len(df), "cached": 0, "failed": 1, "suite_file": "/somewhere/quick.toml", "scenes": scenes}
    return df, meta


def make_pages(root: Path) -> dict[str, list[Path]]:
    """{"compare": [report.html], "study": [study.html], "animate": [its .html pages]} under
    ``root``: a compare run (inside a study directory, as a study's scene run), the study page over
    it, and an animate run of 2 frames, all of the scene named :data:`SCENE_NAME`."""
    scene = _scene_file(root)
    study = root / "study"
    run = study / "runs" / "odd"
    compare(scene, SPECS, PAGE_SIZE, run, repeat=1, warmup=0)
    results, meta = _study_results(run, "runs/odd")
    # the page, not the Pareto figure (tests/study/test_study_report.py draws that; drawing it here would
    # cost the inner loop about 3.5 s): a small stand-in image under its name
    save_png(study / "pareto.png", np.full((40, 60, 3), 0.8))
    write_study_html(study, results, meta)
    moving = animate(scene, SPECS[:2], frames=2, size=PAGE_SIZE, out=root / "animate")
    found = {"compare": [run / "report.html"], "study": [study / "study.html"],
             "animate": sorted(Path(moving).glob("*.html"))}
    assert found["animate"], f"animate wrote no .html page into {moving}"
    for kind, paths in found.items():
        for p in paths:
            assert p.is_file(), f"{kind}: no {p}"
    return found


@pytest.fixture(scope="module")
def pages(tmp_path_factory) -> dict[str, list[Path]]:
    """The three pages, made once per module (:func:`make_pages`)."""
    return make_pages(tmp_path_factory.mktemp("pages"))


#: Where each page's user-controlled strings appear.
USER_STRINGS = {"compare": [SCENE_NAME], "animate": [SCENE_NAME],
                "study": [SCENE_NAME, STUDY_NAME, DESCRIPTION, FAIL_MESSAGE]}
PAGE_KINDS = list(USER_STRINGS)


# ----------------------------------------------------------------------------- the parser

class Page(HTMLParser):
    """One page as the standard library's parser sees it: start tags (name, attributes, line),
    the text with a NUL wherever a tag was (so text split by markup is not contiguous), the
    contents of <script> and <style> elements."""

    def __init__(self, text: str):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict, int]] = []
        self.pieces: list[str] = []
        self.scripts: list[str] = []
        self.styles: list[str] = []
        self._raw: str | None = None  # "script" / "style" while inside one
        self.feed(text)
        self.close()
        self.text = "".join(self.pieces)

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, {k: v or "" for k, v in attrs}, self.getpos()[0]))
        self.pieces.append("\0")
        if tag in ("script", "style"):
            self._raw = tag
            (self.scripts if tag == "script" else self.styles).append("")

    def handle_startendtag(self, tag, attrs):
        self.tags.append((tag, {k: v or "" for k, v in attrs}, self.getpos()[0]))
        self.pieces.append("\0")

    def handle_endtag(self, tag):
        self.pieces.append("\0")
        if tag == self._raw:
            self._raw = None

    def handle_data(self, data):
        if self._raw == "script":
            self.scripts[-1] += data
        elif self._raw == "style":
            self.styles[-1] += data
        else:
            self.pieces.append(data)

    def count(self, tag: str) -> int:
        return sum(1 for t, _, _ in self.tags if t == tag)


_URL = re.compile(r"""url\(\s*(['"]?)(.*?)\1\s*\)""")


def _local_file(page: Path, ref: str) -> tuple[Path | None, str | None]:
    """(file, None) for a relative reference from ``page``; (None, why) when it cannot be one;
    (None, None) for a data: URI (nothing to check)."""
    parts = urlsplit(ref)
    if parts.scheme == "data":
        return None, None
    if parts.scheme or parts.netloc:
        return None, "not a file next to the page (pages must work offline, moved as a folder)"
    if not parts.path:
        return None, "empty reference"
    return page.parent / unquote(parts.path), None


def _image_problem(path: Path) -> str | None:
    """Why ``path`` is no readable image (Pillow), or None."""
    from PIL import Image

    if not path.is_file():
        return "no such file"
    try:
        with Image.open(path) as im:
            im.verify()
    except Exception as exc:  # noqa: BLE001 - any failure to read is the finding
        return f"not a readable image ({type(exc).__name__}: {exc})"
    return None


def page_problems(page: Path) -> list[str]:
    """Everything wrong with one page file that can be seen without a browser (see the module
    docstring), one line each."""
    doc = Page(page.read_text(encoding="utf-8"))
    problems = []
    if doc.count("h1") != 1:
        problems.append(f"{doc.count('h1')} <h1> elements, not exactly one")
    # every image the page shows or a button swaps in, every CSS url(), every relative link
    images: list[tuple[str, str, int]] = []   # (what, reference, line)
    links: list[tuple[str, str, int]] = []
    for tag, attrs, line in doc.tags:
        if tag == "img":
            images.append(("<img src>", attrs.get("src", ""), line))
        for name, value in attrs.items():
            if name.startswith("data-") and value.lower().endswith(IMAGE_SUFFIXES):
                images.append((f"<{tag} {name}>", value, line))
        for _, url in _URL.findall(attrs.get("style", "")):
            images.append((f"<{tag} style> url()", url, line))
        if tag in ("a", "link") and attrs.get("href") and not attrs["href"].startswith("#"):
            if urlsplit(attrs["href"]).scheme not in ("http", "https", "mailto"):
                links.append((f"<{tag} href>", attrs["href"], line))
        if tag == "script" and attrs.get("src"):
            links.append(("<script src>", attrs["src"], line))
    for css in doc.styles:
        images.extend(("<style> url()", url, 0) for _, url in _URL.findall(css))
    checked: dict[Path, str | None] = {}
    for what, ref, line in images:
        path, why = _local_file(page, ref)
        if path is not None:
            if path not in checked:
                checked[path] = _image_problem(path)
            why = checked[path]
        if why:
            problems.append(f"line {line}: {what} {ref!r}: {why}")
    for what, ref, line in links:
        path, why = _local_file(page, ref)
        if path is not None and not path.is_file():
            why = "no such file"
        if why:
            problems.append(f"line {line}: {what} {ref!r}: {why}")
    # internal anchors and ids
    ids = [attrs["id"] for _, attrs, _ in doc.tags if "id" in attrs]
    names = {attrs["name"] for tag, attrs, _ in doc.tags if tag == "a" and "name" in attrs}
    dup = sorted({i for i in ids if ids.count(i) > 1})
    if dup:
        problems.append(f"ids used more than once: {dup}")
    for tag, attrs, line in doc.tags:
        href = attrs.get("href", "")
        if href.startswith("#") and href != "#" and unquote(href[1:]) not in set(ids) | names:
            problems.append(f"line {line}: <{tag} href={href!r}>: no element has that id")
    return problems


def escaping_problems(page: Path, strings: list[str]) -> list[str]:
    """Where a user-controlled string did not come out as text: missing from the text as one
    piece (a tag of its own split it, or it was dropped), written raw into the source, or any
    <script> element's code containing its ``alert(``."""
    source = page.read_text(encoding="utf-8")
    doc = Page(source)
    problems = []
    for s in strings:
        if s not in doc.text:
            problems.append(f"{s!r} is not on the page as text (its markup became tags, or it is missing)")
        if s in source:
            problems.append(f"{s!r} is in the page source unescaped")
    for code in doc.scripts:
        if "alert(" in code:
            problems.append(f"a <script> element runs user text: {code[:80]!r}")
    return problems


@pytest.mark.parametrize("kind", PAGE_KINDS)
def test_page_structure_and_files(pages, kind):
    for page in pages[kind]:
        problems = page_problems(page)
        assert not problems, f"{kind} page {page.name}:\n" + "\n".join(problems)


@pytest.mark.parametrize("kind", PAGE_KINDS)
def test_user_strings_are_escaped(pages, kind):
    for page in pages[kind]:
        problems = escaping_problems(page, USER_STRINGS[kind])
        assert not problems, f"{kind} page {page.name}:\n" + "\n".join(problems)


def test_animate_notes_appear_once_with_their_frames(pages):
    """A note every frame repeats (shadow volumes on the open floor of tm_rotating_sun) is one
    line, "frames 0–1: <spec>: <note>", not one line per frame (issue 38)."""
    for page in pages["animate"]:
        source = page.read_text(encoding="utf-8")
        notes = re.search(r"<h2>Notes</h2>(.*?)</ul>", source, re.S)
        assert notes, f"{page.name}: no notes (shadow_volume reports the floor's boundary edges)"
        items = [html.unescape(i).strip() for i in re.findall(r"<li>(.*?)</li>", notes.group(1), re.S)]
        assert len(items) == len(set(items)), items
        floor = [i for i in items if "boundary edges" in i]
        assert len(floor) == 1 and floor[0].startswith("frames 0–1: shadow_volume"), items
        assert not [i for i in items if re.match(r"frame \d+:", i)], items  # no note repeated per frame
        record = json.loads((page.parent / "animation.json").read_text())
        assert record["notes"] == items


def test_the_checks_find_what_they_look_for(tmp_path):
    """The parser checks themselves, on a hand-made broken page: a second <h1>, a missing image,
    a missing inset background, a truncated image, a dangling anchor, a duplicate id, raw markup."""
    from shadowlab.output.pictures import save_png

    save_png(tmp_path / "ok.png", np.full((4, 4, 3), 0.5))
    (tmp_path / "cut.png").write_bytes((tmp_path / "ok.png").read_bytes()[:20])
    page = tmp_path / "p.html"
    page.write_text('<h1>one</h1><h1>two</h1><img src="ok.png"><img src="gone.png"><img src="cut.png">'
                    '<div style="background-image:url(&#39;also_gone.png&#39;)"></div>'
                    '<div data-shaded="missing_view.png"></div><a href="#nowhere">x</a>'
                    '<p id="a"></p><p id="a"></p><p>a<b>&c</p>')
    problems = "\n".join(page_problems(page))
    for expected in ("2 <h1>", "'gone.png': no such file", "'cut.png': not a readable image",
                     "'also_gone.png': no such file", "'missing_view.png'", "'#nowhere'", "['a']"):
        assert expected in problems, (expected, problems)
    assert "'ok.png'" not in problems
    assert escaping_problems(page, ["a<b>&c"])
    page.write_text("<h1>x</h1><p>a&lt;b&gt;&amp;c</p>")
    assert not page_problems(page) and not escaping_problems(page, ["a<b>&c"])


# ----------------------------------------------------------------------------- the browser

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)

#: Put first into <head> (after <meta charset>): records uncaught errors, unhandled rejections, failed resource loads
#: (error events do not bubble, so they are caught on the way down), console.error calls and
#: dialogs (alert() would otherwise block headless Chromium until it is killed).
PROBE_EARLY = """<script>(function () {
  var p = window.__probe = {errors: []};
  window.addEventListener("error", function (e) {
    var t = e.target;
    if (t && t !== window && t.tagName)
      p.errors.push("failed to load <" + t.tagName.toLowerCase() + "> " + (t.currentSrc || t.src || t.href || ""));
    else p.errors.push("uncaught " + e.message + " at " + e.filename + ":" + e.lineno);
  }, true);
  window.addEventListener("unhandledrejection", function (e) { p.errors.push("unhandled rejection: " + e.reason); });
  ["alert", "confirm", "prompt"].forEach(function (f) {
    window[f] = function (m) { p.errors.push(f + "(" + m + ") called"); };
  });
  var ce = console.error;
  console.error = function () {
    p.errors.push("console.error: " + Array.prototype.join.call(arguments, " "));
    return ce.apply(console, arguments);
  };
})();</script>"""

#: Put last into <body>, where it runs while the page is still loading: makes lazy images eager
#: and adds an invisible <img> for every CSS background image and every image a view button swaps
#: in, so the load event waits for all of them; at load, checks every image (loaded and decoded:
#: naturalWidth > 0), measures the verdict table, clicks every view button (a handler's exception
#: is caught by PROBE_EARLY) and writes the findings as JSON into <pre id="probe-result">, read back
#: from --dump-dom. Everything after load is synchronous: async work (img.decode()) is not reliably
#: finished under --virtual-time-budget.
PROBE_LATE = """<script>(function () {
  var p = window.__probe, suffix = /\\.(png|gif|jpe?g|svg|webp)$/i, urls = {};
  document.querySelectorAll("img[loading]").forEach(function (i) { i.loading = "eager"; });
  document.querySelectorAll("*").forEach(function (el) {
    Array.prototype.forEach.call(el.attributes, function (a) {
      if (a.name.indexOf("data-") === 0 && suffix.test(a.value)) urls[new URL(a.value, document.baseURI).href] = a.name;
    });
    if (el.hasAttribute("style")) {
      var m = getComputedStyle(el).backgroundImage.match(/url\\("?(.*?)"?\\)/);
      if (m) urls[m[1]] = "background";
    }
  });
  var hidden = document.createElement("div");
  hidden.style.cssText = "position:absolute;left:0;top:0;width:1px;height:1px;overflow:hidden;opacity:0";
  Object.keys(urls).forEach(function (u) {
    var im = document.createElement("img");
    im.src = u; im.setAttribute("data-probe", urls[u]); hidden.appendChild(im);
  });
  document.body.appendChild(hidden);
  window.addEventListener("load", function () {
    p.broken = [];
    p.images = document.images.length;
    p.probed = Object.keys(urls).length;
    Array.prototype.forEach.call(document.images, function (i) {
      if (!(i.complete && i.naturalWidth > 0))
        p.broken.push("broken image " + (i.getAttribute("data-probe") ? "(" + i.getAttribute("data-probe") + ") " : "")
                      + i.src);
    });
    window.scrollTo(0, 0);
    var v = document.getElementById("verdict-table");
    p.verdict = v ? {top: v.getBoundingClientRect().top, bottom: v.getBoundingClientRect().bottom, right: 0,
                     columns: 0} : null;
    if (v) v.querySelectorAll("th, td").forEach(function (c) {
      var r = c.getBoundingClientRect();
      p.verdict.right = Math.max(p.verdict.right, r.right);
      if (c.tagName === "TH" && c.parentElement.rowIndex <= 1) p.verdict.columns += 1;
    });
    p.viewport = [window.innerWidth, window.innerHeight];
    var buttons = document.querySelectorAll("button[data-show]");
    p.clicks = buttons.length;
    buttons.forEach(function (b) { b.click(); });
    var out = document.createElement("pre");
    out.id = "probe-result";
    out.textContent = JSON.stringify(p);
    document.body.appendChild(out);
  });
})();</script>"""


def chromium_command(url: str, profile: Path) -> list[str]:
    """The headless Chromium run that loads ``url``, lets it run for 5 s of virtual time (time
    that jumps ahead whenever the page is idle: the load event comes well within it) and prints
    the DOM then; console messages go to stderr."""
    return [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", f"--window-size={WINDOW[0]},{WINDOW[1]}",
            "--hide-scrollbars", f"--user-data-dir={profile}", "--enable-logging=stderr", "--v=0",
            "--virtual-time-budget=5000", "--dump-dom", url]


def browse(page: Path, profile: Path) -> dict:
    """Open a copy of ``page`` with the probes in it (beside the page, so its relative references
    hold; removed after) in headless Chromium; the probe's findings, plus ``uncaught``: the
    "Uncaught ..." console lines Chromium logged."""
    source = page.read_text(encoding="utf-8")
    # the early probe after <meta charset> (which must come within the first 1024 bytes), else <head>
    head = re.search(r"<meta charset[^>]*>", source, re.I) or re.search(r"<head[^>]*>", source, re.I)
    body = source.lower().rfind("</body>")
    assert head and body >= 0, f"{page.name}: no <head> or </body> to put the probes in"
    probed = source[:head.end()] + PROBE_EARLY + source[head.end():body] + PROBE_LATE + source[body:]
    copy = page.with_name(f".probe-{page.name}")
    copy.write_text(probed, encoding="utf-8")
    try:
        done = subprocess.run(chromium_command(copy.as_uri(), profile), capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{page.name}: headless Chromium did not finish in 120 s (a dialog or an endless script?)")
    finally:
        copy.unlink()
    found = re.search(r'<pre id="probe-result">(.*?)</pre>', done.stdout, re.S)
    assert found, (f"{page.name}: the probe reported nothing within the virtual time budget "
                   f"(exit {done.returncode}); stderr:\n{done.stderr[-3000:]}")
    result = json.loads(html.unescape(found.group(1)))
    result["uncaught"] = [m for m in re.findall(r':CONSOLE[^\]]*\] "(.*)", source: ', done.stderr)
                          if m.startswith("Uncaught")]
    return result


@pytest.mark.slow  # starts a browser per page (about 1-2 s each)
@pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium not installed; apt-get install chromium")
def test_pages_in_a_browser(pages, tmp_path):
    seen = {}
    for kind in PAGE_KINDS:
        for page in pages[kind]:
            r = browse(page, tmp_path / "profile")
            seen[f"{kind}/{page.name}"] = r
            problems = list(dict.fromkeys(r["errors"] + r["uncaught"] + r["broken"]))
            assert not problems, f"{kind} page {page.name} in Chromium:\n" + "\n".join(problems)
            assert r["images"] > 0, f"{kind} page {page.name}: no images"
    study = seen["study/study.html"]
    # the viewport of a 1400×900 headless window is 1400 × about 757 px (the window keeps room for
    # browser chrome, as a real one does): the first screen is what the page gets of it
    width, height = study["viewport"]
    assert width == WINDOW[0] and 600 < height <= WINDOW[1], study["viewport"]
    assert study["verdict"] is not None, "study page: no element with id verdict-table"
    # every verdict column (every technique family and scene) within the first screen's width
    assert study["verdict"]["columns"] > 1
    assert study["verdict"]["right"] <= width, (
        f"study page: the verdict table reaches {study['verdict']['right']:.0f} px across, beyond the first screen's "
        f"{width} px")
    assert study["verdict"]["bottom"] <= height, (
        f"study page: the verdict table ends {study['verdict']['bottom']:.0f} px down, below the first screen "
        f"({width}×{height} px of a {WINDOW[0]}×{WINDOW[1]} window)")
    assert seen["compare/report.html"]["clicks"] > 0 and seen["compare/report.html"]["probed"] > 0
