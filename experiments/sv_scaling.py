"""Shadow-volume cost against triangle count: silhouette extraction (CPU and GPU) and the whole technique.

One torus (10k … 1M triangles) over a floor, a point light, 640x480. For each size:
- ``edge_table_ms``: building the edge table (once per mesh; kept with the mesh afterwards);
- ``cpu_silhouette_ms``: per light, face facing + edge multiplicities + silhouette list (numpy);
- ``cpu_geometry_ms``: the above plus building the volume's vertex arrays;
- ``gpu_silhouette_ms``: the geometry-shader pass alone (rasteriser discard: no fill);
- ``cpu_total_ms`` / ``gpu_total_ms``: the technique's whole timed render (z-fail);
- ``zpass_ms`` / ``zfail_ms`` / ``auto_ms``: the whole timed render (CPU silhouette) per counting
  mode, the modes interleaved (``--repeat`` rounds of 3 renders each) — ``auto`` picks z-pass or z-fail per caster (Everitt & Kilgard's near-plane test); the
  camera here is outside every volume, so auto should cost about what z-pass does (issue 11);
plus silhouette edges, volume triangles and fill per pixel (z-fail), and auto's z-fail casters. Timings: wall clock (with
``ctx.finish()`` around GL work), median of ``--repeat``. Writes CSV, plot and provenance (.json).

    python experiments/sv_scaling.py [--sizes 10000,100000] [--repeat 5]
    (the figures in the notes: --sizes 10000,30000,100000,300000,1000000)
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from OpenGL import GL

from shadowlab.gpu import gl, programs
from shadowlab.output import provenance
from shadowlab.gpu.frame import Frame
from shadowlab.geometry import adjacency as adj
from shadowlab.measurement.pipeline import measure as measure_technique
from shadowlab.scene import parse_scene
from shadowlab.techniques import from_spec
from shadowlab.techniques.volumes.shadow_volume import GS_STAGE_VOLUME
from shadowlab.gpu.timing import time_passes


#: Counting modes timed on their own (CPU silhouette), one column each.
MODES = ("zpass", "zfail", "auto")


def torus_scene(triangles: int):
    minor = max(8, int(round(np.sqrt(triangles / 4))))
    major = max(8, int(round(triangles / (2 * minor))))
    return parse_scene({
        "name": f"torus_{triangles}",
        "camera": {"eye": [3.0, 3.0, 4.0], "target": [0.0, 0.5, 0.0], "fov_y": 50.0},
        "lights": [{"type": "point", "position": [1.5, 4.0, 1.0]}],
        "objects": [{"mesh": "plane", "size": [10.0, 10.0], "name": "floor"},
                    {"mesh": "torus", "name": "torus", "major_radius": 1.0, "minor_radius": 0.3,
                     "major_sections": major, "minor_sections": minor, "translate": [0.0, 0.8, 0.0],
                     "rotate": [60.0, 0.0, 0.0]}]})


def gs_only_timer(frame, table, light, repeat):
    """Median ms of the silhouette geometry shader over the torus with the rasteriser off:
    the program of the GPU path, drawn through the public GL helpers."""
    ctx = frame.ctx
    prog = programs.program("shadow_volume_gs.glsl")
    programs.set_uniforms(prog, light.uniforms())
    prog["u_view"].write(programs.mat_bytes(frame.view))
    prog["u_proj"].write(programs.mat_bytes(frame.projection))
    programs.set_uniforms(prog, {"u_two_sided": False, "u_caps": True, "u_far_cap": not light.at_infinity,
                                 "u_stage": GS_STAGE_VOLUME})
    vbo = ctx.buffer(table.vertices.astype("f4").tobytes())
    ibo = ctx.buffer(table.adjacency_indices().tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "3f", "in_pos")], index_buffer=ibo, index_element_size=4)

    def gs_only():
        GL.glEnable(GL.GL_RASTERIZER_DISCARD)
        vao.render(ctx.TRIANGLES_ADJACENCY)
        GL.glDisable(GL.GL_RASTERIZER_DISCARD)

    ms = time_passes(gs_only, repeat=repeat, warmup=1).median_ms
    for obj in (vao, ibo, vbo):  # prog: programs.program's cache keeps it
        obj.release()
    return ms


def measure(n, repeat):
    scene = torus_scene(n)
    torus = scene.objects[1]
    edge_ms = time_passes(lambda: torus.edges, repeat=1, warmup=0, gpu=False).median_ms  # built once, then kept
    table, light = torus.edges, scene.lights[0]
    cpu_sil = time_passes(lambda: adj.silhouette_edges(table, adj.facing(table, light), False), repeat=repeat,
                          gpu=False).median_ms
    frame = Frame(scene, 640, 480)
    row = {"triangles": len(torus.faces), "edge_table_ms": edge_ms, "cpu_silhouette_ms": cpu_sil}
    for path in ("cpu", "gpu"):
        tech = from_spec(f"shadow_volume:mode=zfail,silhouette={path}")
        m = measure_technique(tech, frame, 0, repeat=repeat, warmup=1, release=False)
        row[f"{path}_total_ms"] = m.timing.median_ms
        if path == "cpu":
            row["cpu_geometry_ms"] = time_passes(tech.cpu_volume_geometry, repeat=repeat, gpu=False).median_ms
        row.update({k: m.stats[k] for k in ("silhouette_edges", "volume_triangles", "fill_per_pixel")})
        tech.release()
    row["gpu_silhouette_ms"] = gs_only_timer(frame, table, light, repeat)
    # The modes take turns, ``repeat`` rounds of 3 renders each, so that a busy spell on a shared
    # machine falls on all of them alike; the figure is the median over all renders.
    samples = {mode: [] for mode in MODES}
    for _ in range(repeat):
        for mode in MODES:
            m = measure_technique(from_spec(f"shadow_volume:mode={mode},silhouette=cpu"), frame, 0, repeat=3, warmup=1)
            samples[mode] += m.timing.samples_ms
            if mode == "auto":
                row["auto_zfail_casters"] = m.stats["zfail_casters"]
                row["auto_fill_per_pixel"] = m.stats["fill_per_pixel"]
    row.update({f"{mode}_ms": float(np.median(v)) for mode, v in samples.items()})
    frame.release()
    return row


def plot(df, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.8, 4.4), dpi=110)
    for col, label in (("cpu_silhouette_ms", "CPU silhouette (numpy)"), ("gpu_silhouette_ms", "GPU silhouette (geometry shader, no fill)"),
                       ("cpu_total_ms", "whole technique, CPU silhouette"), ("gpu_total_ms", "whole technique, GPU silhouette"),
                       ("edge_table_ms", "edge table build (once per mesh)"), ("zpass_ms", "z-pass (CPU silhouette)"),
                       ("auto_ms", "mode=auto (CPU silhouette)")):
        ax.loglog(df["triangles"], df[col], "o-", label=label)
    ax.set_xlabel("caster triangles")
    ax.set_ylabel("time, ms (median)")
    ax.set_title(f"Shadow volumes vs triangle count (z-fail unless named)\n{gl.renderer()}, 640x480")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10000,100000")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default="results/sv_scaling")
    args = ap.parse_args()
    rows = []
    for n in map(int, args.sizes.split(",")):
        rows.append(measure(n, args.repeat))
        print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out.with_suffix(".csv"), index=False)
    provenance.write_record(out, {"timing": f"wall clock around ctx.finish(), median of {args.repeat}"})
    plot(df, out.with_suffix(".png"))
    with pd.option_context("display.width", 250):
        print(df.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
    print(f"renderer: {gl.renderer()}; wrote {out.with_suffix('.csv')}, .png and .json")


if __name__ == "__main__":
    main()
