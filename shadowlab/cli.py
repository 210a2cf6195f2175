"""The ``shadowlab`` command: list scenes, techniques and suites, run comparisons and studies,
pick the cheapest configuration within an error budget, check a study against a baseline.

Bad input (scene, technique spec, size, ...) exits with status 2 and one line naming the
culprit, before any GL work; a missing GL driver exits with status 3.
"""
from __future__ import annotations

import argparse
import re
import sys

from .util.sizes import ANIMATE_SIZE, COMPARE_SIZE, VIEW_SIZE, size_text
from .util.validation import SceneError

EXIT_BAD_INPUT = 2
EXIT_NO_GL = 3


def parse_size(text: str) -> tuple[int, int]:
    """``'800x600'`` → (800, 600); RunError on anything else or on absurd sizes."""
    from .util.validation import RunError, check_size

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


class StudyProgress:
    """The study's progress bar over all its tasks, with an ETA (tqdm; silent when stderr is not
    a terminal)."""

    def __init__(self, enabled: bool | None = None):
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.bar = None

    def start(self, total: int) -> None:
        """Open the bar for ``total`` tasks."""
        from tqdm import tqdm

        self.bar = tqdm(total=total, disable=not self.enabled, unit="task", file=sys.stderr, dynamic_ncols=True)

    def step(self, what: str) -> None:
        """One task finished (``what`` names it)."""
        if self.bar is not None:
            self.bar.set_description(what[:48], refresh=False)
            self.bar.update(1)

    def close(self) -> None:
        """Remove the bar."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _with_progress(unit: str, work):
    """Run ``work(on_step)`` under a :class:`Progress` bar of ``unit``s (the single-run commands:
    compare, animate, tune): its result, or None after printing why when no GL context could be
    made (the caller exits with :data:`EXIT_NO_GL`)."""
    from .gpu.gl import GLContextError

    bar = Progress(unit=unit)
    try:
        return work(bar.step)
    except GLContextError as exc:
        print(f"shadowlab: {exc}", file=sys.stderr)
        return None
    finally:
        bar.close()


def technique_listing(name: str | None = None) -> str:
    """Registered techniques with their parameters and defaults, for ``shadowlab techniques``;
    with ``name``, only that technique's block (TechniqueError, with a hint, if there is none)."""
    from .techniques import REGISTRY, technique_class
    from .techniques.base import format_value

    lines = []
    for cls in [technique_class(name)] if name is not None else REGISTRY.values():
        lines.append(f"{cls.name}: {cls.summary}")
        sampled = "; area lights as the average of light_samples point lights" if cls.LIGHT_SAMPLED else ""
        lines.append(f"    lights: {', '.join(sorted(cls.LIGHTS))}{sampled}")
        for key, p in cls.PARAMS.items():
            extra = f" (one of {', '.join(map(str, p.choices))})" if p.choices else ""
            lines.append(f"    {key}={format_value(p.default)}  {p.doc}{extra}")
    return "\n".join(lines)


def version_text() -> str:
    """``shadowlab <version>``, followed by the code's revision (``git describe``,
    :func:`shadowlab.output.provenance.revision`) when run from a git checkout."""
    from . import __version__
    from .output.provenance import revision

    rev = revision()
    return f"shadowlab {__version__}" + ("" if rev.startswith("shadowlab ") else f" ({rev})")


class _VersionAction(argparse.Action):
    """``--version``: print :func:`version_text` (asked for only then: it may run git) and exit."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_text())
        parser.exit()


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="shadowlab", description="Compare real-time shadow techniques "
                                "against a ray-traced ground truth.")
    p.add_argument("--version", action=_VersionAction, help="print the version (and git revision) and exit")
    sub = p.add_subparsers(dest="command", required=True)
    sub.add_parser("scenes", help="list the shipped scenes: what each tests, its objects and lights")
    te = sub.add_parser("techniques", help="list registered techniques and their parameters")
    te.add_argument("name", nargs="?", default=None, help="only this technique")
    c = sub.add_parser("compare", help="run the ground truth and techniques on a scene")
    c.add_argument("scene", help="a shipped scene's name (see 'shadowlab scenes') or a path to a scene file")
    c.add_argument("--technique", "-t", action="append", default=None, metavar="SPEC",
                   help="name or name:key=value,... (repeatable; default: shadow_map)")
    c.add_argument("--size", default=size_text(COMPARE_SIZE),
                   help=f"image size WIDTHxHEIGHT (default {size_text(COMPARE_SIZE)})")
    c.add_argument("--out", default=None, help="run directory (default results/<scene>_<date-time>)")
    c.add_argument("--repeat", type=int, default=5, help="timed runs per configuration (default 5)")
    c.add_argument("--warmup", type=int, default=1, help="untimed warm-up runs (default 1)")
    c.add_argument("--pass-timing", action="store_true",
                   help="also time each named pass (pass_<name>_ms columns, a stacked bar chart in the report; "
                        "measured in runs of their own)")
    vw = sub.add_parser("view", help="fly through a scene in a window: a technique's shaded image, the truth, the "
                        "error map, the texel footprint, the visibility (needs a display: xvfb-run without one)",
                        epilog=_view_keys_text(), formatter_class=argparse.RawDescriptionHelpFormatter)
    vw.add_argument("scene", help="a shipped scene's name or a path to a scene file")
    vw.add_argument("--technique", "-t", action="append", default=None, metavar="SPEC",
                    help="a configuration to show, name or name:key=value,... (repeatable; Tab and 1-9 switch; "
                         "default: shadow_map, shadow_volume and a few others that render for the scene's lights)")
    vw.add_argument("--size", default=size_text(VIEW_SIZE),
                    help=f"window and image size WIDTHxHEIGHT (default {size_text(VIEW_SIZE)})")
    vw.add_argument("--view", default="shaded", choices=("shaded", "truth", "error", "footprint", "visibility"),
                    help="the view shown first (default shaded)")
    vw.add_argument("--screenshot", default=None, metavar="PNG",
                    help="draw the first frame (the truth computed first), save it as PNG and exit")
    vw.add_argument("--script", default=None, metavar="FILE",
                    help="drive the viewer from a TOML script of [[step]]s (keys, mouse drags, screenshots, saved "
                         "views, frame times, quit; docs/your-scenes.md#the-viewer)")
    vw.add_argument("--out", default=".", metavar="DIR",
                    help="where screenshots and saved views go (default: the current directory)")
    vw.add_argument("--hud", action=argparse.BooleanOptionalAction, default=True,
                    help="draw the HUD: configuration, view, times, error (default on; key h toggles)")
    st = sub.add_parser("study", help="run a suite of scenes x techniques and draw the comparison")
    st.add_argument("suite", help="a shipped suite's name (see 'shadowlab suites') or a path to a suite file")
    st.add_argument("--out", default=None, help="study directory (default results/study-<suite name>)")
    st.add_argument("--workers", type=int, default=None,
                    help="local worker processes for the accuracy phase (default: one per core)")
    st.add_argument("--dask", default=None, metavar="ADDRESS",
                    help="run the tasks on the Dask scheduler at ADDRESS (e.g. tcp://host:8786) instead")
    st.add_argument("--force", action="store_true", help="ignore the cache: redo every run")
    sub.add_parser("suites", help="list the shipped suites")
    an = sub.add_parser("animate", help="run the ground truth and techniques on every frame of an animated scene "
                        "(per-frame and temporal metrics, flicker heat maps, error strips)")
    an.add_argument("scene", help="a shipped scene's name or a path to a scene file (with an [animation] table, "
                    "or give --frames for still frames)")
    an.add_argument("--technique", "-t", action="append", default=None, metavar="SPEC",
                    help="name or name:key=value,... (repeatable; default: shadow_map)")
    an.add_argument("--frames", type=int, default=None, help="frame count (default: the scene's animation.frames)")
    an.add_argument("--size", default=size_text(ANIMATE_SIZE),
                    help=f"image size WIDTHxHEIGHT (default {size_text(ANIMATE_SIZE)})")
    an.add_argument("--out", default=None, help="run directory (default results/<scene>_animate_<date-time>)")
    an.add_argument("--repeat", type=int, default=1, help="timed runs per configuration and frame (default 1)")
    an.add_argument("--warmup", type=int, default=0, help="untimed warm-up runs per frame (default 0)")
    tu = sub.add_parser("tune", help="find a configuration's best settings on a scene against the truth "
                        "(the shadow-map bias exactly from one render; anything else by a search over renders)")
    tu.add_argument("scene", help="a shipped scene's name or a path to a scene file")
    tu.add_argument("--technique", "-t", required=True, metavar="SPEC", help="the configuration to tune: name or "
                    "name:key=value,... (the other parameters stay as given)")
    tu.add_argument("--param", action="append", default=None, metavar="NAME[=RANGE]",
                    help="a parameter to tune (repeatable): NAME (its declared range), NAME=LO:HI, NAME=LO:HI:log "
                         "or NAME=a,b,c (default: bias, where the technique has one)")
    tu.add_argument("--objective", default="error_rate", help="the metric column to minimise (default error_rate)")
    tu.add_argument("--time-budget", type=float, default=None, metavar="MS",
                    help="only candidates at most this many ms per frame (median) count")
    tu.add_argument("--budget", type=int, default=24, help="renders the search may spend (default 24; the exact "
                    "bias route renders once)")
    tu.add_argument("--light", type=int, default=0, help="the scene light to tune for (default 0)")
    tu.add_argument("--size", default=size_text(COMPARE_SIZE),
                    help=f"image size WIDTHxHEIGHT (default {size_text(COMPARE_SIZE)}, as compare)")
    tu.add_argument("--out", default=None, help="run directory (default results/<scene>_tune_<technique>)")
    tu.add_argument("--cache", default=None, metavar="DIR", help="a study's cache directory (e.g. "
                    "results/study-quick/cache) to reuse its renders and keep this search's")
    tu.add_argument("--repeat", type=int, default=3, help="timed runs per rendered candidate (default 3)")
    tu.add_argument("--warmup", type=int, default=1, help="untimed warm-up runs (default 1)")
    co = sub.add_parser("cost", help="fit a device's cost model from a study's work counters and times, or "
                        "predict a study's times on a modelled device")
    cosub = co.add_subparsers(dest="cost_command", required=True)
    cf = cosub.add_parser("fit", help="fit time ≈ Σ c_k·work_k (non-negative) from a study's rows")
    cf.add_argument("study_dir", help="a study directory (or a results CSV) with work_ and time columns")
    cf.add_argument("--out", default=None, help="model file (default STUDY_DIR/cost_model.json)")
    cf.add_argument("--target", default="time_ms_median",
                    help="the time column to fit (default time_ms_median; gpu_time_ms_median on a GPU)")
    cf.add_argument("--counters", default=None, metavar="A,B,...",
                    help="the counters to fit (default: the exact ones and the declared taps and bytes)")
    cf.add_argument("--per-pass", action="store_true", help="fit pass_<name>_ms against each pass's counters "
                    "(the study needs pass_timing = true)")
    cf.add_argument("--device", default=None, help="the device's name (default: the study's)")
    cp = cosub.add_parser("predict", help="predicted time of every row of a study on a model's device")
    cp.add_argument("study_dir", help="a study directory (or a results CSV) with work_ columns")
    cp.add_argument("model", help="a model file written by 'cost fit'")
    pk = sub.add_parser("pick", help="the cheapest configuration within an error budget, per scene family and "
                        "scene, from a study's results")
    pk.add_argument("study_dir", help="a study directory (or its results.csv)")
    pk.add_argument("--budget", action="append", default=None, metavar="METRIC=VALUE",
                    help="an error budget, repeatable: edge=1%% (hard scenes: wrong pixels per pixel of the truth's "
                         "shadow boundary), mae=0.005 (soft scenes: mean |V - G|), radiance=2%% (many-light "
                         "scenes: the shaded image's mean relative luminance error) or error=0.1%% (share of all "
                         "pixels); default: edge 10 %%, 1 %%, 0.1 %%, mae 0.02, 0.005, radiance 5 %%, 2 %%, 1 %%")
    pk.add_argument("--scene", default=None, help="only this scene or scene family")
    pk.add_argument("--motion", choices=("still", "moving"), default=None,
                    help="only a still or a moving light (default both; with --model still)")
    pk.add_argument("--model", default=None, help="a cost model file ('shadowlab cost fit'): rank by its predicted "
                    "times on its device, labelled as a prediction")
    pk.add_argument("--csv", default=None, metavar="FILE", help="also write the table as CSV")
    ch = sub.add_parser("check", help="compare a study's artefact metrics with a baseline; exit 1 on regressions")
    ch.add_argument("study_dir", help="a study directory (holds results.csv)")
    ch.add_argument("baseline", help="baseline CSV (scene, light, config, label, held metrics)")
    ch.add_argument("--update", action="store_true", help="write the study's metrics as the new baseline instead")
    return p


def _view_keys_text() -> str:
    """The viewer's keys, for ``shadowlab view --help`` (from the key map the viewer uses)."""
    from .viewer.state import ACTION_HELP, KEYMAP

    lines = ["keys:", "  W A S D, Q E    fly forward, left, back, right, down, up (shift: faster)",
             "  mouse drag      look around"]
    shown = set()
    for key, action in KEYMAP.items():
        name = "config_n" if action.startswith("config_") else action
        if name in shown:
            continue
        shown.add(name)
        lines.append(f"  {'1-9' if name == 'config_n' else key:<15s} {ACTION_HELP[name]}")
    return "\n".join(lines)


def _cmd_view(args) -> int:
    from pathlib import Path

    from .gpu.gl import GLContextError
    from .viewer.app import NoDisplay, view

    try:
        return view(args.scene, args.technique, parse_size(args.size), view_name=args.view,
                    screenshot=args.screenshot, script=args.script, out=Path(args.out), hud=args.hud)
    except NoDisplay as exc:
        print(f"shadowlab: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except GLContextError as exc:
        print(f"shadowlab: {exc}", file=sys.stderr)
        return EXIT_NO_GL


def _cmd_suites() -> int:
    from .study.suite import SuiteError, builtin_suites, load_suite

    suites = builtin_suites()
    width = max(map(len, suites), default=0) + 2
    for name, path in suites.items():
        try:
            s = load_suite(path)
            desc = (f"{len(s.scenes)} scenes, {s.runs()} runs, {s.size[0]}x{s.size[1]}, repeat {s.repeat}"
                    f"{' — ' + s.description.splitlines()[0] if s.description else ''}")
        except SuiteError as exc:
            desc = f"INVALID: {exc}"
        print(f"{name:{width}s}{desc}")
    return 0


def _cmd_study(args) -> int:
    from .gpu.gl import GLContextError
    from .study.runner import run_study

    bar = StudyProgress()
    try:
        outcome = run_study(args.suite, out=args.out, workers=args.workers, dask=args.dask, force=args.force,
                            progress=bar)
    except GLContextError as exc:
        print(f"shadowlab: {exc}", file=sys.stderr)
        return EXIT_NO_GL
    except KeyboardInterrupt:
        bar.close()
        print("shadowlab: interrupted; finished runs are cached — run the same command again to resume",
              file=sys.stderr)
        return 130
    except RuntimeError as exc:  # Dask unreachable or not installed
        print(f"shadowlab: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    finally:
        bar.close()
    out = outcome.out
    print(f"{outcome.ran} tasks run, {outcome.cached} from the cache, in {outcome.elapsed_s:.1f} s")
    if outcome.failed:
        print(f"{len(outcome.failed)} run(s) FAILED (recorded in results.csv with their errors):")
        for line in outcome.failed:
            print(f"  {line}")
    print(f"results: {(out / 'results.csv').resolve()}")
    print(f"summary: {(out / 'summary.md').resolve()}")
    print(f"report:  {(out / 'study.html').resolve()}")
    return 1 if outcome.failed else 0


def _cmd_check(args) -> int:
    from pathlib import Path

    from .study import check as chk

    try:
        results = chk.read_results(Path(args.study_dir))
        if args.update:
            bad = results[results["status"] != "ok"]
            if len(bad):
                print(f"shadowlab: error: {len(bad)} row(s) of {args.study_dir} did not finish (status "
                      f"{', '.join(sorted(set(bad['status'])))}), e.g. {bad['scene'].iloc[0]} / {bad['label'].iloc[0]}: "
                      f"{bad['error'].iloc[0]}; a baseline must hold every configuration — fix and rerun the study",
                      file=sys.stderr)
                return EXIT_BAD_INPUT
            base = chk.baseline_from(results)
            Path(args.baseline).parent.mkdir(parents=True, exist_ok=True)
            base.to_csv(args.baseline, index=False)
            print(f"wrote {len(base)} baseline rows to {args.baseline}")
            return 0
        result = chk.check(results, chk.read_baseline(Path(args.baseline)))
    except chk.CheckError as exc:
        print(f"shadowlab: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if result.new:
        print(f"{len(result.new)} configuration(s) not in the baseline (not checked): " + "; ".join(result.new[:8])
              + (" ..." if len(result.new) > 8 else ""))
    if result.respecified:
        print(f"{len(result.respecified)} configuration(s) now resolve to other parameters than in the baseline "
              f"(a changed default?): " + "; ".join(result.respecified[:4]) + (" ..." if len(result.respecified) > 4 else ""))
    if not result.improvements.empty:
        print(f"{len(result.improvements)} metric(s) better than the baseline beyond tolerance "
              f"(update it with --update to hold the new level):")
        print(chk.format_findings(result.improvements))
    if not result.ok:
        print(f"REGRESSIONS: {len(result.regressions)} metric(s) worse than {args.baseline} beyond tolerance:")
        print(chk.format_findings(result.regressions))
        return 1
    print(f"ok: {result.checked} metrics within tolerance of {args.baseline}")
    return 0


def _cmd_pick(args) -> int:
    from pathlib import Path

    from .commands.pick import pick_command, pick_text

    table, what = pick_command(args.study_dir, args.budget, args.model, args.scene, args.motion)
    print(pick_text(table, what))
    if args.csv:
        from .util.files import write_text_atomic

        write_text_atomic(Path(args.csv), table.to_csv(index=False))
        print(f"table: {Path(args.csv).resolve()}")
    return 0


def _cmd_scenes() -> int:
    from .scene import builtin_scenes, scene_purpose, scene_summary

    for name, path in builtin_scenes().items():
        try:
            desc = scene_summary(path)
        except SceneError as exc:  # a broken shipped scene should still be listed
            desc = f"INVALID: {exc}"
        print(f"{name:28s} {scene_purpose(path) or '(no opening comment)'}")
        print(f"{'':28s}   {desc}")
    return 0


def _cmd_compare(args) -> int:
    from .commands import compare as runmod
    from .evaluation.metrics import format_table

    size = parse_size(args.size)
    out = _with_progress("pass", lambda step: runmod.compare(
        args.scene, args.technique or ["shadow_map"], size=size, out=args.out, repeat=args.repeat,
        warmup=args.warmup, on_step=step, pass_timing=args.pass_timing))
    if out is None:
        return EXIT_NO_GL
    import pandas as pd

    table = format_table(pd.read_csv(out / "metrics.csv"), "summary")
    with pd.option_context("display.width", 200, "display.max_colwidth", 60):
        print(table.to_string(index=False))
    _print_notes(out / "run.json")
    print(f"run directory: {out.resolve()}")
    print(f"report: {(out / 'report.html').resolve()}")
    return 0


def _print_notes(record_path) -> None:
    """Print a run's notes (run.json's ``notes``: fallbacks, ignored parameters, degenerate
    configurations) under the summary table, so that a result that draws no shadow is said on the
    terminal too, not only on the page."""
    import json

    try:
        notes = json.loads(record_path.read_text()).get("notes") or []
    except (OSError, ValueError):
        return
    if notes:
        print("notes:")
        for n in notes:
            print(f"- {n}")


def _cmd_animate(args) -> int:
    import pandas as pd

    from .commands.animate import animate

    size = parse_size(args.size)
    out = _with_progress("render", lambda step: animate(
        args.scene, args.technique or ["shadow_map"], frames=args.frames, size=size, out=args.out,
        repeat=args.repeat, warmup=args.warmup, on_step=step))
    if out is None:
        return EXIT_NO_GL
    from .commands.animate import TEMPORAL_ERROR_DECIMALS
    from .util.format import fmt_fixed, fmt_ms, fmt_pct

    summary = pd.read_csv(out / "summary.csv")
    shown = pd.DataFrame({"configuration": summary["short_label"], "light": summary["light"],
                          "frames": summary["frames"]})
    for col in ("error_rate_mean", "flip_rate_mean", "flip_rate_p95", "flip_rate_max"):  # rates: percent, as compare
        shown[col] = summary[col].map(fmt_pct)
    for col in ("temporal_error_mean", "temporal_error_max"):  # a visibility difference, not a rate
        shown[col] = summary[col].map(lambda v: fmt_fixed(v, TEMPORAL_ERROR_DECIMALS))
    shown["time_ms"] = summary["time_ms_median"].map(fmt_ms)
    with pd.option_context("display.width", 200, "display.max_colwidth", 60):
        print(shown.to_string(index=False))
    print(f"run directory: {out.resolve()}")
    print(f"report: {(out / 'report.html').resolve()}")
    return 0


def _cmd_cost(args) -> int:
    from .commands import cost as cost_cmd
    from .util.format import fmt_whole_pct
    from .analysis.cost import PREDICTED_LABEL, summary_line

    if args.cost_command == "fit":
        counters = [c.strip() for c in args.counters.split(",") if c.strip()] if args.counters else None
        model, path = cost_cmd.fit_command(args.study_dir, args.out, args.target, counters, args.per_pass, args.device)
        print(summary_line(model))
        print(model.table().to_string(index=False, float_format=lambda v: f"{v:.4g}"))
        print(f"model: {path.resolve()}")
        print(f"plot:  {path.with_name('cost_fit.png').resolve()}")
        return 0
    table, path, model = cost_cmd.predict_command(args.study_dir, args.model)
    print(f"{PREDICTED_LABEL} {model.target} on {model.device} (a prediction: the model's leave-one-scene-out "
          f"median error is {fmt_whole_pct(model.cv_median_rel_error)})")
    if table["measured_ms"].notna().any():
        print(f"the study ran on that device: median relative error of the predictions "
              f"{fmt_whole_pct(float(table['rel_error'].median()))}")
    key = next(c for c in ("short_label", "label", "scene") if c in table.columns)
    here = "measured_here_ms" if "measured_here_ms" in table.columns else "measured_ms"
    summary = table.groupby(key, sort=False)[[here, f"{PREDICTED_LABEL}_ms"]].median()
    print(summary.to_string(float_format=lambda v: f"{v:.3g}"))
    missing = sorted({u for v in table.get("unmodelled", []) for u in str(v).split(", ") if u and v == v})
    if missing:
        print(f"no prediction where a row does work the model has no cost for: {', '.join(missing)}")
    print(f"predictions: {path.resolve()}")
    return 0


def _cmd_tune(args) -> int:
    import json

    from .commands.tune import tune

    size = parse_size(args.size)
    out = _with_progress("step", lambda step: tune(
        args.scene, args.technique, args.param or [], objective=args.objective, size=size, out=args.out,
        light=args.light, budget=args.budget, time_budget_ms=args.time_budget, repeat=args.repeat,
        warmup=args.warmup, cache_dir=args.cache, on_step=step))
    if out is None:
        return EXIT_NO_GL
    best = json.loads((out / "best.json").read_text())
    from .util.format import fmt_num

    print(f"best:    {best['spec']}")
    print(f"         {best['objective']} = {fmt_num(best['value'], 6)} (as given: {fmt_num(best['default']['value'], 6)}, "
          + (f"regret {fmt_num(best['regret_of_default'], 3)}" if best["regret_of_default"] is not None else
             f"{fmt_num(best['default']['time_ms'], 3)} ms: over the time budget")
          + f"); route: {best['route']}")
    if best["route"] == "exact":
        print(f"         per-pixel oracle {fmt_num(best['oracle'], 3)}; render equals prediction: {best['verified']}")
    print(f"run directory: {out.resolve()}")
    print(f"page: {(out / 'tune.html').resolve()}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the process exit status."""
    from .commands.compare import RunError
    from .study.suite import SuiteError
    from .techniques import TechniqueError
    from .tuning.space import TuneError

    args = _parser().parse_args(argv)
    try:
        if args.command == "scenes":
            return _cmd_scenes()
        if args.command == "techniques":
            print(technique_listing(args.name))
            return 0
        if args.command == "suites":
            return _cmd_suites()
        if args.command == "study":
            return _cmd_study(args)
        if args.command == "check":
            return _cmd_check(args)
        if args.command == "animate":
            return _cmd_animate(args)
        if args.command == "tune":
            return _cmd_tune(args)
        if args.command == "cost":
            return _cmd_cost(args)
        if args.command == "pick":
            return _cmd_pick(args)
        if args.command == "view":
            return _cmd_view(args)
        return _cmd_compare(args)
    except (SceneError, TechniqueError, RunError, SuiteError, TuneError) as exc:
        print(f"shadowlab: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    raise SystemExit(main())
