"""The built wheel holds the whole lab: every package of shadowlab/ (found, not listed: a package
left out of a hand-written list broke every command of a plain install, issue 36), the shaders,
the scenes and their meshes, the suites and the page templates. ``make test`` also installs the
wheel into a fresh venv outside the tree and runs the lab from there (Makefile, install-check)."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def wheel_names(tmp_path_factory) -> set[str]:
    """The file names in a wheel built from a clean copy of the tracked sources (an in-tree
    build/ left by an earlier build would be packaged again and hide a missing package)."""
    src, out = tmp_path_factory.mktemp("src"), tmp_path_factory.mktemp("wheel")
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, check=True, capture_output=True).stdout
    for name in filter(None, tracked.decode().split("\0")):
        if (ROOT / name).is_file():
            (src / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, src / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(out), str(src)],
                   check=True, capture_output=True)
    (whl,) = out.glob("shadowlab-*.whl")
    return set(zipfile.ZipFile(whl).namelist())


@pytest.mark.slow
def test_every_package_is_in_the_wheel(wheel_names):
    packages = sorted(p.parent.relative_to(ROOT).as_posix() for p in (ROOT / "shadowlab").rglob("__init__.py")
                      if "__pycache__" not in p.parts)
    assert "shadowlab/tuning" in packages
    missing = [p for p in packages if f"{p}/__init__.py" not in wheel_names]
    assert not missing, f"packages not in the wheel: {missing}"
    modules = [p.relative_to(ROOT).as_posix() for p in (ROOT / "shadowlab").rglob("*.py") if "__pycache__" not in p.parts]
    assert not [m for m in modules if m not in wheel_names]


@pytest.mark.slow
def test_the_data_files_are_in_the_wheel(wheel_names):
    """Shaders (beside their modules, in every package), scene files and meshes, suites
    (scaling/ too), page templates."""
    expected = [p.relative_to(ROOT).as_posix() for p in (ROOT / "shadowlab").rglob("*.glsl")]
    assert len(expected) > 30
    for folder, patterns in [("shadowlab/scenes", ["*.toml", "meshes/*"]), ("shadowlab/suites", ["*.toml", "scaling/*.toml"]),
                             ("shadowlab/output/templates", ["*"])]:
        for pattern in patterns:
            expected += [p.relative_to(ROOT).as_posix() for p in (ROOT / folder).glob(pattern) if p.is_file()]
    assert len(expected) > 100
    missing = [e for e in expected if e not in wheel_names]
    assert not missing, f"files not in the wheel: {missing[:10]}"
