#!/usr/bin/env bash
# Fetch the wheels that blender_manifest.toml lists into ./wheels/ (unmodified, from PyPI),
# for Python 3.11 and 3.13 on every platform the manifest declares. Then build with
#   python <bpy>/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py build --source-dir . --output-dir dist
# (add --split-platforms for one smaller archive per platform).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
py="${PYTHON:-$here/.venv/bin/python}"
[ -x "$py" ] || py="$(command -v python3)"

packages=(embreex==4.4.0.post1 OpenEXR==3.5.3 tqdm==4.70.1)
# Oldest platform tag each target accepts; pip also takes older compatible tags
# (e.g. manylinux_2_17 under manylinux_2_28, macosx_11_0 under macosx_13_0).
platforms=(manylinux_2_28_x86_64 win_amd64 macosx_13_0_arm64 macosx_13_0_x86_64)
pythons=(3.11 3.13)

mkdir -p wheels
for pyver in "${pythons[@]}"; do
  for plat in "${platforms[@]}"; do
    echo "== Python $pyver, $plat"
    "$py" -m pip download --only-binary=:all: --no-deps \
      --python-version="$pyver" --platform="$plat" -d wheels "${packages[@]}"
  done
done
# pykdtree has no macOS 13 arm64 wheel: its macOS 14 one there.
for pyver in "${pythons[@]}"; do
  for plat in manylinux_2_28_x86_64 win_amd64 macosx_14_0_arm64 macosx_13_0_x86_64; do
    "$py" -m pip download --only-binary=:all: --no-deps --python-version="$pyver" --platform="$plat" \
      -d wheels pykdtree==1.4.3
  done
done
# tqdm needs colorama on Windows (pure Python, one wheel for all).
"$py" -m pip download --only-binary=:all: --no-deps -d wheels colorama==0.4.6

# Every wheel the manifest names must now be here.
missing=0
while read -r whl; do
  if [ ! -f "$whl" ]; then echo "missing: $whl" >&2; missing=1; fi
done < <(sed -n 's/^ *"\(\.\/wheels\/[^"]*\.whl\)".*/\1/p' blender_manifest.toml)
[ "$missing" = 0 ] && echo "all wheels listed in blender_manifest.toml are in ./wheels"
exit "$missing"
