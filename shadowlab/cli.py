"""The ``shadowlab`` command: list scenes and techniques, run comparisons.

Bad input (scene, technique spec, size, ...) exits with status 2 and one line naming the
culprit, before any GL work; a missing GL driver exits with status 3.
"""
from __future__ import annotations

import argparse
import sys

from .validation import SceneError

EXIT_BAD_INPUT = 2
EXIT_NO_GL = 3


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

    size = runmod.parse_size(args.size)
    try:
        out = runmod.compare(args.scene, args.technique or ["shadow_map"], size=size, out=args.out,
                             repeat=args.repeat, warmup=args.warmup)
    except GLContextError as exc:
        print(f"shadowlab: {exc}", file=sys.stderr)
        return EXIT_NO_GL
    import pandas as pd

    df = pd.read_csv(out / "metrics.csv")
    cols = ["short_label", "light", "error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px", "time_ms_median"]
    with pd.option_context("display.width", 200, "display.max_colwidth", 60):
        print(df[cols].to_string(index=False, float_format=lambda x: f"{x:.4g}"))
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
            from .run import technique_listing

            print(technique_listing())
            return 0
        return _cmd_compare(args)
    except (SceneError, TechniqueError, RunError) as exc:
        print(f"shadowlab: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    raise SystemExit(main())
