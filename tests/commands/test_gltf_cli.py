"""glTF scenes on the command line (issue 41): a compare of a glTF file with its camera chosen
after '#', the file's notes in run.json and on the terminal; broken files exit 2 with one line."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from shadowlab.cli import main

FIXTURE = Path(__file__).parents[1] / "scene" / "gltf" / "fixture.gltf"


def test_compare_a_gltf_file_with_a_chosen_camera(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["compare", f"{FIXTURE}#B", "-t", "shadow_map", "--size", "64x48", "--repeat", "1",
                 "--warmup", "0", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    run = json.loads((out / "run.json").read_text())
    assert run["camera"]["eye"] == pytest.approx([8.0, 2.0, 0.0])
    assert [l["type"] for l in run["scene"]["lights"]] == ["spot", "point"]
    for what in ("skin", "morph targets", "KHR_materials_emissive_strength", "exposure 'auto'"):
        assert any(what in n for n in run["notes"]), what
        assert what in printed, what


@pytest.mark.parametrize("content,culprit", [
    (b"glTF\x02\x00\x00\x00\xff\xff\x00\x00", "glb: truncated"),
    (b"{ no", "json: not valid glTF JSON"),
])
def test_a_broken_gltf_file_exits_2_with_one_line(tmp_path, capsys, content, culprit):
    path = tmp_path / ("bad.glb" if content.startswith(b"glTF") else "bad.gltf")
    path.write_bytes(content)
    assert main(["compare", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and culprit in err and path.name in err
    assert not (tmp_path / "r").exists()


def test_an_unknown_camera_exits_2_with_one_line(tmp_path, capsys):
    assert main(["compare", f"{FIXTURE}#Nope", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no camera 'Nope'" in err and "0: A, 1: B, 2: Top" in err
