"""``shadowlab view`` tested as a desktop program: a virtual X server (Xvfb, started here on a free
display; skipped with the install hint without it), the viewer run as a subprocess and driven by
a ``--script`` through switching configurations, the error view and a saved view; then what it
drew held against ``compare``: its shaded view of the saved scene file, and its error view of the
scene's own camera, equal pixel for pixel to compare's images of the same configuration and size
(the window is the image's size exactly, one texel per pixel, HUD off). Also the machine without a
display (one line naming xvfb-run, exit 2) and bad input (compare's one-line errors)."""
from __future__ import annotations

import csv
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import shadowlab
from shadowlab.commands.compare import compare
from shadowlab.scene import load_scene

XVFB = shutil.which("Xvfb")
ROOT = Path(shadowlab.__file__).resolve().parents[1]
SIZE = (160, 120)


def _env(display: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    if display is not None:
        env["DISPLAY"] = display
    return env


def run_view(args: list[str], display: str | None, cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess:
    """``python -m shadowlab view ARGS`` on ``display`` (None: no DISPLAY at all)."""
    return subprocess.run([sys.executable, "-m", "shadowlab", "view", *args], capture_output=True, text=True,
                          env=_env(display), cwd=cwd, timeout=timeout)


@pytest.fixture(scope="module")
def display():
    """A private Xvfb server (it picks a free display number itself: -displayfd); its DISPLAY."""
    if XVFB is None:
        pytest.skip("Xvfb not installed; apt-get install xvfb")
    read, write = os.pipe()
    proc = subprocess.Popen([XVFB, "-displayfd", str(write), "-screen", "0", "640x480x24", "-nolisten", "tcp"],
                            pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    try:
        with os.fdopen(read) as fh:
            number = fh.readline().strip()
        if not number:
            pytest.skip("Xvfb did not start")
        yield f":{number}"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def _png(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


SCRIPT = """
# frame 0: shadow_map, shaded, HUD on
[[step]]
screenshot = "first.png"
[[step]]
key = "tab"          # shadow_volume
[[step]]
key = "f3"           # the error view
[[step]]
key = "h"            # HUD off
[[step]]
wait_truth = true
[[step]]
screenshot = "error.png"
[[step]]
drag = [30, -12]     # look right and up, over 3 frames
frames = 3
[[step]]
hold = "w"           # fly forward 3 frames
frames = 3
[[step]]
key = "tab"          # back to shadow_map (the list wraps)
[[step]]
key = "f1"           # the shaded view
[[step]]
save_view = "view.toml"
[[step]]
screenshot = "shaded.png"
[[step]]
frame_times = "times.csv"
[[step]]
quit = true
"""


@pytest.mark.slow  # a `python -m shadowlab view` subprocess under Xvfb and two compare runs (about 9 s)
def test_a_scripted_session_draws_what_compare_draws(display, tmp_path):
    (tmp_path / "session.toml").write_text(SCRIPT)
    out = tmp_path / "out"
    res = run_view(["sm_contact", "-t", "shadow_map", "-t", "shadow_volume", "--size", f"{SIZE[0]}x{SIZE[1]}",
                    "--script", "session.toml", "--out", str(out)], display, tmp_path)
    assert res.returncode == 0, res.stderr
    for name in ("first.png", "error.png", "view.toml", "shaded.png", "times.csv"):
        assert (out / name).is_file(), name
        assert str(out / name) in res.stdout  # every saved file is named
    assert _png(out / "first.png").shape == (SIZE[1], SIZE[0], 3)
    assert (_png(out / "first.png") != _png(out / "shaded.png")).any()  # the HUD, and another camera

    # the saved view: the scene from the camera the session flew to
    scene, saved = load_scene("sm_contact"), load_scene(out / "view.toml")
    assert not np.array_equal(saved.camera.eye, scene.camera.eye)
    assert [o.name for o in saved.objects] == [o.name for o in scene.objects]

    # compare on the saved view draws the viewer's shaded picture of it, pixel for pixel
    run = compare(out / "view.toml", ["shadow_map"], size=SIZE, out=tmp_path / "run_view", repeat=1, warmup=0)
    assert np.array_equal(_png(out / "shaded.png"), _png(run / "images" / "shadow_map_shaded.png"))
    # and compare on the scene itself draws the viewer's error map of its first camera
    run = compare("sm_contact", ["shadow_volume"], size=SIZE, out=tmp_path / "run_scene", repeat=1, warmup=0)
    assert np.array_equal(_png(out / "error.png"), _png(run / "images" / "shadow_volume_error.png"))

    # the frame times: a row per frame drawn, the camera moving in the six frames of the drag and the flight
    rows = list(csv.DictReader((out / "times.csv").open()))
    assert [int(r["frame"]) for r in rows] == list(range(len(rows)))
    moving = [r for r in rows if r["camera_moved"] == "1"]
    assert len(moving) == 6 and {r["config"] for r in moving} == {"shadow_volume"}
    assert all(float(r["frame_ms"]) > 0 and float(r["render_ms"]) > 0 for r in moving)
    assert {r["view"] for r in rows} >= {"shaded", "error"}
    assert "frame times: shadow_volume:" in res.stdout


@pytest.mark.slow  # a `python -m shadowlab view` subprocess under Xvfb (about 7 s)
def test_screenshot_of_the_truth_and_exit(display, tmp_path):
    res = run_view(["box_on_plane", "-t", "shadow_map", "--size", "96x72", "--view", "truth", "--no-hud",
                    "--screenshot", "truth.png"], display, tmp_path)
    assert res.returncode == 0, res.stderr
    run = compare("box_on_plane", ["shadow_map"], size=(96, 72), out=tmp_path / "run", repeat=1, warmup=0)
    assert np.array_equal(_png(tmp_path / "truth.png"), _png(run / "images" / "ground_truth_shaded.png"))


@pytest.mark.slow  # a `python -m shadowlab view` subprocess: the whole program, not just main()
def test_no_display_is_one_line_naming_xvfb_run(tmp_path):
    res = run_view(["box_on_plane", "--size", "64x48"], None, tmp_path)
    assert res.returncode == 2
    assert "xvfb-run" in res.stderr and "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("args, culprit", [
    (["no_such_scene"], "no such scene file"),
    (["box_on_plane", "-t", "shadow_mapp"], "shadow_map"),
    (["sm_contact", "-t", "pcss"], "does not render for light 0"),
    (["box_on_plane", "--size", "3x3"], "--size"),
    (["box_on_plane", "--script", "bad.toml"], "step[0].key: must be one of"),
    (["box_on_plane", "--script", "missing.toml"], "cannot read"),
])
def test_bad_input_is_compares_one_line_before_any_window(tmp_path, monkeypatch, capsys, args, culprit):
    """In process: the arguments are refused before the display is looked at (there is none)."""
    from shadowlab.cli import main

    (tmp_path / "bad.toml").write_text('[[step]]\nkey = "tabb"\n')
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DISPLAY", raising=False)
    assert main(["view", *args]) == 2
    err = capsys.readouterr().err
    assert culprit in err and len(err.strip().splitlines()) == 1
