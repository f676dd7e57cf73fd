#!/usr/bin/env bash
# Create the optional cadquery runtime: a separate venv used only to run
# cadquery recipe scripts (sources/script_runner.py runs inside it).
#
# Why a separate venv: cadquery 2.8 needs OCP 7.9.x, build123d 0.13 (the main
# environment) needs OCP 8.0.x; both write the same `OCP/` package, so they
# cannot share one venv (see docs / ecosystem notes). The main process finds
# this interpreter through $DECOLLAGE_CADQUERY_PYTHON or <repo>/.venv-cadquery.
#
# Usage: bash scripts/install_cadquery.sh [VENV_DIR]   (default: <repo>/.venv-cadquery)
#        PYTHON=python3.11 bash scripts/install_cadquery.sh   to pick the base interpreter
set -euo pipefail

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv_dir="${1:-$repo_root/.venv-cadquery}"
base_python="${PYTHON:-python3}"
cadquery_version="2.8.0"
export PIP_DISABLE_PIP_VERSION_CHECK=1
# Drop known noise (this machine's pip config lists local indexes that may not
# exist; OCP's bundled fontconfig warns on import), keep the exit status.
quiet() { "$@" 2> >(grep -v -e "is ignored: it is neither" -e "Fontconfig warning" >&2); }

echo "creating $venv_dir with $($base_python --version 2>&1)"
"$base_python" -m venv "$venv_dir"
quiet "$venv_dir/bin/python" -m pip install --quiet --upgrade pip
# cadquery 2.8.0 with the OCP build it was checked with; nothing else goes into this venv.
quiet "$venv_dir/bin/python" -m pip install --quiet "cadquery==$cadquery_version" "cadquery-ocp==7.9.3.1.1"

# pip check does not catch a broken OCP install; only an import does.
quiet "$venv_dir/bin/python" -c "import cadquery; v = cadquery.Workplane().box(1, 1, 1).val().Volume(); assert abs(v - 1) < 1e-9, v; print('cadquery', cadquery.__version__, 'OK')"

echo "cadquery runtime ready: $venv_dir/bin/python"
echo "(decollage finds it there automatically; elsewhere set DECOLLAGE_CADQUERY_PYTHON=$venv_dir/bin/python)"
