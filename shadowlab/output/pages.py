"""The Jinja2 pages of every run directory (docs/architecture.md#pages-shadowlaboutput): one environment with autoescaping,
one base template (``templates/base.html``: style, heading, the timing banner, provenance
footer) and a child template per page (compare, study, animate).

Values reach the templates raw and are escaped by Jinja2; the few formatting filters
(``pct``, ``ms``, ``num``, ``fixed``) are :mod:`shadowlab.util.format`'s, so every page reads alike.
"""
from __future__ import annotations

import functools
from pathlib import Path

import jinja2

from ..util.files import write_text_atomic
from ..util.format import fmt_fixed, fmt_ms, fmt_num, fmt_pct

TEMPLATES = Path(__file__).parent / "templates"

#: The sentence a page opens with when its times come from a CPU rasteriser.
SOFTWARE_BANNER = ("Times on this page were measured on a software rasteriser ({renderer}): they are CPU "
                   "times, good for comparing techniques with each other, not for judging a GPU.")


@functools.lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """The one Jinja2 environment: templates from :data:`TEMPLATES`, autoescaping on, undefined
    names an error (a typo in a template fails loudly instead of printing nothing)."""
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), autoescape=True,
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters.update(pct=fmt_pct, ms=fmt_ms, num=fmt_num, fixed=fmt_fixed)
    return env


def timing_banner(renderer: str | None) -> str | None:
    """:data:`SOFTWARE_BANNER` for a CPU rasteriser's GL_RENDERER string, else None."""
    from ..gpu.gl import is_software_name

    if renderer and is_software_name(renderer):
        return SOFTWARE_BANNER.format(renderer=renderer.split("(")[0].strip())
    return None


def provenance_items(record: dict) -> list[tuple[str, str]]:
    """The footer's (label, value) pairs from a run record (run.json, study.json, animation.json):
    device, revision, date, timing method, Python and package versions where present."""
    items = [("device", record.get("device") or record.get("renderer")), ("revision", record.get("revision")),
             ("date", record.get("date")), ("timing", record.get("timing_method") or record.get("timing"))]
    if record.get("repeat") is not None:
        items.append(("repeats", f"{record['repeat']} timed after {record.get('warmup', 0)} warm-up"))
    versions = record.get("versions")
    if isinstance(versions, dict) and versions:
        items.append(("versions", ", ".join(f"{k} {v}" for k, v in versions.items())))
    machine = record.get("machine")
    if isinstance(machine, dict) and machine.get("cpu"):
        items.append(("CPU", machine["cpu"]))
    return [(k, str(v)) for k, v in items if v not in (None, "")]


def render_page(template: str, path: Path, **context) -> Path:
    """Render ``template`` with ``context`` into ``path`` (through a temporary name, so a reader
    never sees half a page). The base template needs ``title``, ``renderer`` and ``provenance``
    (:func:`provenance_items`); the banner is derived from ``renderer``."""
    path = Path(path)
    context.setdefault("banner", timing_banner(context.get("renderer")))
    text = environment().get_template(template).render(**context)
    write_text_atomic(path, text)
    return path
