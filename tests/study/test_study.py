"""The study (docs/contracts.md#study-directory): suite validation, parallel and Dask runs that agree with one
worker, the cache (repeat, change, force, interruption), failed runs, and the baseline check."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from shadowlab import cli
from shadowlab.evaluation import perceptual
from shadowlab.evaluation.metrics import RATE_TOLERANCE
from shadowlab.study import check as chk
from shadowlab.study.runner import Progress, run_study
from shadowlab.study.suite import SuiteError, builtin_suites, load_suite

#: Error metrics that must agree exactly between ways of running a study.
EXACT = ["evaluated_pixels", "error_rate", "false_shadow_rate", "false_lit_rate", "boundary_error_px",
         "visibility_mae", "contact_gap_px", "false_shadow_pixels", "false_lit_pixels"]

SMALL = """
name = "small"
size = [96, 72]
repeat = 1
warmup = 0
scenes = ["box_on_plane", "sv_camera_in_shadow"]
techniques = ["shadow_volume:mode=zpass", "planar"]
[[sweeps]]
technique = "shadow_map"
resolution = [64, 512]
scenes = ["box_on_plane"]
"""


def write_suite(tmp_path: Path, text: str = SMALL, name: str = "suite.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def metrics_of(results: pd.DataFrame) -> pd.DataFrame:
    ok = results[results["status"] == "ok"].sort_values(["scene", "label", "light"])
    work = sorted(c for c in ok.columns if c.startswith("work_"))  # the work counters (shadowlab.gpu.work)
    return ok[["scene", "label", "light"] + [c for c in EXACT if c in ok.columns] + work].reset_index(drop=True)


# ----------------------------------------------------------------------------- suites

@pytest.mark.slow  # inner-loop budget (issue 36): among the slowest; make test runs it
def test_shipped_suites_load_and_cover_every_family():
    from shadowlab.techniques import REGISTRY

    suites = builtin_suites()
    assert {"quick", "hard_shadows", "real_meshes"} <= set(suites)
    for name in suites:
        suite = load_suite(name)
        assert suite.runs() > 0
    def families(suite):
        return {spec.split(":")[0] for specs in suite.configurations.values() for spec in specs}

    hard = {name for name, cls in REGISTRY.items() if cls.LIGHTS != {"area"}} - {"raytrace"}
    # the headline holds hard-shadow families, the four classic ones at least; every technique
    # is measured by some shipped suite (a new one joins a suite with one line in its file)
    quick = families(load_suite("quick"))
    assert quick <= hard and {"shadow_map", "shadow_volume", "planar", "shadow_polygons"} <= quick
    # (raytrace itself appears under a shadow budget in many_lights: exact shadows for the kept lights)
    assert set().union(*(families(load_suite(n)) for n in suites)) - {"raytrace"} == set(REGISTRY) - {"raytrace"}


def test_sweeps_expand_to_canonical_specs_on_their_scenes_only(tmp_path):
    suite = load_suite(write_suite(tmp_path))
    box = suite.configurations["box_on_plane"]
    assert len(box) == 4 and len(suite.configurations["sv_camera_in_shadow"]) == 2
    assert any(s.startswith("shadow_map:resolution=64,") for s in box)
    assert all(s.count("=") > 1 for s in box)  # full specs: every parameter written out
    assert suite.scenes[1].family == "shadow volumes" and suite.scenes[0].family == "general"


@pytest.mark.parametrize("text, where", [
    (SMALL.replace('"box_on_plane", "sv_camera', '"no_such_scene", "sv_camera'), "scenes[0]"),
    (SMALL.replace('"planar"]', '"planar", "shadow_mop"]'), "techniques[2]"),
    (SMALL.replace('"planar"]', '"planar:stencli=false"]'), "techniques[1]"),
    (SMALL.replace("resolution = [64, 512]", "resolution = [64, 512]\nbais = [0.1]"), "sweeps[0]"),
    (SMALL.replace("resolution = [64, 512]", "resolution = [64, -5]"), "sweeps[0]"),
    (SMALL.replace('scenes = ["box_on_plane"]\n', 'scenes = ["sm_grazing"]\n'), "sweeps[0].scenes"),
    (SMALL.replace("repeat = 1", "repaet = 1"), "repaet"),
    (SMALL.replace("size = [96, 72]", "size = [0, 72]"), "size"),
])
def test_bad_suites_name_the_file_and_entry(tmp_path, text, where):
    path = write_suite(tmp_path, text)
    with pytest.raises(SuiteError) as info:
        load_suite(path)
    assert str(path) in str(info.value) and where in str(info.value)


def test_bad_suite_exits_2_before_rendering(tmp_path, capsys):
    path = write_suite(tmp_path, SMALL.replace('"planar"]', '"planar:bogus=1"]'))
    out = tmp_path / "study"
    assert cli.main(["study", str(path), "--out", str(out)]) == cli.EXIT_BAD_INPUT
    assert "techniques[1]" in capsys.readouterr().err
    assert not out.exists()
    assert cli.main(["study", "no_such_suite"]) == cli.EXIT_BAD_INPUT


# ----------------------------------------------------------------------------- running

@pytest.fixture(scope="module")
def one_worker(tmp_path_factory):
    """The small suite run with one worker (the reference the other runs must equal)."""
    tmp = tmp_path_factory.mktemp("study1")
    path = write_suite(tmp)
    outcome = run_study(path, out=tmp / "out", workers=1, log=lambda _: None)
    return path, outcome


@pytest.mark.slow  # a study: spawned worker processes
def test_study_writes_the_contract(one_worker):
    _, outcome = one_worker
    out, res = outcome.out, outcome.results
    assert not outcome.failed
    for name in ("results.csv", "study.json", "pareto.png", "study.html", "summary.md", "rank_agreement.csv"):
        assert (out / name).is_file(), name
    # the perceptual metrics of each configuration's picture, on its rows only (make installs them)
    if perceptual.available():
        conf = res[~res["reference"].astype(bool)]
        assert conf["flip_mean"].between(0, 1).all() and conf["ssim"].between(-1, 1).all()
        assert res.loc[res["reference"].astype(bool), "flip_mean"].isna().all()
        assert "What people see" in (out / "summary.md").read_text()
    for col in ("run_dir", "revision", "renderer", "status", "scene_family", "error_rate", "time_ms_median"):
        assert col in res.columns
    assert len(res) == 2 * 1 + 4 + 2  # per scene: the truth and each configuration (one light each)
    for scene in ("box_on_plane", "sv_camera_in_shadow"):
        run = out / "runs" / scene
        metrics = pd.read_csv(run / "metrics.csv")
        masks = np.load(run / "masks.npz")
        assert set(metrics["label"]) == set(masks.files) - {"ground_truth"} | {metrics["label"][0]}
        assert (run / "report.html").is_file() and (run / "run.json").is_file()
        assert masks["ground_truth"].shape == (72, 96)
    # the truth's own rows are exact, and z-pass fails where the camera is in shadow (SV1)
    zpass = res[(res["scene"] == "sv_camera_in_shadow") & (res["technique"] == "shadow_volume")]
    assert zpass["error_rate"].iloc[0] > 0.5
    assert (res[res["reference"]]["error_rate"] == 0).all()
    # every configuration's images exist; the run directories hold the common zoom insets, placed
    # where the configurations are wrong (z-pass is wrong on most of sv_camera_in_shadow)
    first = res[res["light"] == 0]
    assert all((out / p).is_file() for p in first["shaded_image"])
    assert all((out / p).is_file() for p in first.loc[~first["reference"], "error_image"])
    record = json.loads((out / "runs" / "sv_camera_in_shadow" / "run.json").read_text())
    assert record["insets"] and all(i["wrong"] > 0 for i in record["insets"])
    zpass_image = next(im for im in record["images"] if im["label"].startswith("shadow_volume:")
                       and "zpass" in im["label"])
    assert sum(zpass_image["inset_wrong"]) > 0


@pytest.mark.slow  # a study: spawned worker processes
def test_two_workers_give_the_same_metrics(one_worker, tmp_path):
    path, ref = one_worker
    two = run_study(path, out=tmp_path / "two", workers=2, log=lambda _: None)
    pd.testing.assert_frame_equal(metrics_of(two.results), metrics_of(ref.results))


@pytest.mark.slow  # a study: spawned worker processes
def test_repeated_study_runs_nothing_and_changes_rerun_only_what_changed(one_worker, tmp_path):
    _, ref = one_worker
    path = write_suite(tmp_path)  # a copy of its own: this test edits the suite
    out = tmp_path / "out"
    shutil.copytree(ref.out, out)
    again = run_study(path, out=out, workers=1, log=lambda _: None)
    assert again.ran == 0 and again.cached == 8 * 2
    # one more configuration: its accuracy and timing tasks only
    path.write_text(SMALL.replace('"planar"]', '"planar", "shadow_volume:mode=zfail"]'))
    more = run_study(path, out=out, workers=1, log=lambda _: None)
    assert more.ran == 2 * 2  # one configuration on two scenes, each accuracy + timing
    forced = run_study(path, out=out, workers=1, force=True, log=lambda _: None)
    assert forced.ran == 10 * 2
    pd.testing.assert_frame_equal(metrics_of(forced.results), metrics_of(more.results))
    # more repeats: every run re-timed, nothing re-rendered for accuracy
    path.write_text(path.read_text().replace("repeat = 1", "repeat = 2"))
    retimed = run_study(path, out=out, workers=1, log=lambda _: None)
    assert retimed.ran == 10 and not retimed.failed
    # a truncated cache entry is a miss: redone, not reported as a failure
    entry = sorted((out / "cache" / "acc").glob("*.npz"))[0]
    entry.write_bytes(entry.read_bytes()[:100])
    healed = run_study(path, out=out, workers=1, log=lambda _: None)
    assert healed.ran == 1 and not healed.failed
    pd.testing.assert_frame_equal(metrics_of(healed.results), metrics_of(more.results))


@pytest.mark.slow  # a study: spawned worker processes
def test_an_edited_scene_reruns_that_scene_only(tmp_path):
    scene = tmp_path / "lit_box.toml"
    box = (Path(__file__).resolve().parents[2] / "shadowlab/scenes/box_on_plane.toml").read_text()
    scene.write_text(box.replace('name = "box_on_plane"', 'name = "lit_box"'))
    path = write_suite(tmp_path, SMALL.replace('"box_on_plane", "sv_camera', f'"{scene}", "sv_camera')
                       .replace('scenes = ["box_on_plane"]\n', ""))
    first = run_study(path, out=tmp_path / "out", workers=1, log=lambda _: None)
    assert not first.failed
    before = first.results.set_index(["scene", "config"])["truth_shadowed_pixels"]
    # the light moves: the edited scene's truth and configurations rerun, the other scene's not
    import re
    moved = re.sub(r"position = \[[^\]]*\]", "position = [0.5, 9.0, 0.5]", scene.read_text(), count=1)
    assert moved != scene.read_text()
    scene.write_text(moved)
    second = run_study(path, out=tmp_path / "out", workers=1, log=lambda _: None)
    n_lit_box = 1 + len(load_suite(path).configurations["lit_box"])
    assert second.ran == 2 * n_lit_box and not second.failed
    after = second.results.set_index(["scene", "config"])["truth_shadowed_pixels"]
    assert (after["lit_box"] != before["lit_box"]).all()
    assert (after["sv_camera_in_shadow"] == before["sv_camera_in_shadow"]).all()
    # the timing phase ran alone, with every core's llvmpipe threads
    from shadowlab.output.cache import Cache
    from shadowlab.study.executors import cores
    timings = [Cache(tmp_path / "out" / "cache").load_timing(p.stem)
               for p in (tmp_path / "out" / "cache" / "time").glob("*.json")]
    assert timings and all(t["lp_num_threads"] == str(cores()) for t in timings)


class _Interrupt(Progress):
    def __init__(self, after: int):
        self.after, self.done = after, 0

    def step(self, what: str) -> None:
        self.done += 1
        if self.done == self.after:
            raise KeyboardInterrupt


@pytest.mark.slow  # a study: spawned worker processes
def test_interrupted_study_resumes_from_a_consistent_cache(one_worker, tmp_path):
    path, ref = one_worker
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run_study(path, out=out, workers=1, progress=_Interrupt(after=3), log=lambda _: None)
    cached = list((out / "cache").rglob("*"))
    assert not [p for p in cached if p.name.startswith(".")]  # no half-written entries
    resumed = run_study(path, out=out, workers=1, log=lambda _: None)
    assert 0 < resumed.cached < 16 and not resumed.failed
    pd.testing.assert_frame_equal(metrics_of(resumed.results), metrics_of(ref.results))


@pytest.mark.slow  # a study: spawned worker processes
def test_a_failing_run_is_recorded_and_the_others_go_on(tmp_path, capsys):
    broken = tmp_path / "broken_mesh.toml"
    broken.write_text((Path(__file__).resolve().parents[2] / "shadowlab/scenes/box_on_plane.toml").read_text()
                      .replace('mesh = "box"\nsize = [1.0, 1.0, 1.0]', 'mesh = "missing.obj"')
                      .replace('name = "box_on_plane"', 'name = "broken_mesh"'))
    text = SMALL.replace('"box_on_plane", "sv_camera_in_shadow"', f'"box_on_plane", "{broken}"') \
                .replace('scenes = ["box_on_plane"]\n', "")
    path = write_suite(tmp_path, text)
    assert cli.main(["study", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 1
    res = pd.read_csv(tmp_path / "out" / "results.csv")
    bad = res[res["scene"] == "broken_mesh"]
    assert len(bad) and (bad["status"] == "failed").all()
    assert bad["error"].str.contains("missing.obj").all()
    assert (res[res["scene"] == "box_on_plane"]["status"] == "ok").all()
    assert "FAILED" in capsys.readouterr().out


@pytest.mark.slow  # a Dask LocalCluster (spawned processes)
def test_dask_local_cluster_gives_the_local_results(one_worker, tmp_path):
    distributed = pytest.importorskip("distributed")
    path, ref = one_worker
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        on_dask = run_study(path, out=tmp_path / "dask", dask=client, log=lambda _: None)
    assert not on_dask.failed and on_dask.ran == 16
    pd.testing.assert_frame_equal(metrics_of(on_dask.results), metrics_of(ref.results))


# ----------------------------------------------------------------------------- baseline check

@pytest.mark.slow  # uses the one_worker study (spawned worker processes)
def test_check_holds_the_baseline_and_catches_regressions(one_worker, tmp_path, capsys):
    _, outcome = one_worker
    base = tmp_path / "base.csv"
    assert cli.main(["check", str(outcome.out), str(base), "--update"]) == 0
    assert cli.main(["check", str(outcome.out), str(base)]) == 0
    table = pd.read_csv(base)
    # a baseline that was better than the study (as if the study had regressed)
    worse = table.copy()
    worse.loc[worse["label"].str.startswith("shadow_volume:mode=zpass"), "error_rate"] = 0.1
    worse.to_csv(base, index=False)
    capsys.readouterr()
    assert cli.main(["check", str(outcome.out), str(base)]) == 1
    printed = capsys.readouterr().out
    assert "REGRESSIONS" in printed and "error_rate" in printed and "sv_camera_in_shadow" in printed
    # a configuration the study no longer has is a regression too
    extra = pd.concat([table, table.iloc[[0]].assign(config="shadow_map:gone")])
    result = chk.check(outcome.results, extra)
    assert list(result.regressions["problem"]) == ["missing from the study"]
    # a configuration whose defaults changed is still the same configuration: its metrics are
    # compared, and the new resolution is reported
    respec = table.copy()
    i = respec.index[respec["config"].str.startswith("shadow_map")][0]
    assert "bias=0.002," in respec.loc[i, "label"]
    respec.loc[i, "label"] = respec.loc[i, "label"].replace("bias=0.002,", "bias=0.02,")
    result = chk.check(outcome.results, respec)
    assert result.ok and len(result.respecified) == 1 and result.respecified[0].endswith("bias 0.02 → 0.002")
    # within tolerance is fine: a change of half the absolute tolerance
    nudged = table.copy()
    nudged["error_rate"] = (nudged["error_rate"] - RATE_TOLERANCE[0] / 2).clip(lower=0)
    assert chk.check(outcome.results, nudged).ok


@pytest.mark.slow  # uses the one_worker study (spawned worker processes)
def test_check_rejects_what_is_not_a_baseline(one_worker, tmp_path):
    _, outcome = one_worker
    bogus = tmp_path / "bogus.csv"
    bogus.write_text("scene,light,label,speed\nx,0,y,1\n")
    assert cli.main(["check", str(outcome.out), str(bogus)]) == cli.EXIT_BAD_INPUT
    assert cli.main(["check", str(tmp_path), str(bogus)]) == cli.EXIT_BAD_INPUT


# ----------------------------------------------------------------------------- cache

def test_cache_keys_follow_scene_content_meshes_and_code(tmp_path):
    from shadowlab.output.cache import run_key, scene_content_hash

    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene = tmp_path / "s.toml"
    scene.write_text('name = "s"\n[[objects]]\nmesh = "m.obj"\n')
    h = scene_content_hash(scene)
    mesh.write_text("v 0 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\n")
    assert scene_content_hash(scene) != h  # the mesh is part of the scene's content
    mesh.unlink()
    assert scene_content_hash(scene) != h
    base = dict(scene_hash="a", spec="shadow_map", size=(8, 8), revision="r1", renderer="llvmpipe")
    key = run_key(**base)
    assert key == run_key(**base)
    for change in (dict(spec="planar"), dict(size=(8, 9)), dict(revision="r2"), dict(renderer="NVIDIA")):
        assert run_key(**{**base, **change}) != key
    assert run_key(**base, repeat=5) != run_key(**base, repeat=3)


def test_cache_entries_round_trip_and_a_corrupt_entry_is_a_miss(tmp_path):
    from shadowlab.output.cache import Cache

    cache = Cache(tmp_path / "cache")
    vis = np.linspace(0, 1, 12, dtype=np.float32).reshape(3, 4)
    cache.store_result("k", {"meta": {"rows": [{"error_rate": 0.5, "x": float("nan")}]}, "arrays": {"mask_0": vis},
                             "files": {"a.png": b"\x89PNG..."}})
    back = cache.load_result("k")
    assert back["meta"]["rows"][0]["error_rate"] == 0.5 and np.isnan(back["meta"]["rows"][0]["x"])
    assert np.array_equal(back["arrays"]["mask_0"], vis) and back["files"]["a.png"] == b"\x89PNG..."
    (tmp_path / "cache" / "acc" / "k.npz").write_bytes(b"truncated")
    assert cache.load_result("k") is None
    cache.store_timing("t", {"columns": [{"time_ms_median": 1.5}]})
    assert cache.load_timing("t") == {"columns": [{"time_ms_median": 1.5}]}
    assert cache.load_timing("missing") is None


# ----------------------------------------------------------------------------- scene bundles (Dask without a shared disk)

def copy_scene_with_meshes(name: str, dest: Path) -> Path:
    """A shipped scene copied into ``dest`` with the mesh files it names (same relative paths)."""
    from shadowlab.scene import builtin_scenes
    from shadowlab.output.cache import scene_mesh_files

    src = builtin_scenes()[name]
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy(src, dest / src.name)
    for ref, mesh in scene_mesh_files(src):
        (dest / ref).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(mesh, dest / ref)
    return dest / src.name


def test_scene_bundle_round_trips_and_is_reused(tmp_path):
    from shadowlab.study.bundle import materialize, scene_bundle
    from shadowlab.output.cache import scene_content_hash

    scene = copy_scene_with_meshes("rm_bunny", tmp_path / "src")
    bundle = scene_bundle(scene)
    assert bundle["hash"] == scene_content_hash(scene) and bundle["scene"] == "rm_bunny.toml"
    assert set(bundle["files"]) == {"rm_bunny.toml", "meshes/bunny_closed.ply.gz"}
    copy = materialize(bundle, tmp_path / "root")
    assert copy == tmp_path / "root" / bundle["hash"] / "rm_bunny.toml"
    assert scene_content_hash(copy) == bundle["hash"]
    assert (copy.parent / "meshes" / "bunny_closed.ply.gz").read_bytes() == \
        (scene.parent / "meshes" / "bunny_closed.ply.gz").read_bytes()
    marker = copy.parent / "marker"
    marker.write_text("kept")
    assert materialize(bundle, tmp_path / "root") == copy and marker.is_file()  # reused, not rewritten
    assert [p.name for p in (tmp_path / "root").iterdir()] == [bundle["hash"]]  # no temporary folder left


def test_scene_bundle_lifts_its_base_for_meshes_above_the_scene(tmp_path):
    from shadowlab.study.bundle import materialize, scene_bundle
    from shadowlab.output.cache import scene_content_hash

    scene = copy_scene_with_meshes("rm_bunny", tmp_path / "src" / "scenes")
    shutil.move(tmp_path / "src" / "scenes" / "meshes", tmp_path / "src" / "meshes")
    scene.write_text(scene.read_text().replace('"meshes/', '"../meshes/'))
    bundle = scene_bundle(scene)
    assert set(bundle["files"]) == {"scenes/rm_bunny.toml", "meshes/bunny_closed.ply.gz"}
    copy = materialize(bundle, tmp_path / "root")
    assert scene_content_hash(copy) == scene_content_hash(scene)


def test_scene_bundle_refuses_paths_leaving_its_folder(tmp_path):
    from shadowlab.study.bundle import materialize

    for name in ("../evil.toml", "/tmp/evil.toml", "a/../../evil.toml", ""):
        with pytest.raises(ValueError, match="leave the bundle"):
            materialize({"hash": "ab12", "scene": name, "files": {name: b"x"}}, tmp_path / "root")
    with pytest.raises(ValueError, match="hex digest"):
        materialize({"hash": "../x", "scene": "a.toml", "files": {"a.toml": b"x"}}, tmp_path / "root")
    assert not any((tmp_path / "root").glob("**/*evil*")) and not (tmp_path / "evil.toml").exists()


def test_scene_bundle_refuses_an_absolute_mesh_path(tmp_path):
    from shadowlab.study.bundle import scene_bundle

    scene = copy_scene_with_meshes("rm_bunny", tmp_path / "src")
    mesh = (scene.parent / "meshes" / "bunny_closed.ply.gz").resolve()
    scene.write_text(scene.read_text().replace('"meshes/bunny_closed.ply.gz"', f'"{mesh.as_posix()}"'))
    with pytest.raises(ValueError, match="absolute path"):
        scene_bundle(scene)


BUNDLED = """
name = "bundled"
size = [96, 72]
repeat = 1
warmup = 0
scenes = ["rm_bunny.toml", "box_on_plane.toml"]
techniques = ["shadow_map", "shadow_volume"]
"""


@pytest.mark.slow  # a Dask LocalCluster (spawned processes) and a local study
def test_dask_workers_read_scenes_from_bundles_not_the_source_files(tmp_path):
    distributed = pytest.importorskip("distributed")
    from shadowlab.output.cache import Cache

    src = tmp_path / "src"
    for name in ("rm_bunny", "box_on_plane"):
        copy_scene_with_meshes(name, src)
    path = write_suite(src, BUNDLED)
    local = run_study(path, out=tmp_path / "local", workers=1, log=lambda _: None)
    assert not local.failed
    worker_dir, bundle_dir = tmp_path / "worker", tmp_path / "bundles"
    worker_dir.mkdir()
    with distributed.LocalCluster(n_workers=1, processes=True, threads_per_worker=1, dashboard_address=None,
                                  local_directory=str(worker_dir),
                                  env={"SHADOWLAB_BUNDLE_DIR": str(bundle_dir)}) as cluster, \
            distributed.Client(cluster) as client:
        on_dask = run_study(path, out=tmp_path / "dask", dask=client, log=lambda _: None)
        seen = client.run(lambda: sorted(str(p) for p in __import__("pathlib").Path(
            __import__("os").environ["SHADOWLAB_BUNDLE_DIR"]).glob("*/*.toml")))
    assert not on_dask.failed
    pd.testing.assert_frame_equal(metrics_of(on_dask.results), metrics_of(local.results))
    # the worker wrote one bundle per scene, and every task read its scene from there
    (files,) = seen.values()
    assert sorted(Path(f).name for f in files) == ["box_on_plane.toml", "rm_bunny.toml"]
    assert all(Path(f).parent.parent == bundle_dir for f in files)
    cache = Cache(on_dask.out / "cache")
    entries = list((cache.root / "acc").glob("*.npz"))
    assert len(entries) == 2 * 3  # per scene: the truth and two configurations
    for entry in entries:
        loaded = Path(cache.load_result(entry.stem)["meta"]["scene_file"])
        assert loaded.parent.parent == bundle_dir and src not in loaded.parents


def test_a_scene_whose_timing_runs_all_failed_still_gets_its_plot(tmp_path):
    """Every timing task of a scene can fail (its file edited mid-study): its rows then have no
    time columns, and the speed-error plot says so instead of failing the whole study."""
    from shadowlab.output import pictures

    rows = pd.DataFrame({"short_label": ["shadow_map", "planar"], "light": [0, 0], "error_rate": [0.01, 0.02]})
    pictures.speed_error_plot(rows, tmp_path / "speed_vs_error.png")
    assert (tmp_path / "speed_vs_error.png").stat().st_size > 0


def test_the_family_comes_from_the_scene_file_and_the_name_is_only_a_fallback(tmp_path):
    """A soft scene named like a hard one (``rm_area_bunny.toml``, ``family = "soft shadows"``)
    is in the soft family and judged on visibility_mae; a scene file without a family falls back
    on its name's prefix with a warning naming the file; a misspelt family refuses the suite in
    one line naming the file and the key, with the closest family."""
    from shadowlab.analysis.aggregate import judged_metric
    from shadowlab.analysis.verdicts import verdict_table
    from shadowlab.scene import builtin_scenes

    soft = builtin_scenes()["soft_overlap"].read_text()
    assert 'family = "soft shadows"' in soft
    (tmp_path / "rm_area_bunny.toml").write_text(soft.replace('name = "soft_overlap"', 'name = "rm_area_bunny"'))
    plain = builtin_scenes()["box_on_plane"].read_text().replace('family = "general"\n', "")
    (tmp_path / "rm_plain.toml").write_text(plain.replace('name = "box_on_plane"', 'name = "rm_plain"'))
    text = ('name = "families"\nsize = [96, 72]\nrepeat = 1\n'
            'scenes = ["rm_area_bunny.toml", "rm_plain.toml"]\ntechniques = ["shadow_map"]\n')
    suite = load_suite(write_suite(tmp_path, text))
    bunny, rm_plain = suite.scenes
    assert bunny.family == "soft shadows" and bunny.note is None
    assert judged_metric(bunny.family) == "visibility_mae"
    assert rm_plain.family == "real meshes" and judged_metric(rm_plain.family) == "error_rate"
    assert suite.notes == [rm_plain.note]
    assert "warning" in rm_plain.note and str(tmp_path / "rm_plain.toml") in rm_plain.note
    # the verdicts judge the soft scene on mean |V - G|, the hard one on the error rate
    rows = pd.DataFrame([{"scene": e.name, "light": 0, "technique": t, "label": t, "short_label": t,
                          "reference": t == "raytrace", "scene_family": e.family, "status": "ok", "error": "",
                          "evaluated_pixels": 100, "error_rate": 0.5, "false_shadow_rate": 0.5,
                          "false_lit_rate": 0.0, "boundary_error_px": 0.0, "time_ms_median": 1.0,
                          "time_ms_iqr": 0.0, "setup_ms": 1.0, "visibility_mae": 0.001}
                         for e in suite.scenes for t in ("raytrace", "shadow_map")])
    verdicts = verdict_table(rows).set_index("scene")
    assert verdicts.loc["rm_area_bunny", "metric"] == "visibility_mae" and not verdicts.loc["rm_area_bunny", "failed"]
    assert verdicts.loc["rm_plain", "metric"] == "error_rate" and verdicts.loc["rm_plain", "failed"]

    (tmp_path / "rm_plain.toml").write_text(plain.replace('name = "box_on_plane"', 'name = "rm_plain"\n'
                                                          'family = "real mesh"'))
    with pytest.raises(SuiteError) as info:
        load_suite(tmp_path / "suite.toml")
    message = str(info.value)
    assert "\n" not in message and str(tmp_path / "rm_plain.toml") in message and ": family: " in message
    assert "did you mean 'real meshes'?" in message
