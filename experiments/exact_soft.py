"""Exact soft shadows (exact_soft, issue 28): its error against the sampled truth and its cost
against the truth's, and its own cost curve in pixels and in triangles.

Three parts, each a block of rows of results/exact_soft.csv (column ``part``):

- ``scenes``: the seven soft scenes (shadowlab/scenes/soft_*.toml, first frame) at 320x240. exact_soft and the
  sampled truth at 1024 and 4096 samples per pixel (``raytrace:samples=N``) on the same frame;
  per scene the mean |V_exact − V_truth| over the evaluated pixels and over the truth's penumbra
  (0.02 < G < 0.98), its max, and the mean signed difference, against the truth's stated
  per-pixel bound ``truth_stderr_max`` = 0.5/√N. Times: median of ``--repeat`` renders after
  one warm-up (exact_soft), one render each for the truths (seconds long).
- ``pixels``: exact_soft on soft_large_close and soft_overlap at 160x120 … 640x480.
- ``triangles``: a procedural scene (``torus_scene``): one torus of M × m sections over a floor
  under the 2 x 2 rect light of soft_overlap, 2·M·m triangles from 128 to 20,000, at 320x240;
  exact_soft and the truth at 1024 samples.

Timings are wall clock on whatever machine runs this, under its load (the 1-minute load
average is recorded beside each row: the lab's machine is shared). Writes
results/exact_soft.csv, .png (four panels: error per scene with the bound; time per scene;
time against pixels; time against triangles) and the provenance record .json.

    python experiments/exact_soft.py [--out results/exact_soft] [--repeat 3] [--quick]
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.output import provenance
from shadowlab.gpu.frame import Frame
from shadowlab.measurement.pipeline import measure
from shadowlab.scene import load_scene, parse_scene
from shadowlab.techniques import from_spec
from shadowlab.evaluation.metrics import PENUMBRA_HIGH, PENUMBRA_LOW

SCENES = ["soft_banding", "soft_below_plane", "soft_contact_hardening", "soft_large_close", "soft_moving_caster",
          "soft_overlap", "soft_two_heights"]
TRUTH_SAMPLES = [1024, 4096]
SIZES = [(160, 120), (320, 240), (640, 480)]
PIXEL_SCENES = ["soft_large_close", "soft_overlap"]
TORI = [(16, 4), (32, 8), (64, 16), (100, 50), (100, 100)]  # (major, minor) sections: 2·M·m triangles


def torus_scene(major: int, minor: int):
    """A torus of ``major`` × ``minor`` sections (2·major·minor triangles; radii 1 and 0.3, tilted
    60°, 0.8 above a 10 x 10 floor, as shadowlab/suites/scaling) under soft_overlap's 2 x 2 rect
    light 4 above the floor."""
    return parse_scene({
        "name": f"exact_soft_torus_{2 * major * minor}",
        "camera": {"eye": [3.0, 3.0, 4.0], "target": [0.0, 0.5, 0.0], "fov_y": 50.0},
        "lights": [{"type": "area", "shape": "rect", "position": [0.0, 4.0, 0.0], "u": [2.0, 0.0, 0.0],
                    "v": [0.0, 0.0, 2.0]}],
        "objects": [{"name": "floor", "mesh": "plane", "size": [10.0, 10.0]},
                    {"name": "torus", "mesh": "torus", "major_radius": 1.0, "minor_radius": 0.3,
                     "major_sections": major, "minor_sections": minor, "translate": [0.0, 0.8, 0.0],
                     "rotate": [60.0, 0.0, 0.0]}],
    }, "<exact_soft_torus>")


def load() -> float:
    """The 1-minute load average."""
    return os.getloadavg()[0]


def timed(spec: str, frame: Frame, repeat: int, warmup: int):
    """One configuration measured on light 0: (Measurement, its row's common columns)."""
    m = measure(from_spec(spec), frame, 0, repeat=repeat, warmup=warmup, count=False)
    return m, {"technique": spec, "time_ms": m.timing.median_ms, "time_ms_iqr": m.timing.iqr_ms,
               "repeats": len(m.timing.samples_ms), "setup_ms": m.setup_ms, "load_1min": load(), **{
                   k: m.stats[k] for k in ("candidates_mean", "candidates_max", "triangles") if k in m.stats}}


def differences(exact: np.ndarray, truth: np.ndarray, evaluated: np.ndarray) -> dict:
    """Mean |V − G| over the evaluated pixels and over the truth's penumbra, max, mean signed."""
    d = (exact - truth)[evaluated].astype(np.float64)
    g = truth[evaluated]
    pen = (g > PENUMBRA_LOW) & (g < PENUMBRA_HIGH)
    return {"mean_abs_diff": float(np.abs(d).mean()), "max_abs_diff": float(np.abs(d).max()),
            "mean_signed_diff": float(d.mean()), "penumbra_mean_abs_diff": float(np.abs(d[pen]).mean()),
            "penumbra_pixels": int(pen.sum()), "evaluated_pixels": int(evaluated.sum())}


def run(repeat: int, quick: bool) -> pd.DataFrame:
    """Every row of the three parts."""
    rows = []
    w, h = (160, 120) if quick else (320, 240)
    for name in SCENES:
        frame = Frame(load_scene(name), w, h)
        try:
            evaluated = frame.evaluated(0)
            ex, row = timed("exact_soft", frame, repeat, 1)
            truths = {}
            for n in TRUTH_SAMPLES:
                t, trow = timed(f"raytrace:samples={n}", frame, 1, 0)
                truths[n] = t.visibility
                rows.append({"part": "scenes", "scene": name, "width": w, "height": h, "samples": n,
                             "truth_stderr_max": 0.5 / np.sqrt(n), **trow})
            for n in TRUTH_SAMPLES:
                rows.append({"part": "scenes", "scene": name, "width": w, "height": h, "against_samples": n,
                             "truth_stderr_max": 0.5 / np.sqrt(n), **row,
                             **differences(ex.visibility, truths[n], evaluated)})
            print(name, {k: rows[-1][k] for k in ("time_ms", "mean_abs_diff", "penumbra_mean_abs_diff")}, flush=True)
        finally:
            frame.release()
    for name in PIXEL_SCENES:
        for sw, sh in SIZES[:2] if quick else SIZES:
            frame = Frame(load_scene(name), sw, sh)
            try:
                _, row = timed("exact_soft", frame, repeat, 1)
                rows.append({"part": "pixels", "scene": name, "width": sw, "height": sh,
                             "evaluated_pixels": int(frame.evaluated(0).sum()), **row})
            finally:
                frame.release()
    for major, minor in TORI[:3] if quick else TORI:
        scene = torus_scene(major, minor)
        frame = Frame(scene, w, h)
        try:
            evaluated = frame.evaluated(0)
            ex, row = timed("exact_soft", frame, repeat, 1)
            rows.append({"part": "triangles", "scene": scene.name, "width": w, "height": h,
                         "evaluated_pixels": int(evaluated.sum()), **row})
            t, trow = timed("raytrace:samples=1024", frame, 1, 0)
            rows.append({"part": "triangles", "scene": scene.name, "width": w, "height": h, "samples": 1024,
                         "triangles": row["triangles"], **trow})
            rows[-2].update(differences(ex.visibility, t.visibility, evaluated))
            print(scene.name, row["time_ms"], trow["time_ms"], flush=True)
        finally:
            frame.release()
    return pd.DataFrame(rows)


def plot(df: pd.DataFrame, path: Path) -> None:
    """Four panels: error per scene against the bound, time per scene (exact vs truths), time
    against pixels, time against triangles."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 4, figsize=(20, 4.6))
    sc = df[df.part == "scenes"]
    ex = sc[sc.technique == "exact_soft"]
    names = list(dict.fromkeys(ex.scene))
    x = np.arange(len(names))
    for k, n in enumerate(TRUTH_SAMPLES):
        e = ex[ex.against_samples == n].set_index("scene").loc[names]
        ax[0].bar(x + (k - 0.5) * 0.2, e.mean_abs_diff, 0.2, label=f"all evaluated, vs {n} spp")
        ax[0].bar(x + (k + 1.5) * 0.2, e.penumbra_mean_abs_diff, 0.2, label=f"penumbra, vs {n} spp")
        ax[0].axhline(0.5 / np.sqrt(n), ls=":", color=f"C{k}", label=f"0.5/√{n} (truth's per-pixel bound)")
    ax[0].set_xticks(x, [s.replace("soft_", "") for s in names], rotation=20)
    ax[0].set_yscale("log")
    ax[0].set_title("mean |V_exact − V_truth|")
    ax[0].legend(fontsize=7)
    t = sc.pivot_table(index="scene", columns="technique", values="time_ms", aggfunc="first").loc[names]
    for k, col in enumerate(t.columns):
        ax[1].bar(x + (k - 1) * 0.27, t[col] / 1e3, 0.27, label=col)
    ax[1].set_xticks(x, [s.replace("soft_", "") for s in names], rotation=20)
    ax[1].set_yscale("log")
    ax[1].set_ylabel("s per frame")
    ax[1].set_title(f"time, {ex.width.iloc[0]}x{ex.height.iloc[0]}")
    ax[1].legend(fontsize=7)
    px = df[df.part == "pixels"]
    for name, g in px.groupby("scene"):
        ax[2].loglog(g.evaluated_pixels, g.time_ms, "o-", label=name)
    ax[2].set_xlabel("evaluated pixels")
    ax[2].set_ylabel("ms")
    ax[2].set_title("exact_soft: time against pixels")
    ax[2].legend(fontsize=7)
    tr = df[df.part == "triangles"]
    for spec, g in tr.groupby("technique"):
        ax[3].loglog(g.triangles, g.time_ms, "o-", label=spec)
    ax[3].set_xlabel("caster triangles (torus over a floor)")
    ax[3].set_ylabel("ms")
    ax[3].set_title("time against triangles")
    ax[3].legend(fontsize=7)
    fig.suptitle(f"exact_soft (load average {df.load_1min.min():.1f}-{df.load_1min.max():.1f}: shared 2-core machine)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="results/exact_soft")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="160x120, fewer sizes and tori")
    args = ap.parse_args()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    df = run(args.repeat, args.quick)
    df.to_csv(out.with_suffix(".csv"), index=False)
    plot(df, out.with_suffix(".png"))
    provenance.write_record(out.with_suffix(".csv"), {
        "timing": f"wall clock, median of {args.repeat} renders after 1 warm-up (exact_soft), one render (truths)",
        "load_average_1min": [float(df.load_1min.min()), float(df.load_1min.max())],
        "elapsed_s": time.perf_counter() - t0, "quick": args.quick}, gl_info=False)
    print(f"wrote {out.with_suffix('.csv')}, .png, .json")


if __name__ == "__main__":
    main()
