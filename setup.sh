#!/usr/bin/env bash
# Set up .venv/ at the repo root with pinned dependencies, compile the kernels, then
# bake a sample scene (writes out/mirror.exr and out/mirror.json and prints statistics).
set -euo pipefail
cd "$(dirname "$0")"
PY="${PYTHON:-python3.11}"
if ! command -v "$PY" >/dev/null; then
  echo "setup.sh: needs Python 3.11 (bpy 5.0.1 is built for it); set PYTHON=/path/to/python3.11" >&2
  exit 2
fi
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --disable-pip-version-check -r requirements.txt
.venv/bin/python -m pip install -q --disable-pip-version-check --no-deps -e . 2>&1 | grep -v -e '^\s*$' -e '!!' -e 'WheelFile' || true
.venv/bin/python -c "import smbs_addon, testkit, bpy, embreex, OpenImageIO"
# compile the kernels now, in a process per core (once after installing or updating; cached on disk)
.venv/bin/python -m smbs_addon prepare
mkdir -p out
.venv/bin/python -m smbs_addon bake sample_blends/mirror.blend --method smbs --spp 16 --seed 1 \
  --out out/mirror.exr --stats out/mirror.json
