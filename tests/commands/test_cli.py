"""The `shadowlab` command end to end: contract files and columns, bad input, atomic output."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from shadowlab.cli import main
from shadowlab.commands.compare import CONTRACT_COLUMNS


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_compare_writes_every_contract_file(tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["compare", "box_on_plane", "--technique", "shadow_map:resolution=512,bias=0.002",
                 "--technique", "shadow_map:resolution=128", "--size", "160x120", "--out", str(out),
                 "--repeat", "2"])
    assert code == 0
    printed = capsys.readouterr().out
    assert str(out) in printed and "report.html" in printed
    df = pd.read_csv(out / "metrics.csv")
    assert list(df.columns[: len(CONTRACT_COLUMNS)]) == CONTRACT_COLUMNS
    assert len(df) == 3 and df["reference"].sum() == 1
    assert (df["width"] == 160).all() and (df["height"] == 120).all()
    assert df.loc[df["reference"], "error_rate"].item() == 0
    masks = np.load(out / "masks.npz")
    labels = set(df["label"]) - {df.loc[df["reference"], "label"].item()}
    assert set(masks.files) == {"ground_truth"} | labels
    for key in masks.files:
        m = masks[key]
        assert m.dtype == np.float32 and m.shape == (120, 160)
        finite = m[np.isfinite(m)]
        assert finite.size == df["evaluated_pixels"].iloc[0] and finite.min() >= 0 and finite.max() <= 1
    # The masks reproduce the metrics.
    gt = masks["ground_truth"]
    row = df[df["short_label"] == "shadow_map:resolution=128"].iloc[0]
    m = masks[row["label"]]
    ev = np.isfinite(gt)
    assert np.sum((m[ev] < 0.5) != (gt[ev] < 0.5)) / ev.sum() == pytest.approx(row["error_rate"])
    run = json.loads((out / "run.json").read_text())
    for key in ("scene", "configurations", "renderer", "versions", "timing_method", "date"):
        assert run[key]
    for im in run["images"]:
        for k in ("shaded", "visibility", "error"):
            if k in im:
                assert (out / im[k]).stat().st_size > 0
    assert "<table" in (out / "report.html").read_text()
    # a hard run (point light, 0/1 visibility): no signed map, a truth without sampling error
    assert run["signed_map"] is None and not list((out / "images").glob("*_signed.png"))
    assert run["truth_stderr_max"] == [0.0] and (df["truth_stderr_max"] == 0).all()
    assert "Signed map" not in (out / "report.html").read_text()


@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_soft_run_report_has_the_signed_map(tmp_path):
    """An area light: each configuration gets a signed difference map V − G (diverging, centred
    at 0) in the report, with the colour bar and its caption; run.json records the limit and,
    per light, the truth's standard error bound; metrics.csv has the soft-shadow columns."""
    out = tmp_path / "run"
    assert main(["compare", "soft_banding", "-t", "shadow_map", "--size", "64x48", "--repeat", "1", "--warmup", "0",
                 "--out", str(out)]) == 0
    run = json.loads((out / "run.json").read_text())
    sm = run["signed_map"]
    assert sm["colormap"] == "RdBu" and 0 < sm["limit"] <= 1 and (out / sm["legend"]).stat().st_size > 0
    assert run["truth_stderr_max"] == [pytest.approx(0.5 / np.sqrt(1024))]
    conf = [im for im in run["images"] if im["label"] != run["ground_truth"]]
    assert len(conf) == 1 and (out / conf[0]["signed"]).stat().st_size > 0
    page = (out / "report.html").read_text()
    assert f'data-signed="{conf[0]["signed"]}"' in page and f'src="{sm["legend"]}"' in page
    assert "positive (blue) = the technique is too bright (false light)" in page and f"±{sm['limit']:.2f}" in page
    df = pd.read_csv(out / "metrics.csv")
    row = df[~df["reference"]].iloc[0]
    assert row["penumbra_pixels"] > 0 and row["penumbra_mae"] > 0 and row["truth_stderr_max"] == pytest.approx(1 / 64)
    # the map is V − G of the masks on the run's scale: the largest |V − G| fits inside ±limit
    masks = np.load(out / "masks.npz")
    diff = masks[conf[0]["label"]] - masks["ground_truth"]
    assert np.nanmax(np.abs(diff)) <= sm["limit"] < np.nanmax(np.abs(diff)) + 0.05 + 1e-9
    assert "penumbra_mae" in page and "lit_error_rate" in page


@pytest.mark.parametrize("args,culprit", [
    (["compare", "no_such_scene"], "no_such_scene"),
    (["compare", "box_on_plane", "--technique", "nope"], "nope"),
    (["compare", "box_on_plane", "--technique", "shadow_map:foo=1"], "foo"),
    (["compare", "box_on_plane", "--size", "800by600"], "--size"),
    (["compare", "box_on_plane", "--size", "0x600"], "--size"),
    (["compare", "box_on_plane", "--repeat", "0"], "--repeat"),
])
def test_bad_input_exit_2_one_line(tmp_path, capsys, args, culprit):
    out = tmp_path / "existing"
    out.mkdir()
    (out / "keep.txt").write_text("earlier results")
    assert main(args + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and culprit in err
    assert (out / "keep.txt").read_text() == "earlier results"
    assert [p.name for p in tmp_path.iterdir()] == ["existing"]  # no temporary left behind


@pytest.mark.parametrize("change,culprit", [
    (('beta = 50.0', 'beta = 80.0'), "lights[0].beta"),
    (('alpha = 70.0', 'alpha = 70.0\nintensity = 3.0'), "lights[0].intensity"),
    (('mesh = "sphere"', 'mesh = "meshes/nowhere.obj"'), "nowhere.obj"),
])
def test_bad_scene_file_exit_2(tmp_path, capsys, change, culprit):
    from shadowlab.scene import builtin_scenes

    text = builtin_scenes()["spot_scene"].read_text()
    assert change[0] in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(*change))
    assert main(["compare", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and culprit in err and "bad.toml" in err
    assert not (tmp_path / "r").exists()


@pytest.mark.slow  # inner-loop budget (issue 36): one of the slowest tests; make test runs it
def test_failed_run_leaves_earlier_results(tmp_path, monkeypatch):
    """A failure in the middle of a run (after GL work began) keeps the old run directory."""
    from shadowlab.output import rundir

    out = tmp_path / "run"
    assert main(["compare", "box_on_plane", "--size", "64x48", "--repeat", "1", "--out", str(out)]) == 0
    before = (out / "metrics.csv").read_text()

    def boom(*a, **k):
        raise RuntimeError("simulated failure while writing")

    monkeypatch.setattr(rundir, "render_page", boom)  # the page is the last thing the writer makes
    with pytest.raises(RuntimeError):
        main(["compare", "box_on_plane", "--size", "80x60", "--repeat", "1", "--out", str(out)])
    assert (out / "metrics.csv").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.slow  # three `python -m shadowlab` subprocesses (a fresh interpreter and GL context each)
def test_listing_and_python_m(tmp_path):
    env = dict(os.environ)
    res = subprocess.run([sys.executable, "-m", "shadowlab", "scenes"], capture_output=True, text=True, env=env)
    assert res.returncode == 0 and "box_on_plane" in res.stdout and "sun_scene" in res.stdout
    res = subprocess.run([sys.executable, "-m", "shadowlab", "techniques"], capture_output=True, text=True, env=env)
    assert res.returncode == 0 and "shadow_map" in res.stdout and "resolution=2048" in res.stdout
    # Not a terminal: no progress bar noise on stderr.
    res = subprocess.run([sys.executable, "-m", "shadowlab", "compare", "box_on_plane", "--size", "64x48",
                          "--repeat", "1", "--out", str(tmp_path / "r")], capture_output=True, text=True, env=env)
    assert res.returncode == 0 and res.stderr == ""


@pytest.mark.slow  # inner-loop budget (issue 36): one of the slowest tests; make test runs it
def test_pass_timing_and_device_are_recorded(tmp_path):
    """--pass-timing adds pass_<name>_ms columns and the report's chart; run.json names the GL
    device (vendor, renderer, version, driver) and the code revision."""
    out = tmp_path / "run"
    # mode=zfail: the default (auto) counts box_on_plane's casters by z-pass, which has no caps pass
    assert main(["compare", "box_on_plane", "-t", "shadow_volume:mode=zfail", "-t", "shadow_map:variant=midpoint,resolution=256",
                 "--size", "96x72", "--repeat", "2", "--pass-timing", "--out", str(out)]) == 0
    df = pd.read_csv(out / "metrics.csv")
    volume = df[df["technique"] == "shadow_volume"].iloc[0]
    assert all(np.isfinite(volume[f"pass_{p}_ms"]) for p in ("silhouette", "volume", "caps", "count"))
    smap = df[df["technique"] == "shadow_map"].iloc[0]
    assert all(np.isfinite(smap[f"pass_{p}_ms"]) for p in ("depth", "peel", "resolve", "lookup"))
    run = json.loads((out / "run.json").read_text())
    for key in ("GL_VENDOR", "GL_RENDERER", "GL_VERSION", "driver"):
        assert run["gl"][key]
    # the driver is what GL_VERSION says after the version number and profile, e.g. "Mesa 22.3.6"
    assert run["gl"]["GL_VERSION"].endswith(run["gl"]["driver"]) and run["gl"]["driver"][0] not in "(0123456789"
    assert run["revision"] and run["pass_timing"] and (out / run["pass_times_image"]).stat().st_size > 0
    page = (out / "report.html").read_text()
    assert run["gl"]["GL_RENDERER"] in page and run["pass_times_image"] in page


# --------------------------------------------------------------------------- spelling hints, listings

@pytest.mark.parametrize("args,hint", [
    (["compare", "box_on_plane", "-t", "shadow_mpa"], "unknown technique 'shadow_mpa'; did you mean 'shadow_map'?"),
    (["compare", "box_on_plane", "-t", "shadow_map:resolutoin=512"],
     "shadow_map: unknown parameter 'resolutoin'; did you mean 'resolution'?"),
    (["compare", "box_on_plane", "-t", "shadow_map:variant=slop"], "got 'slop'; did you mean 'slope'?"),
    (["compare", "box_on_plan"], "box_on_plan: scene: no such scene file, and not a shipped scene; "
                                 "did you mean 'box_on_plane'?"),
    (["animate", "tm_rotating_su"], "not a shipped scene; did you mean 'tm_rotating_sun'?"),
    (["study", "quik"], "quik: no such suite file, and not a shipped suite; did you mean 'quick'?"),
    (["techniques", "shadow_mpa"], "unknown technique 'shadow_mpa'; did you mean 'shadow_map'?"),
])
def test_misspelt_names_get_a_did_you_mean(tmp_path, capsys, args, hint):
    assert main(args + (["--out", str(tmp_path / "out")] if args[0] != "techniques" else [])) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("shadowlab: error: ") and hint in err, err
    assert not (tmp_path / "out").exists()


def test_no_hint_when_nothing_is_close(capsys):
    assert main(["compare", "box_on_plane", "-t", "zzzz"]) == 2
    assert "did you mean" not in capsys.readouterr().err


@pytest.mark.parametrize("body,hint", [
    ('scenes = ["box_on_plan"]\ntechniques = ["shadow_map"]\n',
     "scenes[0]: unknown scene 'box_on_plan'; did you mean 'box_on_plane'?"),
    ('scenes = ["box_on_plane"]\ntechniques = ["shadow_mpa"]\n',
     "techniques[0]: unknown technique 'shadow_mpa'; did you mean 'shadow_map'?"),
    ('scenes = ["box_on_plane"]\ntechnique = ["shadow_map"]\n', "technique: unknown key; did you mean 'techniques'?"),
    ('scenes = ["box_on_plane"]\n[[sweeps]]\ntechnique = "shadow_map"\nresolutoin = [256, 512]\n',
     "unknown parameter 'resolutoin'; did you mean 'resolution'?"),
    ('scenes = ["box_on_plane"]\n[[sweeps]]\ntechnique = "shadow_map"\nvariant = ["slope", "constnat"]\n',
     "got 'constnat'; did you mean 'constant'?"),
    ('scenes = ["box_on_plane"]\n[[sweeps]]\ntechnique = "shadow_map"\nscenes = ["box_on_plan"]\n',
     "sweeps[0].scenes: 'box_on_plan' is not one of the suite's scenes; did you mean 'box_on_plane'?"),
])
def test_suite_file_misspellings_get_the_same_hint(tmp_path, capsys, body, hint):
    suite = tmp_path / "my_suite.toml"
    suite.write_text('name = "my_suite"\nsize = [64, 48]\n' + body)
    assert main(["study", str(suite), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{suite}: " in err and hint in err, err
    assert not (tmp_path / "out").exists()


def test_did_you_mean_helper():
    from shadowlab.util.validation import did_you_mean

    assert did_you_mean("slop", ("constant", "slope")) == "; did you mean 'slope'?"
    assert did_you_mean("u_colr", ["u_color", "u_colour", "u_depth"], n=3) == "; did you mean 'u_color' or 'u_colour'?"
    assert did_you_mean("zzz", ["shadow_map"]) == ""


def test_version(capsys):
    from shadowlab import __version__
    from shadowlab.output import provenance

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code in (0, None)
    rev = provenance.revision()  # git describe in a checkout (the tests' case), else "shadowlab <version>"
    expected = f"shadowlab {__version__}" + ("" if rev.startswith("shadowlab ") else f" ({rev})")
    assert capsys.readouterr().out == expected + "\n"


def test_techniques_name_prints_its_block_of_the_listing(capsys):
    import re

    from shadowlab.techniques import REGISTRY

    assert main(["techniques"]) == 0
    full = capsys.readouterr().out
    blocks = {b.split(":", 1)[0]: b + "\n" for b in re.split(r"\n(?=\S)", full.rstrip("\n"))}
    assert list(blocks) == list(REGISTRY)
    assert main(["techniques", "pcss"]) == 0
    one = capsys.readouterr().out
    assert one == blocks["pcss"] and one.startswith("pcss: ") and "\n    lights: area\n" in one


@pytest.mark.slow  # inner-loop budget (issue 36): one of the slowest tests; make test runs it
def test_scenes_listing_gives_every_scene_its_purpose(capsys):
    from shadowlab.scene import builtin_scenes, scene_purpose

    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    scenes = builtin_scenes()
    assert len(lines) == 2 * len(scenes)
    for (name, path), line, summary in zip(scenes.items(), lines[::2], lines[1::2]):
        assert line.startswith(f"{name} ") and line[28:29] == " ", line
        purpose = line[29:]
        assert purpose == scene_purpose(path) and purpose and not purpose.startswith("#"), line
        assert len(purpose) <= 102 and "INVALID" not in summary and "triangles, lights: " in summary, summary
    assert lines[0] == f"{'box_on_plane':28s} A unit box resting on a floor, lit by a point light: the lab's default scene."


def test_scene_purpose_is_one_shortened_line(tmp_path):
    from shadowlab.scene import scene_purpose

    path = tmp_path / "s.toml"
    path.write_text("# Hard case XY: one two three four five six seven eight nine ten eleven twelve thirteen fourteen\n"
                    "# fifteen sixteen seventeen eighteen. Second sentence.\n#\n# More.\nname = 'x'\n")
    assert scene_purpose(path) == ("Hard case XY: one two three four five six seven eight nine ten eleven twelve "
                                   "thirteen fourteen …")
    path.write_text("# Short: what it tests (Author 2001). Then more.\n# Still more.\nname = 'x'\n")
    assert scene_purpose(path) == "Short: what it tests (Author 2001)."
    path.write_text("name = 'x'  # no opening comment\n")
    assert scene_purpose(path) == ""


@pytest.mark.parametrize("mesh,data,reason", [
    ("x.obj", np.random.default_rng(0).bytes(4096), "(not UTF-8 text)"),  # random bytes as an OBJ
    ("x.ply", b"ply\nformat nonsense\n", "("),
])
def test_unreadable_mesh_file_exit_2(tmp_path, capsys, monkeypatch, mesh, data, reason):
    """Bytes trimesh cannot read as a mesh: one line naming the scene file, the object key and
    the mesh file — not the optional module trimesh reaches for (charset_normalizer, absent
    from constraints.txt: made absent here whether or not it is installed)."""
    from shadowlab.scene import builtin_scenes

    monkeypatch.setitem(sys.modules, "charset_normalizer", None)
    (tmp_path / mesh).write_bytes(data)
    text = builtin_scenes()["box_on_plane"].read_text()
    assert 'mesh = "box"' in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace('mesh = "box"', f'mesh = "{mesh}"'))
    assert main(["compare", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"shadowlab: error: {path}: objects[1].mesh: {tmp_path / mesh} is not a readable mesh file "
                          f"{reason}"), err
    assert "charset_normalizer" not in err and not (tmp_path / "r").exists()
