#!/usr/bin/env bash
# Packs what a bare GPU machine lacks for benchmarks/gpu_check.py (docs/gpu_check.md): cp312 manylinux wheels of
# gsplat and of sagebench's dependencies a GPU image lacks (one with gpu_check.IMAGE_HAS) into .whl/, and the demo run's files the check reads
# into .gpu_check/demo_run.tgz (DEMO, default out/demo, made with `sagebench demo` first when missing).
# Usage: bash benchmarks/gpu_pack.sh [DEMO]
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
DEMO=${1:-out/demo}
[ -f "$DEMO/manifest.json" ] || "$PY" -m sagebench -q demo --out "$DEMO"
pin() { grep -i "^$1==" constraints.txt; }
rm -rf .whl && "$PY" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_24_x86_64 \
  --platform manylinux_2_17_x86_64 \
  --platform manylinux2014_x86_64 -d .whl "gsplat==1.5.3" "$(pin mujoco)" "$(pin mujoco-core)" "$(pin glfw)" \
  "$(pin pydantic)" "$(pin pydantic_core)" "$(pin annotated-types)" "$(pin typing-inspection)" "$(pin platformdirs)" \
  "$(pin shapely)"
mkdir -p .gpu_check && (cd "$DEMO" && tar czf - scenes/*/scene.json scenes/*/topdown.npz scenes/*/gaussians.ply \
  scenes/*/scene.xml scenes/*/colliders episodes) > .gpu_check/demo_run.tgz
du -sh .whl .gpu_check
