"""Epsilon sweep for exact shadow polygons: where too small and too large a tolerance break them.

Three families of nearly degenerate configurations, each with a closed-form or independently
computed answer (central / parallel projection, then GEOS's polygon intersection (shapely) — no code
shared with shadowlab.geometry.clipping.scalar), each rotated by a random rotation so that nothing lies
exactly on an axis:

- **coplanar, above**: a sheet lying δ above the receiver (RT3's 0.1 mm sheet, in general): it
  casts its shadow. An ε larger than δ calls the receiver coplanar with the caster, and a
  coplanar receiver is not behind it: the shadow goes missing;
- **grazing light**: a directional light φ above the receiver's plane over a small caster: a long
  shadow. An ε larger than sin φ declares the light to lie in the receiver's plane: no shadow;
- **touching**: a card standing on the receiver (its bottom edge on the plane up to rounding),
  point light: an ε below the coordinates' rounding lets the clipper split at rounding noise.

Reports, for ε from 1e-18 to 1e-1 (world units, receiver of size ~4), the relative error of the
shadow fragment's area and the number of sliver pieces (area < 1e-12 of the receiver) in the
tiling — what too small an ε produces. Writes results/sp_epsilon_sweep.csv and .png.

    python experiments/sp_epsilon_sweep.py [--trials 20]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from shadowlab.output import provenance
from shadowlab.geometry.clipping import scalar as pc

# The independent oracle (shapely/GEOS, no code shared with the clipper) lives with the tests.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from convex_reference import overlap_area  # noqa: E402

EPSILONS = 10.0 ** np.arange(-18, 0)
RECEIVER = np.array([[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2.0]])


def case(family, param):
    """(receiver, caster, light_h, expected area) in unrotated coordinates."""
    if family == "coplanar, above":  # a sheet lying δ above the receiver: it casts its shadow
        caster = np.array([[-0.5, param, -0.4], [0.6, param, -0.4], [0.6, param, 0.5], [-0.5, param, 0.5]])
        L = np.array([0.3, 3.0, 0.2])
        s = L[1] / (L[1] - caster[:, 1])
        proj = (L + (caster - L) * s[:, None])[:, [0, 2]]
        return RECEIVER, caster, np.append(L, 1.0), overlap_area(RECEIVER[:, [0, 2]], proj)
    if family == "grazing light":  # a card 2·tan φ tall: a shadow 2 long on the receiver
        d = np.array([np.cos(param), -np.sin(param), 0.0])
        h = 2.0 * np.tan(param)
        caster = np.array([[-1.9, 0.0, -0.2], [-1.9, 0.0, 0.2], [-1.9, h, 0.2], [-1.9, h, -0.2]])
        shadow = np.array([[-1.9, -0.2], [-1.9, 0.2], [0.1, 0.2], [0.1, -0.2]])
        return RECEIVER, caster, np.append(-d, 0.0), overlap_area(RECEIVER[:, [0, 2]], shadow)
    # touching: a vertical card on the floor, point light
    card = np.array([[-0.5, 0.0, 0.3], [0.5, 0.0, 0.1], [0.5, 1.0, 0.1], [-0.5, 1.0, 0.3]])
    L = np.array([-0.4, 3.0, -1.5])
    s = L[1] / (L[1] - card[:, 1])
    proj = (L + (card - L) * s[:, None])[:, [0, 2]]
    hull = ConvexHull(proj)
    return RECEIVER, card, np.append(L, 1.0), overlap_area(RECEIVER[:, [0, 2]], proj[hull.vertices])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20, help="random rotations per configuration")
    ap.add_argument("--out", default="results/sp_epsilon_sweep")
    args = ap.parse_args()
    rng = np.random.default_rng(7)
    families = {"coplanar, above": [1e-12, 1e-9, 1e-6, 1e-3], "grazing light": [1e-10, 1e-7, 1e-4],
                "touching": [0.0]}
    rows = []
    for family, params in families.items():
        for param in params:
            receiver, caster, light, expected = case(family, param)
            for trial in range(args.trials):
                rot = Rotation.random(random_state=rng).as_matrix()
                shift = rng.uniform(-3, 3, 3)
                r, c = receiver @ rot.T + shift, caster @ rot.T + shift
                lh = np.append(light[:3] @ rot.T + (shift if light[3] else 0.0), light[3])
                for eps in EPSILONS:
                    frag, pieces = pc.shadow_fragment(r, c, lh, eps)
                    got = pc.area(frag)
                    err = abs(got - expected) / max(expected, pc.area(caster))
                    parts = ([frag] if len(frag) else []) + pieces
                    slivers = sum(pc.area(p) < 1e-12 * pc.area(r) for p in parts)
                    rows.append({"family": family, "param": param, "trial": trial, "epsilon": eps,
                                 "expected_area": expected, "area": got, "relative_error": err,
                                 "sliver_pieces": slivers})
    df = pd.DataFrame(rows)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    provenance.write_record(out, {"trials": args.trials}, gl_info=False)
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        for col in ("relative_error", "sliver_pieces"):
            print(f"worst {col} over rotations:")
            print(df.groupby(["family", "param", "epsilon"])[col].max().unstack("epsilon")
                  .to_string(float_format=lambda x: f"{x:.0e}"))
    plot(df, out.with_suffix(".png"))
    print(f"wrote {out.with_suffix('.csv')} and {out.with_suffix('.png')}")


def plot(df, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fams = list(dict.fromkeys(df["family"]))
    fig, axes = plt.subplots(1, len(fams), figsize=(15, 4.6), dpi=100, sharey=True)
    for ax, fam in zip(axes, fams):
        d = df[df["family"] == fam]
        for param, g in d.groupby("param"):
            worst = g.groupby("epsilon")["relative_error"].max()
            label = {"coplanar, above": f"δ = {param:g}", "grazing light": f"φ = {param:g} rad"}.get(fam, "card on floor")
            line, = ax.loglog(worst.index, np.maximum(worst.to_numpy(), 1e-17), "o-", label=label)
            slivers = g.groupby("epsilon")["sliver_pieces"].max()
            bad = slivers[slivers > 0]
            if len(bad):
                ax.loglog(bad.index, np.full(len(bad), 3e-17), "x", color=line.get_color(), ms=8,
                          label=f"{label}: sliver pieces")
        ax.axvline(1e-9 * 8, color="k", ls=":", lw=1, label="default ε (1e-9 × scene size)")
        ax.set_title(fam, fontsize=10)
        ax.set_xlabel("ε (world units)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("worst relative error of the shadow's area\n(over random rotations; 1 = all wrong;\n"
                       "x at the bottom: sliver pieces produced)")
    fig.suptitle("Exact shadow polygons: tolerance ε too small (rounding slivers) and too large (missing shadows)",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


if __name__ == "__main__":
    main()
