"""The ``shadowlab`` command: list scenes and techniques, run comparisons.

Bad input (scene, technique spec, size, ...) exits with status 2 and one line naming the
culprit, before any GL work; a missing GL driver exits with status 3.
"""
from __future__ import annotations

import argparse
import re
import sys

from .validation import SceneError

EXIT_BAD_INPUT = 2
EXIT_NO_GL = 3


def parse_size(text: str) -> tuple[int, int]:
    """``'800x600'`` → (800, 600); RunError on anything else or on absurd sizes."""
    from .run import RunError, check_size

    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not m:
        raise RunError(f"--size must look like WIDTHxHEIGHT (e.g. 800x600), got {text!r}")
    return check_size((int(m.group(1)), int(m.group(2))))


class Progress:
    """A progress bar on a terminal (tqdm), silent when stderr is not a terminal; its
    :meth:`step` is a pipeline ``on_step(what, total)`` callback."""

    def __init__(self, enabled: bool | None = None, unit: str = "pass"):
        from tqdm import tqdm

        enabled = sys.stderr.isatty() if enabled is None else enabled
        self.bar = tqdm(total=None, disable=not enabled, unit=unit, leave=False, file=sys.stderr)

    def step(self, what: str, total: int) -> None:
        """Advance by one; ``what`` becomes the bar's description, ``total`` its length."""
        if self.bar.total != total:
            self.bar.total = total
        self.bar.set_description(what, refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        """Remove the bar."""
        self.bar.close()


def technique_listing() -> str:
    """Registered techniques with their parameters and defaults, for ``shadowlab techniques``."""
    from .techniques import REGISTRY
    from .techniques.base import format_value

    lines = []
    for name, cls in REGISTRY.items():
        lines.append(f"{name}: {cls.summary}")
        for key, p in cls.PARAMS.items():
            extra = f" (one of {', '.join(map(str, p.choices))})" if p.choices else ""
            lines.append(f"    {key}={format_value(p.default)}  {p.doc}{extra}")
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="shadowlab", description="Compare real-time shadow techniques "
                                "against a ray-traced ground truth.")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("scenes", help="list the shipped scenes")
    sub.add_parser("techniques", help="list registered techniques and their parameters")
    c = sub.add_parser("compare", help="run the ground truth and techniques on a scene")
    c.add_argument("scene", help="a shipped scene's name (see 'shadowlab scenes') or a path to a scene file")
    c.add_argument("--technique", "-t", action="append", default=None, metavar="SPEC",
                   help="name or name:key=value,... (repeatable; default: shadow_map)")
    c.add_argument("--size", default="800x600", help="image size WIDTHxHEIGHT (default 800x600)")
    c.add_argument("--out", default=None, help="run directory (default results/<scene>_<date-time>)")
    c.add_argument("--repeat", type=int, default=5, help="timed runs per configuration (default 5)")
    c.add_argument("--warmup", type=int, default=1, help="untimed warm-up runs (default 1)")
    c.add_argument("--pass-timing", action="store_true",
                   help="also time each named pass (pass_<name>_ms columns, a stacked bar chart in the report; "
                        "measured in runs of their own)")
    return p


def _cmd_scenes() -> int:
    from .scene import builtin_scenes, scene_summary

    for name, path in builtin_scenes().items():
        try:
            desc = scene_summary(path)
        except SceneError as exc:  # a broken shipped scene should still be listed
            desc = f"INVALID: {exc}"
        print(f"{name:28s} {desc}")
    return 0


def _cmd_compare(args) -> int:
    from . import run as runmod
    from .gl import GLContextError
    from .metrics import format_table

    size = parse_size(args.size)
    bar = Progress()
    try:
        out = runmod.compare(args.scene, args.technique or ["shadow_map"], size=size, out=args.out,
                             repeat=args.repeat, warmup=args.warmup, on_step=bar.step,
                             pass_timing=args.pass_timing)
    except GLContextError as exc:
        print(f"shadowlab: {exc}", file=sys.stderr)
        return EXIT_NO_GL
    finally:
        bar.close()
    import pandas as pd

    table = format_table(pd.read_csv(out / "metrics.csv"), "summary")
    with pd.option_context("display.width", 200, "display.max_colwidth", 60):
        print(table.to_string(index=False))
    print(f"run directory: {out.resolve()}")
    print(f"report: {(out / 'report.html').resolve()}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the process exit status."""
    from .run import RunError
    from .techniques import TechniqueError

    args = _parser().parse_args(argv)
    try:
        if args.command == "scenes":
            return _cmd_scenes()
        if args.command == "techniques":
            print(technique_listing())
            return 0
        return _cmd_compare(args)
    except (SceneError, TechniqueError, RunError) as exc:
        print(f"shadowlab: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    raise SystemExit(main())
