"""The fill the modern shadow-volume family saves, beside the papers' claims (issue 37).

Every volume technique at its defaults — the plain stencil volume (``shadow_volume``), CC
volumes (``cc_volume``), hierarchical volumes (``hierarchical_volume``), per-triangle volumes
(``per_triangle_volume``) and partitioned volumes (``partitioned_volume``) — with the irregular
z-buffer and a 2048² shadow map for reference, on the fill and soup hard cases, the city scenes
and a few standard scenes, one row per (scene, hard light, technique):

- the error against the truth (wrong evaluated pixels and ``error_rate``) and the pixels whose
  visibility differs from the plain volume's (0 where a variant keeps its mask);
- the per-pixel work on one footing (``volume_fragments``: volume fragments that reach per-pixel
  stencil work; ``pixel_ops``: the per-pixel operations of the technique's per-pixel stage —
  stencil fragments, test-and-set operations or tree nodes visited) and the technique's own
  counters;
- the median render time (wall clock around ``ctx.finish()``; one warm-up and ``--repeat`` timed
  renders, or the first render alone where that took over 2 s: ``timed_renders``) and the
  untimed setup.

``fill.md`` tabulates the saving, plain ``volume_fragments`` / variant ``pixel_ops``, per scene with
the paper's claim beside it; ``fill.png`` draws the per-pixel work per scene on a log scale.

    python experiments/volume_fill.py [--out results/volume_fill] [--size 320x240] [--repeat 3]
        [--scenes sv_colonnade,sv_soup,...] [--techniques shadow_volume,cc_volume,...] [--tables-only]

Writes ``fill.csv``, ``fill.md``, ``fill.png`` and the provenance record ``fill.json`` under ``--out``.
The committed figures (``results/volumes/``, docs/shadow-volumes.md) are
``--size 800x600 --out results/volumes``; the default is small, for ``make experiments``.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.gpu.frame import Frame
from shadowlab.measurement.pipeline import Evaluator, measure
from shadowlab.output import provenance
from shadowlab.output.pictures import PLOT_DPI
from shadowlab.scene import load_scene
from shadowlab.scene.area_lights import AreaLight
from shadowlab.techniques import from_spec

PLAIN = "shadow_volume"
VOLUMES = (PLAIN, "cc_volume", "hierarchical_volume", "per_triangle_volume", "partitioned_volume")
REFERENCES = ("irregular_zbuffer", "shadow_map")
SCENES = ("sv_colonnade", "sv_soup", "sv_many_casters", "city_wires", "box_on_plane", "sv_camera_in_shadow",
          "spot_scene", "sun_scene")
#: Each variant's published saving over the plain volume, as the paper states it.
CLAIMS = {
    "cc_volume": "up to 7× less fill (Lloyd et al. 2004, 96K-polygon scene)",
    "hierarchical_volume": "up to 11.5× fewer pixels processed (Aila & Akenine-Möller 2004)",
    "per_triangle_volume": "an order of magnitude fewer test-and-set operations than z-pass "
                           "(Sintorn et al. 2011, multi-sampled HD)",
    "partitioned_volume": "no fill claim (Gerhards et al. 2015 compare time and memory)",
}
#: A configuration slower than this per render (ms) is timed by its first render alone.
SLOW_MS = 2000.0
#: Columns kept from each measurement's stats when present.
STAT_KEYS = ("volume_fragments", "pixel_ops", "stencil_updates", "fill_per_pixel", "casters_culled",
             "casters_clamped", "casters_kept", "tiles_inside", "tiles_outside", "tiles_boundary", "tile_tests",
             "tiles_accepted", "tiles_rejected", "tiles_descended", "sample_tests", "tree_nodes",
             "nodes_visited", "nodes_visited_mean", "nodes_visited_max", "triangles_culled", "memory_bytes")


def parse_size(text: str) -> tuple[int, int]:
    """``"800x600"`` → (800, 600)."""
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def measure_scene(name: str, size, techniques, repeat: int) -> list[dict]:
    """Rows of every technique on every hard light of one scene."""
    scene = load_scene(name)
    frame = Frame(scene, *size)
    evaluator = Evaluator(frame, truth=from_spec("raytrace"))
    rows = []
    for li, light in enumerate(scene.lights):
        if isinstance(light, AreaLight):
            continue
        truth = evaluator.truth(li).visibility
        evaluated = frame.evaluated(li)
        plain = None
        for spec in techniques:
            # one render first; a configuration under SLOW_MS per render is measured again with
            # a warm-up and ``repeat`` timed renders, a slower one keeps its single render
            m = measure(from_spec(spec), frame, li, repeat=1, warmup=0, count=False)
            timed = 1
            if m.timing.median_ms < SLOW_MS:
                m = measure(from_spec(spec), frame, li, repeat=repeat, warmup=1, count=False)
                timed = repeat
            vis = m.visibility[evaluated] < 0.5
            if spec == PLAIN:
                plain = vis
            row = {"scene": name, "light": li, "technique": spec, "pixels": int(evaluated.sum()),
                   "wrong": int(np.sum(vis != (truth[evaluated] < 0.5))),
                   "differ_from_plain": int(np.sum(vis != plain)) if plain is not None else np.nan,
                   "time_ms_median": m.timing.median_ms, "timed_renders": timed, "setup_ms": m.setup_ms}
            row["error_rate"] = row["wrong"] / max(1, row["pixels"])
            row.update({k: m.stats[k] for k in STAT_KEYS if k in m.stats})
            rows.append(row)
            print(f"{name} light {li} {spec:22s} wrong {row['wrong']:6d}  differ {row['differ_from_plain']!s:>6}  "
                  f"pixel_ops {row.get('pixel_ops', float('nan')):>14,.0f}  {m.timing.median_ms:8.1f} ms", flush=True)
    return rows


def saving_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per (scene, light, variant): plain volume_fragments / variant pixel_ops, and the errors."""
    out = []
    for (scene, light), g in df.groupby(["scene", "light"], sort=False):
        plain = g[g.technique == PLAIN]
        if plain.empty:
            continue
        base = float(plain.volume_fragments.iloc[0])
        for _, r in g.iterrows():
            if r.technique not in VOLUMES:
                continue
            ops = r.get("pixel_ops", np.nan)
            out.append({"scene": scene, "light": light, "technique": r.technique, "pixel_ops": ops,
                        # unknown ops (NaN): an unknown saving, not an infinite one
                        "saving": np.nan if pd.isna(ops) else base / ops if ops > 0 else np.inf,
                        "wrong": r.wrong, "differ_from_plain": r.differ_from_plain,
                        "time_ms_median": r.time_ms_median})
    return pd.DataFrame(out)


def markdown(df: pd.DataFrame, saving: pd.DataFrame, size) -> str:
    """fill.md: the saving per scene beside the claims, then the full table."""
    lines = [f"# Shadow-volume fill, {size[0]}x{size[1]} (experiments/volume_fill.py)", "",
             "Saving = the plain volume's `volume_fragments` / the variant's `pixel_ops` (per-pixel "
             "operations: stencil fragments, test-and-set operations, tree nodes visited). `wrong`: "
             "evaluated pixels that differ from the truth; `differ`: from the plain volume. The plain "
             "volume's stencil updates (the fragments that change a count: z-pass's depth-test passes, "
             "z-fail's fails) are the figure Sintorn et al. compare test-and-set operations with.", ""]
    variants = [v for v in VOLUMES[1:] if v in set(saving.technique)]
    head = ("| scene | light | plain fragments | plain stencil updates | "
            + " | ".join(f"{v} saving (wrong/differ)" for v in variants) + " |")
    lines += [head, "|" + "---|" * (4 + len(variants))]
    for (scene, light), g in saving.groupby(["scene", "light"], sort=False):
        plain = g[g.technique == PLAIN]
        cells = []
        for v in variants:
            r = g[g.technique == v]
            cells.append("—" if r.empty else f"{r.saving.iloc[0]:.2g}× ({int(r.wrong.iloc[0])}/"
                                             f"{int(r.differ_from_plain.iloc[0])})")
        updates = df[(df.scene == scene) & (df.light == light) & (df.technique == PLAIN)].stencil_updates.iloc[0]
        lines.append(f"| `{scene}` | {light} | {plain.pixel_ops.iloc[0]:,.0f} | {updates:,.0f} | "
                     + " | ".join(cells) + " |")
    lines += ["", "Claims:", ""] + [f"- `{k}`: {v}" for k, v in CLAIMS.items()] + ["", "## All rows", ""]
    cols = ["scene", "light", "technique", "wrong", "differ_from_plain", "volume_fragments", "pixel_ops",
            "time_ms_median", "setup_ms"]
    shown = df[[c for c in cols if c in df]]
    lines.append("| " + " | ".join(shown.columns) + " |")
    lines.append("|" + "---|" * len(shown.columns))
    for _, r in shown.iterrows():
        lines.append("| " + " | ".join(_cell(v) for v in r) + " |")
    return "\n".join(lines) + "\n"


def _cell(value) -> str:
    """A table cell: integers with separators, other numbers to 4 significant digits."""
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    if float(value).is_integer():
        return f"{int(value):,}"
    return f"{value:.4g}"


def plot(df: pd.DataFrame, path: Path) -> None:
    """Per-pixel work per scene and technique, log scale."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = df[df.technique.isin(VOLUMES)]
    d = d.assign(case=d.scene + ":" + d.light.astype(str))
    table = d.pivot_table(index="case", columns="technique", values="pixel_ops", sort=False)
    table = table[[v for v in VOLUMES if v in table]]
    fig, ax = plt.subplots(figsize=(10, 5))
    table.plot.bar(ax=ax, logy=True, width=0.8, color=[from_spec(t).STYLE.color for t in table.columns])
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=len(table.columns), frameon=False)
    ax.set_ylabel("per-pixel operations per render")
    ax.set_xlabel("")
    ax.set_title("Shadow-volume family: per-pixel work (lower is less fill)")
    ax.tick_params(axis="x", rotation=20)
    fig.tight_layout()
    fig.savefig(path, dpi=PLOT_DPI)
    plt.close(fig)


def main() -> None:
    """Measure, then write the tables and the figure."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results/volume_fill"))
    ap.add_argument("--size", type=parse_size, default=(320, 240))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--techniques", default=",".join(VOLUMES + REFERENCES))
    ap.add_argument("--tables-only", action="store_true",
                    help="rewrite fill.md and fill.png from fill.csv (give the --size it was measured at)")
    args = ap.parse_args()
    if args.tables_only:
        df = pd.read_csv(args.out / "fill.csv")
        (args.out / "fill.md").write_text(markdown(df, saving_table(df), args.size))
        plot(df, args.out / "fill.png")
        return
    args.out.mkdir(parents=True, exist_ok=True)
    techniques = args.techniques.split(",")
    if PLAIN in techniques:  # the plain volume first: the others are compared with its mask
        techniques = [PLAIN] + [t for t in techniques if t != PLAIN]
    start = time.time()
    rows = []
    for name in args.scenes.split(","):
        rows += measure_scene(name, args.size, techniques, args.repeat)
    df = pd.DataFrame(rows)
    df.to_csv(args.out / "fill.csv", index=False)
    saving = saving_table(df)
    (args.out / "fill.md").write_text(markdown(df, saving, args.size))
    plot(df, args.out / "fill.png")
    provenance.write_record(args.out / "fill.csv", {"size": list(args.size), "repeat": args.repeat,
                                                    "scenes": args.scenes.split(","), "techniques": techniques,
                                                    "seconds": round(time.time() - start, 1)})
    print(f"wrote {args.out}/fill.csv, fill.md, fill.png ({time.time() - start:.0f} s)")


if __name__ == "__main__":
    main()
