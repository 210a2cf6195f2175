#!/usr/bin/env bash
# The lab as a user installs it (issue 36): a wheel built from a clean copy of the tracked
# sources, installed (not editable) into a fresh venv outside the source tree, and the commands
# run from there — compare, tune, one tiny study, animate, a cost model fitted and used, the glTF
# scene and (under xvfb-run) a viewer screenshot. An editable install hides packaging mistakes
# (a package missing from the wheel broke every command of a plain install).
# Usage: tests/install_check/run.sh PYTHON   (make test passes the repository's .venv python)
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
python=${1:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "install check in $work"
mkdir "$work/src"
(cd "$repo" && git ls-files -z | xargs -0 -I{} cp --parents {} "$work/src/")
"$python" -m pip wheel --quiet --no-deps -w "$work/dist" "$work/src"
"$python" -m venv "$work/venv"
"$work/venv/bin/python" -m pip install --quiet --upgrade pip
wheel=$(ls "$work"/dist/shadowlab-*.whl)
"$work/venv/bin/python" -m pip install --quiet -c "$repo/constraints.txt" "$wheel[viewer]"
cp "$repo/tests/install_check/tiny.toml" "$work/tiny.toml"
cd "$work"   # outside the source tree: the installed package is what runs
lab="$work/venv/bin/shadowlab"
"$lab" --version
"$lab" compare box_on_plane -t shadow_map -t shadow_volume --size 160x120 --repeat 1 --out "$work/compare"
"$lab" tune sm_contact -t shadow_map --size 160x120 --out "$work/tune"
"$lab" study "$work/tiny.toml" --out "$work/study"
"$lab" animate tm_moving_caster -t shadow_map --frames 2 --size 96x72 --out "$work/animate"
"$lab" cost fit "$work/study" --out "$work/cost_model.json"
"$lab" cost predict "$work/study" "$work/cost_model.json"
# issue 41: the shipped glTF scene (package data: the .glb beside the TOML that includes it) and a preset
"$lab" compare gltf_blender_cube -t shadow_map:preset=godot --size 96x72 --repeat 1 --out "$work/gltf"
test -f "$work/compare/report.html" && test -f "$work/tune/best.json" && test -f "$work/study/study.html"
test -f "$work/animate/report.html" && test -f "$work/cost_model.json" && test -f "$work/gltf/report.html"
# the viewer (its extra, moderngl-window, installed with the wheel): one screenshot under Xvfb where there is one
if command -v xvfb-run >/dev/null; then
  xvfb-run -a "$lab" view gltf_blender_cube -t shadow_map --size 96x72 --screenshot "$work/view.png"
  test -f "$work/view.png"
  viewed="and the viewer"
else
  viewed="(not the viewer: no xvfb-run)"
fi
echo "install check: compare, tune, study, animate, cost, a glTF scene $viewed ran from the installed wheel"
