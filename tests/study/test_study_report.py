"""The study report (docs/contracts.md#study-directory): per-configuration pooling over lights, the Pareto front, the
Pareto figure, summary.md and study.html — on a synthetic results table (no GL)."""
from __future__ import annotations

import math
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from shadowlab.output.pictures import save_png
from shadowlab.output import pareto
from shadowlab.analysis import aggregate as agg
from shadowlab.study import report as sr

TRUTH = "raytrace:offset_scale=1e-06"
#: A label with characters HTML must escape.
ODD = 'planar:note=<b>&"x"'


def _row(scene, family, light, spec, *, evaluated=1000, error=0.0, fs=None, fl=None, lit=None, time=1.0, iqr=0.1,
         boundary=0.0, status="ok", err_msg=""):
    tech = spec.split(":")[0]
    lit = evaluated if lit is None else lit
    fs = 0 if fs is None else fs        # wrong pixel counts
    fl = round(error * evaluated) - fs if fl is None else fl
    shadowed = evaluated - lit
    row = {"scene": scene, "light": light, "technique": tech, "params": spec.partition(":")[2], "width": 64,
           "height": 48, "evaluated_pixels": evaluated, "error_rate": error,
           "false_shadow_rate": fs / lit if lit else 0.0, "false_lit_rate": fl / shadowed if shadowed else 0.0,
           "boundary_error_px": boundary, "time_ms_median": time, "time_ms_iqr": iqr, "label": spec,
           "short_label": "raytrace" if spec == TRUTH else spec, "reference": spec == TRUTH,
           "truth_lit_pixels": lit, "truth_shadowed_pixels": shadowed, "false_shadow_pixels": fs,
           "false_lit_pixels": fl, "scene_family": family, "status": status, "error": err_msg,
           "run_dir": f"runs/{scene}" if status == "ok" else "", "revision": "abc123", "renderer": "llvmpipe",
           "shaded_image": "", "error_image": "", "worst_crop_image": "", "worst_box": "", "worst_errors": math.nan}
    if status != "ok":
        for k in ("evaluated_pixels", "error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px",
                  "time_ms_median", "time_ms_iqr", "truth_lit_pixels", "truth_shadowed_pixels",
                  "false_shadow_pixels", "false_lit_pixels"):
            row[k] = math.nan
    return row


def _with_images(root: Path, row: dict, worst: int | None) -> dict:
    """Light-0 image columns, with tiny PNGs written under ``root``, and the configuration's entry
    in its run directory's run.json (images, as the run-directory writer lays them out)."""
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", row["short_label"])
    images = root / row["run_dir"] / "images"
    images.mkdir(parents=True, exist_ok=True)
    rgb = np.full((6, 8, 3), 0.5)
    entry = {"label": row["label"], "title": row["short_label"], "reference": bool(row["reference"])}
    for kind in ("shaded", "visibility") + (() if row["reference"] else ("error",)):
        save_png(images / f"{stem}_{kind}.png", rgb)
        entry[kind] = f"images/{stem}_{kind}.png"
    row["shaded_image"] = f"{row['run_dir']}/images/{stem}_shaded.png"
    if not row["reference"]:
        row["error_image"] = f"{row['run_dir']}/images/{stem}_error.png"
        entry["inset_wrong"] = [worst or 0]
    record_path = root / row["run_dir"] / "run.json"
    record = json.loads(record_path.read_text()) if record_path.is_file() else {
        "size": [8, 6], "images": [], "insets": [{"box": [1, 2, 5, 6], "wrong": 3}], "legends": {}}
    record["images"].append(entry)
    record_path.write_text(json.dumps(record))
    return row


def synthetic(root: Path | None = None) -> pd.DataFrame:
    """Three scenes (one with two lights), the truth on each, a zero-error configuration, one
    failed run, one configuration over the fail threshold; images under ``root`` if given."""
    rows = []

    def add(row, worst=None):
        if root is not None and row["light"] == 0 and row["status"] == "ok":
            row = _with_images(root, row, worst)
        rows.append(row)

    # box_on_plane (general), one light of 1000 evaluated pixels
    add(_row("box_on_plane", "general", 0, TRUTH, time=50.0, iqr=1.0))
    add(_row("box_on_plane", "general", 0, "shadow_map", error=0.02, fs=5, time=2.0, iqr=0.2, lit=800), worst=7)
    add(_row("box_on_plane", "general", 0, "shadow_volume", error=0.0, time=4.0, lit=800), worst=0)
    add(_row("box_on_plane", "general", 0, "planar", error=0.005, fs=1, time=1.0, lit=800), worst=3)
    # sv_two_lights (shadow volumes): light 0 has 1000 evaluated pixels, light 1 has 3000
    for li, ev, lit in ((0, 1000, 800), (1, 3000, 1000)):
        add(_row("sv_two_lights", "shadow volumes", li, TRUTH, evaluated=ev, lit=lit, time=30.0, iqr=2.0))
    add(_row("sv_two_lights", "shadow volumes", 0, "shadow_volume", evaluated=1000, lit=800, error=0.01, fs=4,
             time=3.0, iqr=0.1, boundary=1.0), worst=6)
    add(_row("sv_two_lights", "shadow volumes", 1, "shadow_volume", evaluated=3000, lit=1000, error=0.002, fs=2,
             time=5.0, iqr=0.3, boundary=3.0))
    add(_row("sv_two_lights", "shadow volumes", 0, "shadow_map", evaluated=1000, lit=800, error=0.03, time=1.5),
        worst=20)
    add(_row("sv_two_lights", "shadow volumes", 1, "shadow_map", evaluated=3000, lit=1000, error=0.01, time=1.5))
    for li in (0, 1):
        add(_row("sv_two_lights", "shadow volumes", li, "planar", status="failed",
                 err_msg="RuntimeError: no planar receiver <here>"))
    # sm_thin (shadow maps)
    add(_row("sm_thin", "shadow maps", 0, TRUTH, time=40.0))
    add(_row("sm_thin", "shadow maps", 0, "shadow_map", error=0.001, time=2.0, lit=900), worst=1)
    add(_row("sm_thin", "shadow maps", 0, "shadow_volume", error=0.003, time=3.0, lit=900), worst=2)
    add(_row("sm_thin", "shadow maps", 0, "planar", error=0.2, time=0.5, lit=900), worst=90)
    add(_row("sm_thin", "shadow maps", 0, ODD, error=0.05, time=0.7, lit=900), worst=40)
    if root is not None:
        for scene in ("box_on_plane", "sv_two_lights", "sm_thin"):
            (root / "runs" / scene / "report.html").write_text("<html></html>")
    return pd.DataFrame(rows)


META = {"name": "synthetic <suite>", "description": "a made-up study & its report", "size": [64, 48], "repeat": 3,
        "warmup": 1, "device": "llvmpipe (test)", "revision": "abc123", "date": "2026-01-01T00:00:00+00:00",
        "timing": "wall clock around ctx.finish()", "workers": 2, "elapsed_s": 12.5, "runs": 14, "cached": 3,
        "failed": 1, "suite_file": "/somewhere/suite.toml"}


def _cfg(results, scene, label) -> pd.Series:
    c = agg.per_configuration(results)
    hit = c[(c["scene"] == scene) & (c["label"] == label)]
    assert len(hit) == 1
    return hit.iloc[0]


# ----------------------------------------------------------------------------- per configuration

def test_per_configuration_pools_lights():
    res = synthetic()
    cfg = agg.per_configuration(res)
    # one row per (scene, label) that ran: 4 + 3 (planar failed) + 5
    assert len(cfg) == 12
    assert list(cfg.columns) == agg.CONFIG_COLUMNS
    sv = _cfg(res, "sv_two_lights", "shadow_volume")
    assert sv["lights"] == 2 and sv["evaluated_pixels"] == 4000
    assert sv["time_ms"] == pytest.approx(8.0)            # 3 + 5: a frame renders both lights
    assert sv["time_iqr_ms"] == pytest.approx(0.4)
    assert sv["error_rate"] == pytest.approx(16 / 4000)   # (10 + 6) wrong of 4000, not mean(1 %, 0.2 %)
    assert sv["false_shadow_rate"] == pytest.approx(6 / 1800)   # by truly lit pixels 800 + 1000
    assert sv["false_lit_rate"] == pytest.approx(10 / 2200)     # by truly shadowed pixels 200 + 2000
    assert sv["boundary_error_px"] == pytest.approx(2.0)
    assert sv["wrong_pixels"] == 16
    assert sv["scene_family"] == "shadow volumes" and sv["technique"] == "shadow_volume"
    truth = _cfg(res, "sv_two_lights", TRUTH)
    assert bool(truth["reference"]) and truth["time_ms"] == pytest.approx(60.0)
    sm = _cfg(res, "sv_two_lights", "shadow_map")
    assert sm["error_rate"] == pytest.approx(60 / 4000)


def test_per_configuration_without_count_columns_weights_by_evaluated_pixels():
    res = synthetic().drop(columns=["truth_lit_pixels", "truth_shadowed_pixels"])
    sv = _cfg(res, "sv_two_lights", "shadow_volume")
    assert sv["false_shadow_rate"] == pytest.approx((4 / 800 * 1000 + 2 / 1000 * 3000) / 4000)
    assert sv["error_rate"] == pytest.approx(16 / 4000)


def test_per_configuration_nan_time_and_csv_round_trip(tmp_path):
    res = synthetic()
    res.loc[(res["scene"] == "sv_two_lights") & (res["label"] == "shadow_volume") & (res["light"] == 1),
            "time_ms_median"] = math.nan
    assert math.isnan(_cfg(res, "sv_two_lights", "shadow_volume")["time_ms"])
    # read back from results.csv: reference as text or bool, empty strings as NaN
    res = synthetic(tmp_path)
    res.to_csv(tmp_path / "results.csv", index=False)
    back = pd.read_csv(tmp_path / "results.csv")
    a, b = agg.per_configuration(res), agg.per_configuration(back)
    assert a["label"].tolist() == b["label"].tolist()
    assert b["reference"].tolist() == a["reference"].tolist()
    np.testing.assert_allclose(a["error_rate"], b["error_rate"])
    np.testing.assert_allclose(a["time_ms"], b["time_ms"])


def test_failed_runs_one_row_per_configuration():
    f = agg.failed_runs(synthetic())
    assert f[["scene", "label"]].values.tolist() == [["sv_two_lights", "planar"]]
    assert f["error"].iloc[0] == "RuntimeError: no planar receiver <here>"


# ----------------------------------------------------------------------------- Pareto front

def test_pareto_front_hand_made():
    t = [1, 2, 3, 2, 4, 4, 5, np.nan, 0.5]
    e = [5, 3, 4, 3, 1, 2, 1, 0.1, np.nan]
    # (3,4) dominated by (2,3); the two (2,3) tie and are both kept; (4,2) and (5,1) dominated by (4,1);
    # NaN points are never on the front
    assert agg.pareto_front(t, e).tolist() == [True, True, False, True, True, False, False, False, False]
    assert agg.pareto_front([7.0], [0.2]).tolist() == [True]
    assert agg.pareto_front([], []).tolist() == []
    assert agg.pareto_front([1, 1], [0, 0]).tolist() == [True, True]
    with pytest.raises(ValueError):
        agg.pareto_front([1, 2], [1])


# ----------------------------------------------------------------------------- Pareto figure

def _panels(fig):
    return {ax.get_title().split()[0]: ax for ax in fig.axes if ax.axison}


def _gid(ax, gid):
    return [ln for ln in ax.lines if ln.get_gid() == gid]


def test_pareto_figure_content():
    fig = pareto.pareto_figure(synthetic())
    panels = _panels(fig)
    assert list(panels) == ["box_on_plane", "sv_two_lights", "sm_thin"]
    box = panels["box_on_plane"]
    assert box.get_xscale() == "log" and box.get_yscale() == "log"
    # the truth is a vertical line at its time, not a point
    (truth,) = _gid(box, "truth")
    assert truth.get_xdata()[0] == pytest.approx(50.0)
    # zero error drawn at half a pixel of 1000 evaluated pixels, in percent
    (floor,) = _gid(box, "zero-floor")
    assert floor.get_ydata()[0] == pytest.approx(100 * 0.5 / 1000)
    # front: planar (1 ms, 0.5 %) and shadow_volume (4 ms, 0 → floor); shadow_map (2 ms, 2 %) is dominated
    (front,) = _gid(box, "pareto-front")
    x, y = front.get_xdata(), front.get_ydata()
    assert x[1:3].tolist() == [1.0, 4.0] and y[1:3] == pytest.approx([0.5, 0.05])
    assert x[0] == 1.0 and y[0] >= 0.5 and y[-1] == pytest.approx(0.05)   # staircase from the top, to the right
    # the failed configuration is named in its panel; the two-light scene's truth time is summed
    sv = panels["sv_two_lights"]
    texts = " ".join(t.get_text() for t in sv.texts)
    assert "failed: planar" in texts
    assert _gid(sv, "truth")[0].get_xdata()[0] == pytest.approx(60.0)
    # one legend for the figure: every drawn configuration, family by family (the tables' order:
    # the headline, volumes then maps, first)
    (legend,) = fig.legends
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels[:4] == ["shadow_volume", "shadow_map", "planar", ODD]
    assert any("no wrong pixel" in s for s in labels)
    assert any(f"> {100 * agg.FAIL_ERROR_RATE:g} %" in s for s in labels)
    # the fail threshold: a line at 1 % in every panel with points; shadow_map's 2 % on box_on_plane is
    # over it (and off the front), so it is named there in the fail colour
    for ax in panels.values():
        (line,) = _gid(ax, "fail-threshold")
        assert line.get_ydata()[0] == pytest.approx(100 * agg.FAIL_ERROR_RATE)
    assert max(ln.get_ydata()[0] for ln in _points(box)) > 100 * agg.FAIL_ERROR_RATE
    named = {t.get_text(): t.get_color() for t in box.texts}
    assert named.get("shadow_map") == pareto.FAIL_COLOR
    assert "planar" in named and "shadow_volume" in named   # the front's points


def _points(ax):
    """The configurations' points of a panel (one Line2D each, labelled by short label)."""
    return [ln for ln in ax.lines if ln.get_gid() == "configuration"]


def _filtered_family_rows(scene):
    rows = [_row(scene, "shadow maps", 0, TRUTH, time=30.0)]
    for k, spec in enumerate(("filtered_map", "filtered_map:variant=esm", "filtered_map:variant=msm",
                              "shadow_map", "shadow_map:variant=slope")):
        rows.append(_row(scene, "shadow maps", 0, spec, error=0.004, time=5.0 + k))
    return rows


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_pareto_figure_tells_configurations_of_a_family_apart():
    """Three filtered_map variants at the same spot were three identical glyphs: now each
    configuration of a family has its own marker, in the family's colour (its declared STYLE),
    the family's own marker first, the same in every panel and in the legend."""
    from matplotlib.colors import to_hex
    from shadowlab.techniques import REGISTRY

    res = pd.DataFrame(_filtered_family_rows("a") + _filtered_family_rows("b") + synthetic().to_dict("records"))
    fig = pareto.pareto_figure(res)
    seen: dict[str, tuple[str, str]] = {}
    for ax in _panels(fig).values():
        for ln in _points(ax):
            style = (to_hex(ln.get_color()), ln.get_marker())
            assert seen.setdefault(ln.get_label(), style) == style   # one look per configuration
    family = {lab: lab.split(":")[0] for lab in seen}
    for fam in set(family.values()):
        mine = [style for lab, style in seen.items() if family[lab] == fam]
        assert len(set(mine)) == len(mine), (fam, mine)              # distinct within the family
        assert {c for c, _ in mine} == {REGISTRY[fam].STYLE.color}    # the family's colour
    assert seen["filtered_map"][1] == REGISTRY["filtered_map"].STYLE.marker
    assert len({m for lab, (_, m) in seen.items() if family[lab] == "filtered_map"}) == 3
    (legend,) = fig.legends
    handles = {t.get_text(): h for t, h in zip(legend.get_texts(), legend.legend_handles)}
    for lab, (color, marker) in seen.items():
        assert (to_hex(handles[lab].get_color()), handles[lab].get_marker()) == (color, marker)
    # legend grouped by family: each family's entries together, in the tables' order (volumes, then maps, ...)
    order = [family[t.get_text()] for t in legend.get_texts() if t.get_text() in seen]
    assert order == sorted(order, key=agg.family_order(REGISTRY).index)


def test_configuration_styles_past_the_markers():
    """More configurations of a family than markers: the markers repeat in a shade of the
    family's colour, the (colour, marker) pairs all distinct."""
    n = 2 * len(pareto.CONFIG_MARKERS) + 3
    cfg = pd.DataFrame({"technique": ["shadow_map"] * n, "label": [f"shadow_map:bias={k}" for k in range(n)]})
    styles = pareto.configuration_styles(cfg)
    assert len(set(styles.values())) == n
    assert pareto.configuration_styles(cfg.iloc[:0]) == {}


def test_pareto_figure_text_legible_at_page_width():
    """Six panels make a figure about as wide as the study page (≈ 1350 px), so it is shown 1:1,
    with tick labels, titles and the legend at ≥ 8 pt and point names at ≥ 7.5 pt."""
    six = pd.concat([_row_frame(f"scene_{k}", k) for k in range(6)], ignore_index=True)
    fig = pareto.pareto_figure(six)
    width_px = fig.get_figwidth() * fig.dpi
    assert 1300 <= width_px <= 1400
    panels = _panels(fig)
    assert len(panels) == 6
    for ax in panels.values():
        ticks = ax.get_xticklabels() + ax.get_yticklabels()
        assert ticks and all(t.get_fontsize() >= 8 for t in ticks)
        assert ax.title.get_fontsize() >= 8
        assert ax.texts and all(t.get_fontsize() >= 7.5 for t in ax.texts)
    (legend,) = fig.legends
    assert all(t.get_fontsize() >= 8 for t in legend.get_texts())


@pytest.mark.slow  # draws a 30-panel figure to PNG (~8 s of matplotlib)
def test_pareto_plot_one_and_many_scenes(tmp_path):
    import matplotlib.image as mpimg

    one = synthetic()
    one = one[one["scene"] == "sm_thin"]
    p1 = pareto.pareto_plot(one, tmp_path / "one.png")
    many = pd.concat([_row_frame(f"scene_{k:02d}", k) for k in range(30)], ignore_index=True)
    fig = pareto.pareto_figure(many)
    assert len(_panels(fig)) == 30
    p30 = pareto.pareto_plot(many, tmp_path / "many.png")
    h1, w1 = mpimg.imread(p1).shape[:2]
    h30, w30 = mpimg.imread(p30).shape[:2]
    assert h30 > 4 * h1   # the figure grows with the rows (8 rows of 4 panels)
    assert w30 > w1


def _row_frame(scene, k):
    rows = [_row(scene, "general", 0, TRUTH, time=10.0)]
    rows.append(_row(scene, "general", 0, "shadow_map", error=0.001 * (k % 5), time=1.0 + k))
    if k % 3 == 0:
        rows.append(_row(scene, "general", 0, "planar", status="failed", err_msg="boom"))
    return pd.DataFrame(rows)


def test_pareto_plot_single_configuration_and_nan_time(tmp_path):
    single = pd.DataFrame([_row("lonely", "general", 0, "shadow_volume", error=0.01, time=2.0)])
    fig = pareto.pareto_figure(single)
    (front,) = _gid(_panels(fig)["lonely"], "pareto-front")
    assert 2.0 in front.get_xdata()
    untimed = pd.DataFrame([_row("untimed", "general", 0, TRUTH, time=math.nan),
                            _row("untimed", "general", 0, "shadow_map", error=0.01, time=math.nan)])
    fig = pareto.pareto_figure(untimed)
    ax = _panels(fig)["untimed"]
    assert "no time: shadow_map" in " ".join(t.get_text() for t in ax.texts)
    assert not _gid(ax, "pareto-front")
    assert pareto.pareto_plot(untimed, tmp_path / "p.png").stat().st_size > 1000
    assert pareto.pareto_plot(pd.DataFrame(columns=["scene", "label"]), tmp_path / "empty.png").is_file()


# ----------------------------------------------------------------------------- summary.md

def test_summary_md(tmp_path):
    res = synthetic()
    table = agg.summary_table(res)
    sm = table[table["label"] == "shadow_map"].iloc[0]
    assert sm["median_error_rate"] == pytest.approx(0.015)   # median of 2 %, 1.5 %, 0.1 %
    assert sm["median_time_ms"] == pytest.approx(2.0)        # median of 2, 3 (1.5 + 1.5), 2
    assert sm["wins"] == [("shadow maps", "sm_thin")]
    assert sm["fails"] == [("box_on_plane", "2.000 %"), ("sv_two_lights", "1.500 %")]
    sv = table[table["label"] == "shadow_volume"].iloc[0]
    assert sv["wins"] == [("general", "box_on_plane"), ("shadow volumes", "sv_two_lights")]
    planar = table[table["label"] == "planar"].iloc[0]
    assert planar["scenes"] == 2 and planar["failed"] == 1
    assert [s for s, _ in planar["fails"]] == ["sv_two_lights", "sm_thin"]
    # grouped by family, in the tables' order: the headline (volumes, then maps) first
    assert table["technique"].tolist() == ["shadow_volume", "shadow_map", "planar", "planar"]

    fam = agg.family_table(res).set_index("scene_family")
    assert fam.loc["shadow maps", "best"] == "shadow_map"
    assert fam.loc["general", "best"] == "shadow_volume"
    assert fam.loc["shadow volumes", "best"] == "shadow_volume"
    assert fam.loc["general", "fastest"] == "planar" and fam.loc["general", "fastest_ok"] == "planar"
    assert fam.loc["shadow maps", "fastest"] == "planar"
    assert fam.loc["shadow maps", "fastest_ok"] == "shadow_map"   # planar's 20 % is over the threshold

    path = sr.write_summary_md(res, tmp_path / "summary.md", META)
    text = path.read_text()
    assert text.startswith("# Study: synthetic <suite>")
    for fact in ("64×48", "llvmpipe (test)", "abc123", "2026-01-01", "wall clock around ctx.finish()"):
        assert fact in text
    fam_rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[1:-1]]
                for line in text.split("## By scene family")[1].split("## By scene\n")[0].splitlines()
                if line.startswith("| ")}
    assert fam_rows["shadow maps"][3] == "shadow_map" and fam_rows["shadow maps"][4] == "0.100 %"
    assert fam_rows["general"][3] == "shadow_volume"
    failed = text.split("## Failed runs")[1]
    assert "sv_two_lights" in failed and "planar" in failed and "RuntimeError: no planar receiver <here>" in failed
    assert "sv_two_lights (failed: RuntimeError" in text
    assert "box_on_plane (2.000 %)" in text
    assert f"{100 * agg.FAIL_ERROR_RATE:g} %" in text


# ----------------------------------------------------------------------------- study.html

@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_study_html(tmp_path):
    res = synthetic(tmp_path)
    out = sr.write_study_report(tmp_path, res, META)
    assert set(out) == {"pareto", "html", "summary"} and all(Path(p).is_file() for p in out.values())
    doc = Path(out["html"]).read_text()
    srcs = re.findall(r'<img[^>]* src="([^"]+)"', doc)
    links = re.findall(r'<a href="([^"#][^"]*)"', doc)
    for s in srcs + links:
        assert not s.startswith("/") and "://" not in s and (tmp_path / s).is_file(), s
    assert str(tmp_path) not in doc
    # verdicts first: the headline table comes before the Pareto figure and the scenes
    assert doc.count("<h1>") == 1
    assert doc.index('id="verdict-table"') < doc.index('src="pareto.png"') < doc.index('id="scene-1"')
    # a software rasteriser's times are flagged at the top, provenance is in the footer
    assert doc.index('id="timing-banner"') < doc.index('id="verdict-table"')
    footer = doc.split('<footer class="provenance">')[1]
    for fact in ("llvmpipe (test)", "abc123", "12.5 s", "14 runs", "3 cached", "1 failed", "suite.toml"):
        assert fact in footer
    # every configuration of a scene is in its grid, images from its run directory, with the insets
    grid = doc.split('id="scene-1"')[1].split('id="scene-2"')[0]
    for stem in ("raytrace", "shadow_map", "shadow_volume", "planar"):
        assert f'runs/box_on_plane/images/{stem}_' in grid
    assert "url(&#39;runs/box_on_plane/images/shadow_map_error.png&#39;)" in grid
    assert links.count("runs/box_on_plane/report.html") == 1 and "runs/sv_two_lights/report.html" in links
    # the failed run is in its scene's grid and in the failed-runs table
    assert "failed: RuntimeError: no planar receiver &lt;here&gt;" in doc
    failed = doc.split('id="failed"')[1].split("<h2")[0]
    assert "sv_two_lights" in failed and "planar" in failed
    # escaped text, never raw
    assert "planar:note=&lt;b&gt;&amp;&#34;x&#34;" in doc and ODD not in doc
    assert "a made-up study &amp; its report" in doc and "synthetic &lt;suite&gt;" in doc and "<suite>" not in doc
    assert "false lit (leak, missing shadow)" in doc
    # the verdicts: planar fails sm_thin (20 %), marked in its cell
    verdicts = doc.split('id="verdict-table"')[1].split("</table>")[0]
    assert verdicts.count("✗") >= 1 and 'class="fail"' in verdicts


def test_study_html_offers_signed_maps_of_soft_configurations(tmp_path):
    """A configuration whose run directory has a signed difference map (soft shadows) carries it
    as a view of the scene's grid; a study without any offers no such view."""
    res = synthetic(tmp_path)
    plain = Path(sr.write_study_html(tmp_path, res, META)).read_text()
    assert "data-signed=" not in plain and 'data-show="signed"' not in plain
    record_path = tmp_path / "runs/box_on_plane/run.json"
    record = json.loads(record_path.read_text())
    save_png(tmp_path / "runs/box_on_plane/images/shadow_map_signed.png", np.full((6, 8, 3), 0.9))
    next(im for im in record["images"] if im["label"] == "shadow_map")["signed"] = "images/shadow_map_signed.png"
    record_path.write_text(json.dumps(record))
    doc = Path(sr.write_study_html(tmp_path, res, META)).read_text()
    scene = doc.split('id="scene-1"')[1].split('id="scene-2"')[0]
    assert 'data-show="signed"' in scene and 'data-signed="runs/box_on_plane/images/shadow_map_signed.png"' in scene
    assert doc.count("data-signed=") == 1
