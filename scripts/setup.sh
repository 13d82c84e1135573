#!/usr/bin/env bash
# Install what the tests need on a fresh Debian machine: libclang (bindgen for Embree),
# Blender and numpy (the Blender import check), Xvfb (EEVEE renders need an OpenGL context:
# scripts/blender-render.sh runs Blender under xvfb-run), Node.js (the Khronos glTF-Validator),
# Debian's chromium and the npm packages of scripts/package.json (three.js, Babylon.js, Spark,
# puppeteer-core: the browser viewer checks, scripts/web-render.mjs and scripts/splat-render.mjs),
# and Embree 4 from the PyPI wheel `embreex` (scripts/get-embree.sh). Idempotent: what is
# there already is left alone.
set -euo pipefail
cd "$(dirname "$0")/.."

need=()
installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
# blender: the import check; python3-numpy: Debian's Blender 3.4 importer needs it;
# libclang-dev: bindgen in embree4-sys (headers included, not just the runtime library);
# xvfb, xauth: a virtual display (software GL) for EEVEE (`xvfb-run` needs xauth);
# chromium: headless software-GL browser for the three.js / Babylon.js viewer check;
# python3-venv: the Python package's test environment (target/py-venv).
for pkg in blender python3-numpy python3-venv libclang-dev unzip xvfb xauth chromium; do
  installed "$pkg" || need+=("$pkg")
done
command -v node >/dev/null 2>&1 || need+=(nodejs npm)
if ((${#need[@]})); then
  if [ "$(id -u)" = 0 ]; then
    echo "setup: installing ${need[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
  else
    echo "setup: please install: ${need[*]} (apt-get needs root)" >&2
    exit 1
  fi
fi

if [ -x scripts/get-embree.sh ]; then
  scripts/get-embree.sh
fi

# The glTF-Validator installs itself into ~/.cache/gltf-validator on first use; warm it here
# so a failure to reach the npm registry shows up as a setup error, not a test failure.
dir=${GLTF_VALIDATOR_DIR:-$HOME/.cache/gltf-validator}
if [ ! -f "$dir/node_modules/gltf-validator/package.json" ]; then
  mkdir -p "$dir"
  (cd "$dir" && { [ -f package.json ] || npm init -y >/dev/null; } && npm install --silent --no-audit --no-fund gltf-validator@2.0.0-dev.3.10 >/dev/null)
fi
# The viewer check's npm packages (pinned in scripts/package.json) go to a cache folder, not
# the repository; reinstalled when the pinned versions change.
web=${SPLATBRIDGE_WEB_DIR:-$HOME/.cache/splatbridge-web}
if ! cmp -s scripts/package.json "$web/package.json" || [ ! -f "$web/node_modules/three/package.json" ] \
  || [ ! -f "$web/node_modules/@sparkjsdev/spark/package.json" ]; then
  mkdir -p "$web"
  cp scripts/package.json "$web/package.json"
  (cd "$web" && npm install --silent --no-audit --no-fund >/dev/null)
fi
echo "setup: done"
