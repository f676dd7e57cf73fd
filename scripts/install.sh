#!/usr/bin/env bash
# Set up (or update) the project's virtual environment in .venv.
#   bash scripts/install.sh            runtime only
#   bash scripts/install.sh test       runtime + test tools + the cadquery runtime (so the
#                                      tests also prove that the optional cadquery install works)
#                                      + Debian's chromium for the studio's browser tests (apt-get, as root)
#   bash scripts/install.sh cadquery   the optional cadquery runtime in .venv-cadquery
#   bash scripts/install.sh exemplars  runtime + pybullet (103 MB wheel): its pybullet_data holds the
#                                      model the 'monastery' style set is read from; and the Debian
#                                      package sweethome3d-furniture (120 MB, no dependencies; apt-get,
#                                      as root) the 'sweethome' set is read from
# torch is installed first and pinned, so pip takes the local CPU build
# instead of pulling a multi-GB CUDA build; constraints.txt pins the rest.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"

if [ "${1:-}" = "cadquery" ]; then
    exec bash scripts/install_cadquery.sh
fi

# Drop two kinds of known noise, keep the exit status: this machine's pip
# config lists local indexes that may not exist, and the OCP wheel's bundled
# fontconfig warns about a config element it does not know.
quiet() { "$@" 2> >(grep -v -e "is ignored: it is neither" -e "Fontconfig warning" >&2); }

if [ ! -x .venv/bin/python ]; then
    "$PYTHON" -m venv .venv
fi
export PIP_DISABLE_PIP_VERSION_CHECK=1
quiet .venv/bin/python -m pip install --quiet --upgrade pip
quiet .venv/bin/python -m pip install --quiet -c constraints.txt "torch==2.13.0"
extra=""
if [ "${1:-}" = "test" ]; then extra="[test]"; fi
if [ "${1:-}" = "exemplars" ]; then extra="[exemplars]"; fi
quiet .venv/bin/python -m pip install --quiet -c constraints.txt -e ".${extra}"
if [ "${1:-}" = "exemplars" ] && [ ! -d /usr/share/sweethome3d/furniture ]; then
    if command -v apt-get >/dev/null && [ "$(id -u)" = "0" ]; then
        apt-get update -qq && apt-get install -y -qq sweethome3d-furniture
    else
        echo "the 'sweethome' style set needs the Debian package sweethome3d-furniture:" \
             "run: sudo apt-get install -y sweethome3d-furniture" >&2
    fi
fi
# The studio's WebGL library (three.js, pinned by studio/web/package-lock.json), served by 'decollage view' and
# 'decollage paint' from this checkout: the pages never load anything from a CDN.
if command -v npm >/dev/null; then
    npm ci --silent --no-audit --no-fund --prefix studio/web
else
    echo "npm not found: 'decollage view' and 'paint' need three.js: install Node.js and npm, then run" \
         "npm ci --prefix studio/web" >&2
fi
# pip's resolver cannot see every conflict (ecosystem.md §1.1): prove the stack imports.
quiet .venv/bin/python -c "import build123d, trimesh, torch, skimage, fast_simplification, meshoptimizer, fontTools, uharfbuzz, shapely, cli.app; print('decollage environment ready: torch', torch.__version__, '| build123d', build123d.__version__)"
if [ "${1:-}" = "test" ]; then
    if [ ! -x .venv-cadquery/bin/python ]; then
        bash scripts/install_cadquery.sh
    fi
    # The studio's browser tests drive the distribution's Chromium with playwright (never a downloaded browser).
    if [ ! -x /usr/bin/chromium ]; then
        if command -v apt-get >/dev/null && [ "$(id -u)" = "0" ]; then
            apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null
        else
            echo "the studio's browser tests need Debian's Chromium: run: sudo apt-get install -y chromium" \
                 "chromium-driver (without it they are skipped, and fail under CI=true)" >&2
        fi
    fi
    # The Khronos glTF validator checks every GLB the tests write (npm, pinned in tools/gltf).
    if command -v npm >/dev/null; then
        npm ci --silent --no-audit --no-fund --prefix tools/gltf
    else
        echo "npm not found: the glTF validator tests will be skipped" >&2
    fi
fi
