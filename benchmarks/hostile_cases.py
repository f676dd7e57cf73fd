"""The cases of issue 17 (hostile and odd inputs): exit code, wall time and peak memory of each (not a test).

Run from the repository root:
    .venv/bin/python benchmarks/hostile_cases.py [--code DIR] [--json OUT.json] [--only ID ...]
    .venv/bin/python benchmarks/hostile_cases.py compare BEFORE.json[,MORE.json] AFTER.json   # the two side by side

Each case is made in a fresh temporary folder and run as the real CLI in a
fresh process (``python -c "from cli.app import main; main()" ...``) with the
code found under ``--code`` (default: this checkout), so the same script
measures an older checkout (``git archive <commit> | tar -x -C DIR``) and this
one. Peak memory is the largest sum of RSS over the CLI's process tree, polled
every 20 ms (and never below the CLI's own ``ru_maxrss``). A case is stopped
when its tree passes ``--rss-cap-mb`` (default 4096, so the shared machine
survives the old behaviour) or ``--timeout-s`` (default 60): the table then
says ``killed: RSS cap`` or ``killed: timeout`` instead of an exit code.

The table is printed as Markdown (one row per case: id, exit, time, peak RSS,
stderr lines, and the first ``error:``/``failed`` line of stderr, else its last
line, shortened).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import psutil

REPO = Path(__file__).resolve().parents[1]

_BOX_OBJ = "\n".join(
    ["o box"]
    + [f"v {x} {y} {z}" for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    + ["f 1 3 4 2", "f 5 6 8 7", "f 1 2 6 5", "f 3 7 8 4", "f 1 5 7 3", "f 2 4 8 6"]
) + "\n"


def _icosphere_obj(subdivisions: int = 2) -> str:
    """An ordinary closed mesh (a sphere of 320 triangles), as OBJ text."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.5)
    lines = ["o sphere"] + [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in sphere.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in sphere.faces]
    return "\n".join(lines) + "\n"


def _recipe(source: str, *, extra: str = "", detailizer: str = "upsample", name: str = "a",
            regions: str = "[{part: body, style: brick}]") -> str:
    return (f"version: 1\nassets:\n  - name: {name}\n    source: {source}\n    regions: {regions}\n"
            f"    detailize: {{detailizer: {detailizer}}}\n{extra}")


@dataclass
class Case:
    id: str
    what: str
    setup: Callable[[Path], list[str]]  # makes the files in the folder, returns the CLI arguments
    expect: str = ""  # what the issue asks for
    env: dict = field(default_factory=dict)
    prelude: str = ""  # Python run before the CLI (e.g. to hide a package)


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _mesh_recipe(folder: Path, extra_source: str = "", grid: str = "", detailizer: str = "upsample") -> Path:
    _write(folder, "sphere.obj", _icosphere_obj())
    extra = f"    grid: {grid}\n" if grid else ""
    regions = "[{part: body, style: tower}]" if detailizer == "decollage" else "[{part: body, style: brick}]"
    return _write(folder, "r.yaml", _recipe(f"{{kind: mesh, path: sphere.obj{extra_source}}}", extra=extra,
                                             detailizer=detailizer, regions=regions))


def case_dev_zero(d: Path) -> list[str]:
    return ["build", "/dev/zero", "-o", str(d / "out")]


def case_alias_bomb(d: Path) -> list[str]:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 10):
        lines.append(f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]")
    lines.append("version: 1")
    lines.append("assets: [{name: a, source: {kind: text, text: A}, regions: [{part: body, style: brick}], "
                 "detailize: {detailizer: upsample}}]")
    r = _write(d, "bomb.yaml", "\n".join(lines) + "\n")
    return ["build", str(r), "-o", str(d / "out")]


def case_variants_500k(d: Path) -> list[str]:
    words = "[" + ",".join(f"w{i}" for i in range(100)) + "]"
    seeds = "[" + ",".join(str(i) for i in range(100)) + "]"
    lines = ["version: 1", "assets:"]
    for a in range(50):
        lines.append(f"  - name: v{a}\n    variants: {{word: {words}, seed: {seeds}}}\n"
                     f"    source: {{kind: text, text: '${{word}}'}}\n"
                     f"    regions: [{{part: body, style: brick}}]\n"
                     f"    detailize: {{detailizer: upsample, seed: '${{seed}}'}}")
    r = _write(d, "big.yaml", "\n".join(lines) + "\n")
    return ["build", str(r), "-o", str(d / "out")]


def case_resolution_64(d: Path) -> list[str]:
    r = _mesh_recipe(d, grid="{resolution: 64}", detailizer="decollage")
    return ["build", str(r), "-o", str(d / "out")]


def case_deep_yaml(d: Path) -> list[str]:
    depth = 3000
    r = _write(d, "deep.yaml", "version: 1\nassets: " + "[" * depth + "]" * depth + "\n")
    return ["build", str(r), "-o", str(d / "out")]


def case_deep_yaml_maps(d: Path) -> list[str]:
    depth = 3000
    r = _write(d, "deepmap.yaml", "version: 1\nextra: " + "{a: " * depth + "1" + "}" * depth + "\n")
    return ["build", str(r), "-o", str(d / "out")]


def case_cad_deep(d: Path) -> list[str]:
    node = "{shape: box, size: [1, 1, 1]}"
    for _ in range(450):
        node = "{shape: union, children: [" + node + "]}"
    top = node.replace("{shape: union,", "{shape: union, name: tower,", 1)
    r = _write(d, "cad.yaml", _recipe(f"{{kind: cad, parts: [{top}]}}"))
    return ["build", str(r), "-o", str(d / "out")]


def _voxels(folder: Path) -> Path:
    import numpy as np

    grid = np.zeros((8, 8, 8), dtype=np.uint8)
    grid[2:6, 0:6, 2:6] = 1
    np.save(folder / "g.npy", grid)
    return _write(folder, "r.yaml", _recipe("{kind: voxels, path: g.npy}"))


def case_out_cache_is_file(d: Path) -> list[str]:
    r = _voxels(d)
    (d / "out").mkdir()
    (d / "out" / ".decollage").write_text("not a folder")
    return ["build", str(r), "-o", str(d / "out")]


def case_manifest_is_dir(d: Path) -> list[str]:
    r = _voxels(d)
    (d / "out" / "manifest.json").mkdir(parents=True)
    return ["build", str(r), "-o", str(d / "out")]


_MOUNTS: list[Path] = []


def case_cache_read_only(d: Path) -> list[str]:
    """The cache folder read-only: a read-only bind mount (root ignores permission bits), else chmod 555."""
    r = _voxels(d)
    cache = d / "out" / ".decollage"
    cache.mkdir(parents=True)
    cache.chmod(0o555)
    if os.geteuid() == 0:
        bound = subprocess.run(["mount", "--bind", str(cache), str(cache)], capture_output=True).returncode == 0
        if bound:
            _MOUNTS.append(cache)
            subprocess.run(["mount", "-o", "remount,ro,bind", str(cache)], capture_output=True)
    return ["build", str(r), "-o", str(d / "out")]


def _script(d: Path, body: str) -> Path:
    _write(d, "tower.py", "import os, sys\n\ndef build():\n" + "".join(f"    {line}\n" for line in body.splitlines()))
    return _write(d, "r.yaml", _recipe("{kind: cad, script: tower.py}"))


def case_script_os_exit(d: Path) -> list[str]:
    return ["build", str(_script(d, "os._exit(0)")), "-o", str(d / "out")]


def case_script_sys_exit(d: Path) -> list[str]:
    return ["build", str(_script(d, "sys.exit(0)")), "-o", str(d / "out")]


#: --old-schema: leave out recipe fields the old code does not know (script_timeout_s).
OLD_SCHEMA = False


def case_script_loop(d: Path) -> list[str]:
    _write(d, "tower.py", "def build():\n    while True:\n        pass\n")
    timeout = "" if OLD_SCHEMA else ", script_timeout_s: 5"
    r = _write(d, "r.yaml", _recipe(f"{{kind: cad, script: tower.py{timeout}}}"))
    return ["build", str(r), "-o", str(d / "out")]


def case_scale_1e30(d: Path) -> list[str]:
    return ["build", str(_mesh_recipe(d, ", scale: 1.0e+30")), "-o", str(d / "out")]


def case_scale_1e_30(d: Path) -> list[str]:
    return ["build", str(_mesh_recipe(d, ", scale: 1.0e-30")), "-o", str(d / "out")]


def _sparse(path: Path, size: int) -> Path:
    with open(path, "wb") as f:
        f.truncate(size)
    return path


def case_sparse_mesh(d: Path) -> list[str]:
    _sparse(d / "huge.stl", 2 << 30)
    r = _write(d, "r.yaml", _recipe("{kind: mesh, path: huge.stl}"))
    return ["build", str(r), "-o", str(d / "out")]


def case_sparse_recipe(d: Path) -> list[str]:
    return ["build", str(_sparse(d / "huge.yaml", 2 << 30)), "-o", str(d / "out")]


def case_seed_2_64(d: Path) -> list[str]:
    r = _write(d, "r.yaml", _recipe("{kind: text, text: A}").replace(
        "{detailizer: upsample}", "{detailizer: upsample, seed: 18446744073709551616}"))
    return ["build", str(r), "-o", str(d / "out")]


def case_scale_1e_3(d: Path) -> list[str]:
    return ["validate", str(_mesh_recipe(d, ", scale: 1e-3"))]


def case_size_1e12(d: Path) -> list[str]:
    return ["validate", str(_write(d, "r.yaml", _recipe("{kind: text, text: A, size_m: 1e12}")))]


def case_scale_inf(d: Path) -> list[str]:
    return ["build", str(_mesh_recipe(d, ", scale: .inf")), "-o", str(d / "out")]


def case_validate_missing_glyphs(d: Path) -> list[str]:
    return ["validate", str(_write(d, "r.yaml", _recipe("{kind: text, text: '漢字'}")))]


def case_arabic(d: Path) -> list[str]:
    r = _write(d, "r.yaml", _recipe("{kind: text, text: 'سلام'}"))
    return ["build", str(r), "-o", str(d / "out")]


def case_checkpoint_random(d: Path) -> list[str]:
    (d / "junk.pt").write_bytes(os.urandom(4096))
    r = _write(d, "r.yaml", _recipe("{kind: text, text: A}", regions="[{part: body, style: tower}]").replace(
        "{detailizer: upsample}", "{detailizer: decollage, checkpoint: junk.pt}"))
    return ["build", str(r), "-o", str(d / "out")]


def case_dask_hint(d: Path) -> list[str]:
    r = _voxels(d)
    return ["build", str(r), "-o", str(d / "out"), "--executor", "dask", "--address", "tcp://127.0.0.1:1"]


def case_engine_profile_noise(d: Path) -> list[str]:
    r = _mesh_recipe(d, detailizer="decollage").read_text()
    r = r + "    export: {profile: unreal, lods: [1.0, 0.5, 0.25], collision: hull, formats: [glb, obj]}\n"
    return ["build", str(_write(d, "r.yaml", r)), "-o", str(d / "out")]


CASES = [
    Case("recipe_dev_zero", "a recipe path that is /dev/zero", case_dev_zero, "exit 2"),
    Case("yaml_alias_bomb", "a YAML alias bomb (9 levels of 9) at the top level", case_alias_bomb, "exit 2"),
    Case("variants_500k", "a variant matrix of 500,000 assets (50 assets x 100 x 100)", case_variants_500k, "exit 2"),
    Case("mesh_resolution_64", "grid.resolution: 64 on an ordinary mesh (1024^3 fine grid)", case_resolution_64,
         "exit 1"),
    Case("yaml_deep_lists", "lists nested 3,000 levels deep", case_deep_yaml, "exit 2"),
    Case("yaml_deep_maps", "maps nested 3,000 levels deep", case_deep_yaml_maps, "exit 2"),
    Case("cad_boolean_450", "a CAD boolean tree nested 450 levels", case_cad_deep, "exit 2"),
    Case("out_cache_is_file", "out/.decollage exists as a file", case_out_cache_is_file, "exit 2, nothing written"),
    Case("out_cache_read_only", "out/.decollage is read-only (a read-only bind mount)", case_cache_read_only,
         "exit 2, nothing written"),
    Case("out_manifest_is_dir", "out/manifest.json is a directory", case_manifest_is_dir, "exit 2, nothing written"),
    Case("script_os_exit", "a CAD script whose build() calls os._exit(0)", case_script_os_exit, "exit 1"),
    Case("script_sys_exit", "a CAD script whose build() calls sys.exit(0)", case_script_sys_exit, "exit 1"),
    Case("script_endless_loop", "a CAD script that never returns (script_timeout_s: 5; not set with --old-schema)",
         case_script_loop, "exit 1"),
    Case("mesh_scale_1e30", "scale: 1.0e+30 on a mesh", case_scale_1e30, "exit 2"),
    Case("mesh_scale_1e-30", "scale: 1.0e-30 on a mesh", case_scale_1e_30, "exit 2"),
    Case("mesh_sparse_2gb", "a 2 GB sparse file as a mesh", case_sparse_mesh, "exit 1 or 2"),
    Case("recipe_sparse_2gb", "a 2 GB sparse file as a recipe", case_sparse_recipe, "exit 2"),
    Case("seed_2_64", "detailize: {seed: 18446744073709551616}", case_seed_2_64, "exit 2"),
    Case("scale_1e-3", "scale: 1e-3 (validate)", case_scale_1e_3, "exit 0: a YAML 1.2 number"),
    Case("size_m_1e12", "size_m: 1e12 (validate)", case_size_1e12, "exit 2: out of range"),
    Case("scale_inf", "scale: .inf on a mesh", case_scale_inf, "exit 2"),
    Case("validate_missing_glyphs", "validate text the font lacks (漢字, DejaVu)", case_validate_missing_glyphs,
         "exit 2"),
    Case("text_arabic", "Arabic text (سلام)", case_arabic, "exit 0, shaped right to left"),
    Case("checkpoint_random", "4 KB of random bytes as a checkpoint", case_checkpoint_random,
         "exit 2, 'not a torch file'"),
    Case("dask_hint", "--executor dask without the distributed package", case_dask_hint,
         "exit 2, hint names the cluster extra", prelude="import sys; sys.modules['distributed'] = None"),
    Case("engine_profile_noise", "an unreal-profile GLB with LODs and collision (stderr lines)",
         case_engine_profile_noise, "exit 0, no raw warnings"),
]


def _tree_rss(proc: psutil.Process) -> int:
    total = 0
    try:
        procs = [proc, *proc.children(recursive=True)]
    except psutil.Error:
        return 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except psutil.Error:
            pass
    return total


def run_case(case: Case, code: Path, timeout_s: float, rss_cap_mb: float) -> dict:
    with tempfile.TemporaryDirectory(prefix=f"hostile-{case.id}-") as tmp:
        folder = Path(tmp)
        args = case.setup(folder)
        program = (f"{case.prelude}\nimport sys\nsys.argv = ['decollage', *sys.argv[1:]]\n"
                   "from cli.app import main\nmain()\n")
        env = {**os.environ, "PYTHONPATH": str(code), "PYTHONUNBUFFERED": "1", **case.env}
        stderr_path = folder / "stderr.txt"
        started = time.perf_counter()
        with open(stderr_path, "wb") as err, open(os.devnull, "wb") as out:
            popen = subprocess.Popen([sys.executable, "-c", program, *args], cwd=folder, env=env, stdout=out,
                                     stderr=err, start_new_session=True)
            proc = psutil.Process(popen.pid)
            peak, outcome = 0, None
            while True:
                try:
                    _, status, usage = os.wait4(popen.pid, os.WNOHANG)
                except ChildProcessError:
                    break
                if _ != 0:
                    popen.returncode = os.waitstatus_to_exitcode(status)
                    peak = max(peak, usage.ru_maxrss * 1024)
                    break
                peak = max(peak, _tree_rss(proc))
                elapsed = time.perf_counter() - started
                if peak > rss_cap_mb * 2**20 or elapsed > timeout_s:
                    outcome = "killed: RSS cap" if peak > rss_cap_mb * 2**20 else "killed: timeout"
                    os.killpg(popen.pid, signal.SIGKILL)
                    os.waitpid(popen.pid, 0)
                    break
                time.sleep(0.02)
        wall = time.perf_counter() - started
        while _MOUNTS:
            subprocess.run(["umount", str(_MOUNTS.pop())], capture_output=True)
        try:
            os.killpg(popen.pid, signal.SIGKILL)  # anything the CLI left behind
        except ProcessLookupError:
            pass
        lines = [ln for ln in stderr_path.read_text(encoding="utf-8", errors="replace").splitlines() if ln.strip()]
        # The line that says what went wrong: the first error or failed asset, else the last line.
        message = next((ln for ln in lines if ln.startswith(("error:", "failed ", "internal error"))),
                       lines[-1] if lines else "")
        out_dir = folder / "out"
        files = sorted(str(p.relative_to(out_dir)) for p in out_dir.rglob("*") if p.is_file()) \
            if out_dir.is_dir() else []
        for p in out_dir.rglob("*") if out_dir.is_dir() else ():
            if p.is_dir():
                p.chmod(0o755)  # let the temporary folder be removed
        return {
            "id": case.id, "what": case.what, "expect": case.expect,
            "exit": outcome or popen.returncode, "time_s": round(wall, 2), "peak_rss_mb": round(peak / 2**20),
            "stderr_lines": len(lines), "message": message, "out_files": files,
        }


def compare(before_files: list[Path], after_files: list[Path]) -> str:
    """A Markdown table of each case before and after, from result files (later files override earlier ones)."""
    def load(files: list[Path]) -> dict:
        merged: dict = {}
        for path in files:
            merged.update({r["id"]: r for r in json.loads(path.read_text(encoding="utf-8"))["results"]})
        return merged

    before, after = load(before_files), load(after_files)
    rows = ["| case | before: exit | time (s) | peak RSS (MB) | files in out/ | after: exit | time (s) | peak RSS (MB) "
            "| files in out/ | after: message |", "|---|---|---|---|---|---|---|---|---|---|"]
    for case in CASES:
        b, a = before.get(case.id), after.get(case.id)
        if not (b and a):
            continue
        message = a.get("message", a.get("last_line", "")).replace("|", "\\|")
        message = message if len(message) <= 160 else message[:159] + "…"
        files = (lambda r: ", ".join(r.get("out_files", [])) or "-")
        rows.append(f"| {case.id} | {b['exit']} | {b['time_s']} | {b['peak_rss_mb']} | {files(b)} | {a['exit']} "
                    f"| {a['time_s']} | {a['peak_rss_mb']} | {files(a)} | {message} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    if argv[:1] == ["compare"]:  # compare BEFORE.json[,MORE.json] AFTER.json[,MORE.json]
        print(compare([Path(p) for p in argv[1].split(",")], [Path(p) for p in argv[2].split(",")]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--code", type=Path, default=REPO, help="checkout whose code runs (default: this one)")
    parser.add_argument("--json", type=Path, help="also write the results as JSON")
    parser.add_argument("--only", nargs="*", help="case ids to run")
    parser.add_argument("--timeout-s", type=float, default=60.0)
    parser.add_argument("--rss-cap-mb", type=float, default=4096.0)
    parser.add_argument("--old-schema", action="store_true",
                        help="leave out recipe fields older code does not know (script_timeout_s)")
    args = parser.parse_args(argv)
    global OLD_SCHEMA
    OLD_SCHEMA = args.old_schema
    results = []
    for case in CASES:
        if args.only and case.id not in args.only:
            continue
        result = run_case(case, args.code.resolve(), args.timeout_s, args.rss_cap_mb)
        results.append(result)
        print(json.dumps(result, ensure_ascii=False), file=sys.stderr, flush=True)
    machine = f"{platform.machine()}, {os.cpu_count()} cores, {psutil.virtual_memory().total / 2**30:.0f} GiB"
    print(f"code: {args.code.resolve()}  machine: {machine}\n")
    print("| case | exit | time (s) | peak RSS (MB) | stderr lines | message (first error line, else last line) |")
    print("|---|---|---|---|---|---|")
    for r in results:
        last = r["message"].replace("|", "\\|")
        last = last if len(last) <= 140 else last[:139] + "…"
        print(f"| {r['id']} | {r['exit']} | {r['time_s']} | {r['peak_rss_mb']} | {r['stderr_lines']} | {last} |")
    if args.json:
        args.json.write_text(json.dumps({"code": str(args.code.resolve()), "machine": machine, "results": results},
                                        indent=1, ensure_ascii=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
