"""Seeded fuzzing of recipes, in process: thousands of mutated recipes through the real CLI, never an internal error.

The corpus is the repository's own recipes (``recipes/*.yaml``, with their
input files) plus a CAD recipe and a variant matrix. Each of ``COUNT``
iterations takes a corpus recipe and applies one to three mutations chosen by a
``random.Random(SEED)``: structure-aware ones on the parsed data (a leaf
replaced by a hostile value, a key deleted or added, a subtree swapped,
duplicated, wrapped or nested hundreds deep, a variant matrix of random size)
or text-level ones on the YAML (characters flipped, inserted or deleted,
truncation, alias bombs, tabs, NUL and BOM). The result goes through
``cli.app.main`` in this process: ``decollage validate`` (and every tenth time
``decollage build --list``). The test asserts that every run ends with exit
0, 1 or 2 (never 3, "internal error"), that nothing but ``SystemExit`` leaves
``main``, and that no run takes more than ``MAX_SECONDS``.
"""

from __future__ import annotations

import copy
import random
import shutil
import sys
import time
from pathlib import Path

import pytest
import yaml

from cli.app import main
from core.recipe_loader import json_schema

pytestmark = pytest.mark.e2e  # 2,000 CLI runs in this process: about a minute

SEED = 20_240_617
COUNT = 2_000
MAX_SECONDS = 5.0
REPO = Path(__file__).resolve().parents[1]

_EXTRA_CORPUS = {
    "cad.yaml": """version: 1
assets:
  - name: tower
    source:
      kind: cad
      units: mm
      parts:
        - {name: body, shape: difference, children: [{shape: box, size: [40, 40, 80]},
                                                       {shape: cylinder, radius: 8, height: 30, at: [0, 0, 60]}]}
        - {name: roof, shape: cone, radius_bottom: 30, height: 30, at: [0, 0, 80]}
        - {name: flag, shape: extrude, profile: [[0, 0], [10, 0], [0, 6]], height: 1, at: [0, 0, 110]}
    grid: {resolution: 12}
    regions: [{parts: [body], part: body, style: tower}, {parts: [roof, flag], part: roof, style: tower}]
    detailize: {detailizer: upsample, seed: 3}
    export: {formats: [glb, obj], profile: unity, lods: [1.0, 0.5], collision: hull}
""",
    "variants.yaml": """version: 1
defaults: {grid: {resolution: 10}, export: {max_triangles: 2000}}
assets:
  - name: word
    variants: {text: [ORC, ELF], style: [tower, druse], seed: [0, 1]}
    name_template: "{asset}_{text}_{style}_{seed}"
    source: {kind: text, text: "${text}", size_m: 0.3, letter_spacing: 0.1}
    regions: [{part: body, style: "${style}"}, {band: top, part: top, style: "${style}"}]
    detailize: {seed: "${seed}"}
""",
}

_HOSTILE_VALUES = [
    0, -1, 1, 2**31, 2**64, -(2**63), 10**400, 1e308, -1e308, 5e-324, 1e-3, 1e12, float("inf"), float("-inf"),
    float("nan"), True, False, None, "", " ", "x" * 5000, "../../../../etc/passwd", "/dev/zero", "/proc/self/mem",
    "~", ".", "inputs", "inputs/cottage.glb", "inputs/mushroom.npz", "recipe.yaml", "${seed}", "${nope}", "@source",
    "glyph_*", "[", "{", "\u202eevil", "漢字", "سلام", "abc שלום", "क्ष", "e\u0301", "\x00", "\t", "\ufeff", "0x10",
    "1e-3", "yes", "NO", "2024-01-01", [], {}, [[]], [[[[[]]]]], {"a": {"b": {}}}, [1, 2, 3], [1.0, 0.5, 0.25],
    [0.0, 0.0, 0.0], [1e30, 1e30, 1e30], [-1, -1, -1], ["a"] * 50, list(range(300)),
]


def _schema_keys() -> list[str]:
    keys: set[str] = set()
    stack: list = [json_schema()]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            keys.update(k for k in node.get("properties", {}) if isinstance(k, str))
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
    return sorted(keys)


def _paths(data, prefix=()) -> list[tuple]:
    """Every (container, key) location in the data, iteratively."""
    out, stack = [], [(data, prefix)]
    while stack:
        node, path = stack.pop()
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for key, value in items:
            out.append((node, key))
            stack.append((value, path + (key,)))
    return out


class Mutator:
    def __init__(self, rng: random.Random, keys: list[str]) -> None:
        self.rng, self.keys = rng, keys

    def value(self):
        rng = self.rng
        roll = rng.random()
        if roll < 0.6:
            return rng.choice(_HOSTILE_VALUES)
        if roll < 0.75:
            return rng.uniform(-1e6, 1e6) * 10 ** rng.randint(-40, 40)
        if roll < 0.9:
            return "".join(chr(rng.choice([rng.randint(32, 126), rng.randint(0x80, 0x2FFF), rng.randint(0, 31)]))
                           for _ in range(rng.randint(0, 40)))
        return {rng.choice(self.keys): rng.choice(_HOSTILE_VALUES)}

    def structural(self, data) -> object:
        rng = self.rng
        places = _paths(data)
        if not places:
            return self.value()
        node, key = rng.choice(places)
        op = rng.randrange(9)
        if op == 0:
            node[key] = self.value()
        elif op == 1 and isinstance(node, dict):
            del node[key]
        elif op == 2 and isinstance(node, dict):
            node[rng.choice(self.keys)] = self.value()
        elif op == 3:
            other_node, other_key = rng.choice(places)
            node[key] = copy.deepcopy(other_node[other_key])  # a subtree from elsewhere (often the wrong type)
        elif op == 4 and isinstance(node, list):
            node.append(copy.deepcopy(node[key]))  # duplicate (e.g. two assets of one name)
        elif op == 5:
            node[key] = [node[key]] if rng.random() < 0.5 else {rng.choice(self.keys): node[key]}
        elif op == 6:
            deep = node[key]
            for _ in range(rng.choice([5, 40, 60, 110])):  # deeper: textual (the fuzzer's dumper recurses)
                deep = [deep] if rng.random() < 0.5 else {"children": [deep], "shape": "union"}
            node[key] = deep
        elif op == 7 and isinstance(node, dict):
            sizes = [rng.choice([1, 2, 10, 60, 300]) for _ in range(rng.randint(1, 3))]
            node["variants"] = {f"k{i}": [f"v{j}" for j in range(n)] for i, n in enumerate(sizes)}
        else:
            node[key] = self.value()
        return data

    def textual(self, text: str) -> str:
        rng = self.rng
        op = rng.randrange(7)
        if op == 6:
            depth = rng.choice([50, 101, 500, 3000])
            lines = text.split("\n")
            at = rng.randrange(len(lines) + 1)
            indent = " " * rng.choice([0, 2, 4, 6])
            deep = "[" * depth + "]" * depth if rng.random() < 0.5 else "{a: " * depth + "1" + "}" * depth
            text = "\n".join(lines[:at] + [f"{indent}deep: {deep}"] + lines[at:])
        elif op == 0 and text:
            for _ in range(rng.randint(1, 8)):
                i = rng.randrange(len(text))
                text = text[:i] + rng.choice(":-[]{}&*!|>'\"#%@`,?\n\t \x00") + text[i + 1:]
        elif op == 1 and text:
            i = rng.randrange(len(text))
            text = text[:i] + text[i + rng.randint(1, 30):]
        elif op == 2:
            text = text[: rng.randrange(len(text) + 1)]
        elif op == 3:
            n = rng.randint(2, 12)
            bomb = [f"b0: &b0 [{', '.join(['x'] * n)}]"]
            bomb += [f"b{i}: &b{i} [{', '.join([f'*b{i - 1}'] * n)}]" for i in range(1, rng.randint(2, 10))]
            text = "\n".join(bomb) + "\n" + text
        elif op == 4:
            text = rng.choice(["\ufeff", "%YAML 1.1\n---\n", "---\n", "!!python/object:os.system\n"]) + text
        else:
            text = text.replace("  ", "\t", rng.randint(1, 5))
        return text


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> tuple[Path, dict[str, str]]:
    folder = tmp_path_factory.mktemp("fuzz")
    shutil.copytree(REPO / "recipes" / "inputs", folder / "inputs")
    texts = {p.name: p.read_text(encoding="utf-8") for p in sorted((REPO / "recipes").glob("*.yaml"))}
    texts.update(_EXTRA_CORPUS)
    return folder, texts


def _run(args: list[str], capsys) -> tuple[int, str]:
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    return code, capsys.readouterr().err


_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # the fuzzer's own YAML handling: fast, and it trusts
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)  # nothing of what decollage reads (that is safe_yaml's)


def _mutate(text: str, mutator: Mutator, rng: random.Random) -> str:
    """Structural mutations on the parsed recipe, then (sometimes) textual ones on the YAML; never re-parsed after."""
    structural = rng.choice([0, 1, 1, 2, 3])
    if structural:
        data = yaml.load(text, Loader=_LOADER)  # noqa: S506 - a safe loader
        for _ in range(structural):
            data = mutator.structural(data)
        try:
            text = yaml.dump(data, Dumper=_DUMPER, allow_unicode=rng.random() < 0.5, sort_keys=False)
        except RecursionError:  # too deep for the fuzzer's own dumper: keep the text, mutate it as text
            structural = 0
    for _ in range(rng.choice([0, 0, 1, 2]) if structural else rng.randint(1, 3)):
        text = mutator.textual(text)
    return text


def test_mutated_recipes_never_cause_internal_errors(corpus, capsys):
    folder, texts = corpus
    rng = random.Random(SEED)
    mutator = Mutator(rng, _schema_keys())
    names = sorted(texts)
    for name in names:  # warm up (imports, the shipped model): the corpus itself is valid
        (folder / name).write_text(texts[name], encoding="utf-8")
        assert _run(["validate", str(folder / name)], capsys)[0] == 0, name
    codes: dict[int, int] = {}
    bad: list[str] = []
    slowest = 0.0
    started = time.perf_counter()
    for i in range(COUNT):
        name = rng.choice(names)
        text = _mutate(texts[name], mutator, rng)
        path = folder / "recipe.yaml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        args = ["build", str(path), "--list"] if i % 10 == 0 else ["validate", str(path)]
        t0 = time.perf_counter()
        code, err = _run(args, capsys)
        took = time.perf_counter() - t0
        slowest = max(slowest, took)
        codes[code] = codes.get(code, 0) + 1
        if code not in (0, 1, 2) or "internal error" in err or "Traceback" in err or took > MAX_SECONDS:
            bad.append(f"#{i} ({name}): exit {code} in {took:.1f} s: {err.strip()[-300:]}\n"
                       f"--- recipe ---\n{text[:1500]}")
    elapsed = time.perf_counter() - started
    print(f"{COUNT} mutated recipes in {elapsed:.1f} s (slowest {slowest:.2f} s); exit codes {sorted(codes.items())}",
          file=sys.__stderr__)
    assert not bad, f"{len(bad)} of {COUNT} runs failed; first:\n" + "\n\n".join(bad[:3])
    assert codes.get(2, 0) > COUNT // 4  # the mutations do reach the checks
    assert sum(codes.values()) == COUNT
