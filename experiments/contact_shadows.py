"""Contact shadows (issue 39): what Bend Studio's screen-space march recovers and what it costs.

On the contact hard cases (sm_contact, sm_lamp_contact, cs_thin_fins) with the shadow map at its
default bias and at a bias that detaches thin casters (0.02), measures without and with
``contact=true`` and over two sweeps of the march:

1. the surface thickness (``contact_thickness`` 0.001-0.05): contact pixels recovered, false
   shadows introduced (thickness halos), the error where contact and map shadows meet (seam);
2. its length (``contact_samples`` 8-120 pixels): the contact gap it closes and the pass's time;
3. the depth-edge test off (``contact_bilinear=1``): grazing surfaces no longer shadow themselves.

Also tabulates Bend's dispatch list (:func:`shadowlab.techniques.maps.contact.bend_dispatch_count`)
over light positions on and off a 1920x1080 screen against its comment ("one or two when the light
is off-screen, 4 to 6 when on").

Writes results/contact/contact_sweep.csv, results/contact/dispatches.csv and
results/contact/contact_sweep.png. About ten minutes on a 2-core machine at 320x240.

    python experiments/contact_shadows.py [--out results/contact] [--size 320x240]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from shadowlab.measurement.pipeline import measure_configs
from shadowlab.techniques.maps.contact import bend_dispatch_count
from tqdm import tqdm

SCENES = ["sm_contact", "sm_lamp_contact", "cs_thin_fins"]
BIASES = [0.002, 0.02]
THICKNESS = [0.001, 0.002, 0.005, 0.01, 0.02, 0.05]
SAMPLES = [8, 16, 30, 60, 120]
COLUMNS = ["scene", "light", "short_label", "param_bias", "param_contact", "param_contact_thickness",
           "param_contact_samples", "param_contact_bilinear", "error_rate", "false_shadow_pixels", "false_lit_pixels", "contact_gap_px",
           "contact_recovered_pixels", "contact_false_pixels", "contact_gap_closed_px", "seam_pixels",
           "seam_error_rate", "time_ms_median", "pass_contact_ms", "contact_dispatches", "bend_dispatches",
           "contact_samples"]


def specs() -> list[str]:
    """Every configuration: per bias the map alone, then both sweeps with contact on."""
    out = []
    for bias in BIASES:
        base = f"shadow_map:bias={bias}"
        out.append(base)
        out += [f"{base},contact=true,contact_thickness={t}" for t in THICKNESS]
        out += [f"{base},contact=true,contact_samples={n}" for n in SAMPLES if n != 60]
        out.append(f"{base},contact=true,contact_bilinear=1.0")  # the depth-edge test off
    return out


def measure(size: tuple[int, int]) -> pd.DataFrame:
    """The rows of every configuration on every light of the contact scenes."""
    from shadowlab.scene import load_scene

    rows = []
    jobs = [(s, li) for s in SCENES for li in range(len(load_scene(s).lights))]
    for scene, light in tqdm(jobs, desc="contact scenes"):
        df = measure_configs(scene, specs(), size=size, repeat=3, warmup=1, light_index=light, pass_timing=True)
        rows.append(df[~df["reference"].astype(bool)])
    df = pd.concat(rows, ignore_index=True)
    return df[[c for c in COLUMNS if c in df.columns]]


def dispatches() -> pd.DataFrame:
    """Bend's dispatch count over a grid of light points around a 1920x1080 screen: share of the
    points on and off the screen with each count."""
    rows = []
    for x in np.linspace(-4000, 6000, 101):
        for y in np.linspace(-3000, 4000, 71):
            on = 0 <= x < 1920 and 0 <= y < 1080
            rows.append({"where": "on-screen" if on else "off-screen", "dispatches": bend_dispatch_count((x, y), (1920, 1080))})
    d = pd.DataFrame(rows)
    table = d.groupby(["where", "dispatches"]).size().rename("points").reset_index()
    table["share"] = table["points"] / table.groupby("where")["points"].transform("sum")
    return table


def plot(df: pd.DataFrame, path: Path) -> None:
    """Thickness sweep (recovered vs false pixels, seam error) and length sweep (gap closed, time)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    on = df[df["param_contact"].astype(str).str.lower() == "true"]
    default_len = (on["param_contact_samples"] == 60) & (on["param_contact_bilinear"] == 0.02)
    for (scene, light, bias), d in on[default_len].groupby(["scene", "light", "param_bias"]):
        d = d.sort_values("param_contact_thickness")
        label = f"{scene} L{light} bias {bias:g}"
        axes[0].plot(d["param_contact_thickness"], d["contact_false_pixels"], "o-", label=label)
        axes[1].plot(d["param_contact_thickness"], d["contact_recovered_pixels"], "s-", label=label)
    default_thick = (on["param_contact_thickness"] == 0.005) & (on["param_contact_bilinear"] == 0.02)
    for (scene, light, bias), d in on[default_thick].groupby(["scene", "light", "param_bias"]):
        d = d.sort_values("param_contact_samples")
        axes[2].plot(d["param_contact_samples"], d["contact_gap_closed_px"], "o-", label=f"{scene} L{light} bias {bias:g}")
    for ax, title, xl, yl in ((axes[0], "false shadows introduced (halos)", "contact_thickness", "pixels"),
                              (axes[1], "truly shadowed pixels recovered", "contact_thickness", "pixels"),
                              (axes[2], "contact gap closed", "contact_samples (max length, px)", "px")):
        ax.set_xscale("log")
        ax.set_title(title)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("Contact shadows (Bend-style march) on top of shadow_map", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    """Measure, tabulate and draw into --out."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="results/contact")
    ap.add_argument("--size", default="320x240")
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.lower().split("x"))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = dispatches()
    table.to_csv(out / "dispatches.csv", index=False)
    print(table.to_string(index=False))
    df = measure(size)
    df.to_csv(out / "contact_sweep.csv", index=False)
    plot(df, out / "contact_sweep.png")
    print(f"wrote {out / 'contact_sweep.csv'}, {out / 'dispatches.csv'}, {out / 'contact_sweep.png'}")


if __name__ == "__main__":
    main()
