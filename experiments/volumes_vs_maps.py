"""Where the shadow-volume family stands against the shadow-map family in a study (issue 37).

Reads a study directory (``shadowlab study hard_shadows --out DIR``, ``shadowlab study city``) and
prints, per scene, each family's best technique as the study's verdict table chooses it (the
lowest judged error among its sound configurations, ties by time: ``verdict_table``): its
error and the median time of its fastest configuration with that error, the stencil volume's
own best error (the family before issue 37), the best *sampled* map
(every map technique but the exact irregular z-buffer) likewise, and which family has the lower
error. Families are the
techniques' folders (``techniques/volumes``, ``techniques/maps``).

    python experiments/volumes_vs_maps.py STUDY_DIR [STUDY_DIR ...] [--out FILE.md]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from shadowlab.analysis.verdicts import verdict_table
from shadowlab.study.check import read_results
from shadowlab.study.tiles import read_tiles
from shadowlab.techniques import REGISTRY

FAMILIES = ("volumes", "maps")
#: The irregular z-buffer sits in the map family (an alias-free shadow map) but is exact; the
#: table also shows the best *sampled* map (every other map technique), the usual rival.
EXACT_MAPS = ("irregular_zbuffer",)
#: The volume family before issue 37 (the stencil volume alone), shown beside the family today.
PLAIN_VOLUMES = ("shadow_volume",)


def standings(results: pd.DataFrame, tiles: dict | None = None) -> pd.DataFrame:
    """Per scene: the best verdict row of each family (technique, error, time) and the winners
    (``tiles``: the study's tiles.npz, for the verdicts' own significance tests)."""
    verdicts = verdict_table(results, tiles=tiles)
    verdicts["family"] = verdicts["technique"].map(lambda t: getattr(REGISTRY.get(t), "FAMILY", ""))
    sampled = verdicts[(verdicts.family == "maps") & ~verdicts.technique.isin(EXACT_MAPS)].assign(family="sampled")
    plain = verdicts[verdicts.technique.isin(PLAIN_VOLUMES)].assign(family="plain")
    verdicts = pd.concat([verdicts, sampled, plain])
    rows = []
    for scene, g in verdicts.groupby("scene", sort=False):
        row = {"scene": scene, "metric": g["metric"].iloc[0]}
        for fam in FAMILIES + ("sampled", "plain"):
            f = g[(g.family == fam) & g.error.notna()].sort_values(["error", "time_ms"], kind="stable")
            if f.empty:
                row.update({f"{fam}_best": "", f"{fam}_error": float("nan"), f"{fam}_ms": float("nan")})
                continue
            best = f.iloc[0]
            fastest_exact = f[f.error <= f.error.min()].sort_values("time_ms").iloc[0]
            row.update({f"{fam}_best": best["short_label"], f"{fam}_error": best["error"],
                        f"{fam}_ms": fastest_exact["time_ms"]})
        v, m = row.get("volumes_error"), row.get("maps_error")
        row["lower_error"] = "" if pd.isna(v) or pd.isna(m) else ("tie" if v == m else
                                                                 ("volumes" if v < m else "maps"))
        rows.append(row)
    return pd.DataFrame(rows)


def markdown(table: pd.DataFrame) -> str:
    """The standings as a markdown table (errors in the scene's judged metric)."""
    lines = ["| scene | metric | volumes: best | error | ms | stencil volume alone: error | maps: best | error | ms "
             "| sampled maps: best | error | ms | lower error |",
             "|---|---|---|---:|---:|---:|---|---:|---:|---|---:|---:|---|"]
    for _, r in table.iterrows():
        def num(x, pct):
            return "" if pd.isna(x) else (f"{100 * x:.3g} %" if pct else f"{x:.4g}")
        pct = r.metric == "error_rate"
        lines.append(f"| `{r.scene}` | {r.metric} | {r.volumes_best} | {num(r.volumes_error, pct)} | "
                     f"{num(r.volumes_ms, False)} | {num(r.plain_error, pct)} | {r.maps_best} | "
                     f"{num(r.maps_error, pct)} | "
                     f"{num(r.maps_ms, False)} | {r.sampled_best} | {num(r.sampled_error, pct)} | "
                     f"{num(r.sampled_ms, False)} | {r.lower_error} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    """Print (and optionally write) the standings of each study directory given."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("studies", type=Path, nargs="+")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    parts = []
    for study in args.studies:
        table = standings(read_results(study), read_tiles(study))
        parts.append(f"## {study.name}\n\n" + markdown(table))
        wins = table.lower_error.value_counts().to_dict()
        exact = {fam: int((table[f"{fam}_error"] == 0).sum()) for fam in ("volumes", "plain", "maps", "sampled")}
        parts[-1] += (f"\nLower error: {wins}. Scenes where the best is exact (error 0) of {len(table)}: the volume "
                      f"family {exact['volumes']}, the stencil volume alone {exact['plain']}, the map family "
                      f"{exact['maps']}, sampled maps {exact['sampled']}.\n")
    text = "\n".join(parts)
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
