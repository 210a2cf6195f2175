"""How each shadow-volume technique's cost grows with triangles and with pixels (issue 37).

The torus of ``sv_scaling.py`` (one point light over a floor) refined from ``--triangles`` caster
triangles at 640x480, then the ``--pixel-torus`` torus at each of ``--pixel-sizes``; every volume
technique at its defaults: ``shadow_volume``, ``cc_volume``, ``hierarchical_volume``,
``per_triangle_volume``, ``partitioned_volume``. One row per (technique, triangles, pixels): the
median render time (wall clock around ``ctx.finish()``: one warm-up and ``--repeat`` timed renders,
or the first render alone where that took over 2 s), the setup time, ``pixel_ops`` and
``volume_fragments``. The log-log slope of time (and of ``pixel_ops``) against triangles and
against pixels is fitted per technique over the points (least squares on logs): the exponent of
the technique's growth on this machine and scene, not a law to extrapolate from (the full
scaling laws, every family, come from the ``scaling`` suite: ``experiments/scaling_laws.py``).

    python experiments/volume_scaling.py [--out results/volume_scaling] [--triangles 10000,40000]
        [--pixel-sizes 320x240,640x480] [--pixel-torus 40000] [--repeat 3]

Writes ``scaling.csv``, ``scaling.md`` and the provenance record ``scaling.json`` under ``--out``.
The committed figures (``results/volumes/``, docs/shadow-volumes.md) are ``--triangles
10000,40000,160000 --pixel-sizes 320x240,640x480,1280x960 --out results/volumes``; the default is
small, for ``make experiments``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.gpu.frame import Frame
from shadowlab.measurement.pipeline import measure
from shadowlab.output import provenance
from shadowlab.techniques import from_spec

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sv_scaling import torus_scene  # noqa: E402  (the torus of the shadow-volume scaling experiment)

VOLUMES = ("shadow_volume", "cc_volume", "hierarchical_volume", "per_triangle_volume", "partitioned_volume")
#: A configuration slower than this per render (ms) is timed by its first render alone.
SLOW_MS = 2000.0


def parse_size(text: str) -> tuple[int, int]:
    """``"640x480"`` → (640, 480)."""
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def point(spec: str, triangles: int, size, repeat: int) -> dict:
    """One technique on the torus of ``triangles`` triangles at ``size``."""
    frame = Frame(torus_scene(triangles), *size)
    m = measure(from_spec(spec), frame, 0, repeat=1, warmup=0, count=False)
    timed = 1
    if m.timing.median_ms < SLOW_MS:
        m = measure(from_spec(spec), frame, 0, repeat=repeat, warmup=1, count=False)
        timed = repeat
    return {"technique": spec, "triangles": int(sum(len(o.faces) for o in frame.scene.objects)),
            "pixels": size[0] * size[1], "time_ms": m.timing.median_ms, "timed_renders": timed,
            "setup_ms": m.setup_ms, "pixel_ops": m.stats.get("pixel_ops", np.nan),
            "volume_fragments": m.stats.get("volume_fragments", np.nan)}


def slopes(df: pd.DataFrame, axis: str, held: str, held_at: int) -> pd.DataFrame:
    """Per technique, the log-log slope of time and of pixel_ops against ``axis`` with ``held`` fixed."""
    rows = []
    for tech, g in df[df[held] == held_at].groupby("technique", sort=False):
        g = g.sort_values(axis)
        x = np.log(g[axis].to_numpy(float))
        row = {"technique": tech, "axis": axis, "points": len(g)}
        for col in ("time_ms", "pixel_ops"):
            y = g[col].to_numpy(float)
            ok = np.isfinite(y) & (y > 0)
            row[f"{col}_slope"] = float(np.polyfit(x[ok], np.log(y[ok]), 1)[0]) if ok.sum() >= 2 else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def main() -> None:
    """Measure the two sweeps, fit the slopes, write the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results/volume_scaling"))
    ap.add_argument("--triangles", default="10000,40000")
    ap.add_argument("--pixel-sizes", default="320x240,640x480")
    ap.add_argument("--pixel-torus", type=int, default=40000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--techniques", default=",".join(VOLUMES))
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.time()
    base = (640, 480)
    tris = [int(t) for t in args.triangles.split(",")]
    sizes = [parse_size(s) for s in args.pixel_sizes.split(",")]
    jobs = [(t, base) for t in tris] + [(args.pixel_torus, s) for s in sizes if s != base or args.pixel_torus not in tris]
    rows = []
    for spec in args.techniques.split(","):
        for t, size in jobs:
            rows.append(point(spec, t, size, args.repeat))
            r = rows[-1]
            print(f"{spec:22s} {r['triangles']:>8,} tris {size[0]}x{size[1]}: {r['time_ms']:9.1f} ms  "
                  f"pixel_ops {r['pixel_ops']:>14,.0f}", flush=True)
    df = pd.DataFrame(rows)
    df.to_csv(args.out / "scaling.csv", index=False)
    # the pixel sweep's scene, counted as the rows count triangles (floor included)
    held_tris = int(df[df.pixels != base[0] * base[1]].triangles.iloc[0])
    fits = pd.concat([slopes(df, "triangles", "pixels", base[0] * base[1]),
                      slopes(df, "pixels", "triangles", held_tris)])
    lines = ["# Shadow-volume family: growth with triangles and pixels (experiments/volume_scaling.py)", "",
             "Log-log slopes of the median render time and of `pixel_ops` (per-pixel operations), per "
             f"technique: against triangles at {base[0]}x{base[1]}, against pixels on the "
             f"{held_tris:,}-triangle scene. 1 = linear.", "",
             "| technique | axis | points | time slope | pixel_ops slope |", "|---|---|---:|---:|---:|"]
    for _, r in fits.iterrows():
        lines.append(f"| {r.technique} | {r.axis} | {r.points} | {r.time_ms_slope:.2f} | {r.pixel_ops_slope:.2f} |")
    lines += ["", "| technique | triangles | pixels | time ms | timed renders | setup ms | pixel_ops |",
              "|---|---:|---:|---:|---:|---:|---:|"]
    for _, r in df.iterrows():
        lines.append(f"| {r.technique} | {r.triangles:,} | {r.pixels:,} | {r.time_ms:.4g} | {r.timed_renders} | "
                     f"{r.setup_ms:.4g} | {r.pixel_ops:,.0f} |")
    (args.out / "scaling.md").write_text("\n".join(lines) + "\n")
    provenance.write_record(args.out / "scaling.csv", {"triangles": tris, "pixel_sizes": [list(s) for s in sizes],
                                                       "repeat": args.repeat, "seconds": round(time.time() - start, 1)})
    print("\n".join(lines[:6 + len(fits)]))
    print(f"wrote {args.out}/scaling.csv, scaling.md ({time.time() - start:.0f} s)")


if __name__ == "__main__":
    main()
