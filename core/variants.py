"""Variant matrices: one recipe asset → many named assets (styles × seeds × words × sizes ...).

An asset may declare::

    - name: word
      variants:                      # the cartesian product, in key order
        text: [CASTLE, TOWER]
        style: [stone, moss]
        seed: [0, 1]
      name_template: "{asset}_{text}_{style}_{seed}"   # default: {asset}_ + every key in order
      source: {kind: text, text: "${text}"}
      regions: [{part: body, style: "${style}"}]
      detailize: {seed: "${seed}"}

Expansion works on the raw YAML data before validation: a string that is
exactly ``${key}`` becomes the value itself (so ``seed`` stays an integer), a
string containing ``${key}`` gets the value's text. Every key must be used and
every ``${...}`` must be a key. Each expanded asset records its ``variant``
(key → value) for the manifest.

Caps, checked on the counts before anything is expanded (so a typo that asks
for millions of assets is refused at once): the whole recipe may give at most
``max_assets`` assets (default ``DEFAULT_MAX_ASSETS``; ``decollage
build/validate --max-assets N`` raises it), and the expanded assets together may hold at most
``MAX_EXPANDED_VALUES`` YAML values (a big extrude profile times many variants).
Substitution walks the data with an explicit stack, never by recursion.
"""

from __future__ import annotations

import itertools
import re
from collections import Counter
from typing import Any

from core.errors import RecipeError

_PLACEHOLDER = re.compile(r"\$\{([^}]*)\}")
_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_NAME_UNSAFE = re.compile(r"[^A-Za-z0-9_.\-]+")
#: Most assets a recipe may expand to unless the caller raises the cap (``--max-assets``);
#: a typo like a 1000-value list multiplies fast.
DEFAULT_MAX_ASSETS = 2_000

#: Most values (scalars, lists, mappings) all expanded assets may hold together.
MAX_EXPANDED_VALUES = 2_000_000


def _name_piece(value: Any) -> str:
    """A variant value as it appears in an asset name (unsafe characters become '-')."""
    text = str(value).strip()
    return _NAME_UNSAFE.sub("-", text).strip("-") or "x"


def _substitute(node: Any, values: dict[str, Any], path: str, used: set[str]) -> Any:
    """``node`` with ``${key}`` replaced; iterative (an explicit stack), so depth costs no recursion."""
    root: list[Any] = [None]
    # (value to copy, container to put the copy in, key or index there, field path of the value)
    stack: list[tuple[Any, Any, Any, str]] = [(node, root, 0, path)]
    while stack:
        value, container, slot, where = stack.pop()
        if isinstance(value, dict):
            copy: Any = {}
            for k, v in value.items():
                copy[k] = None
                stack.append((v, copy, k, f"{where}.{k}"))
        elif isinstance(value, list):
            copy = [None] * len(value)
            for i, v in enumerate(value):
                stack.append((v, copy, i, f"{where}[{i}]"))
        else:
            copy = _substitute_scalar(value, values, where, used)
        container[slot] = copy
    return root[0]


def _substitute_scalar(node: Any, values: dict[str, Any], path: str, used: set[str]) -> Any:
    if not isinstance(node, str) or "${" not in node:
        return node
    for key in _PLACEHOLDER.findall(node):
        if key not in values:
            raise RecipeError(f"'${{{key}}}' is not a variant key (keys: {sorted(values)})", field=path,
                              hint="declare it under 'variants' or fix the spelling")
        used.add(key)
    whole = _PLACEHOLDER.fullmatch(node)
    if whole:
        return values[whole.group(1)]
    return _PLACEHOLDER.sub(lambda m: str(values[m.group(1)]), node)


def count_values(node: Any) -> int:
    """Scalars, lists and mappings in ``node`` (itself included); iterative."""
    count, stack = 0, [node]
    while stack:
        value = stack.pop()
        count += 1
        if isinstance(value, dict):
            stack.extend(value.values())
        elif isinstance(value, list):
            stack.extend(value)
    return count


def matrix_size(raw: Any) -> int:
    """How many assets a raw recipe asset expands to (1 without a usable ``variants`` matrix)."""
    variants = raw.get("variants") if isinstance(raw, dict) else None
    if not isinstance(variants, dict) or not variants:
        return 1
    count = 1
    for values in variants.values():
        count *= len(values) if isinstance(values, list) and values else 1
    return count


def _check_matrix(variants: Any, where: str) -> dict[str, list]:
    if not isinstance(variants, dict) or not variants:
        raise RecipeError("variants must be a mapping of key → list of values", field=f"{where}.variants",
                          hint="e.g. variants: {seed: [0, 1], style: [stone, moss]}")
    for key, values in variants.items():
        if not isinstance(key, str) or not _KEY.match(key) or key == "asset":
            raise RecipeError(f"bad variant key {key!r}", field=f"{where}.variants",
                              hint="use letters, digits and '_' (not 'asset', which names the base asset)")
        if not isinstance(values, list) or not values:
            raise RecipeError("needs a non-empty list of values", field=f"{where}.variants.{key}")
        for i, v in enumerate(values):
            if not isinstance(v, (str, int, float, bool)):
                raise RecipeError("variant values must be plain strings or numbers",
                                  field=f"{where}.variants.{key}[{i}]")
        if len(set(map(repr, values))) != len(values):
            raise RecipeError("a value is listed twice", field=f"{where}.variants.{key}")
    return variants


def expand_asset(raw: dict, index: int) -> list[dict]:
    """The raw asset itself (no ``variants``), or one raw asset per combination."""
    where = f"assets[{index}]"
    if "variants" not in raw:
        if "name_template" in raw:
            raise RecipeError("name_template without variants", field=f"{where}.name_template",
                              hint="add a 'variants' matrix or remove the template")
        return [raw]
    matrix = _check_matrix(raw["variants"], where)
    base = raw.get("name")
    if not isinstance(base, str):
        return [raw]  # the schema reports the missing/invalid name
    keys = list(matrix)
    template = raw.get("name_template", "{asset}_" + "_".join("{%s}" % k for k in keys))
    if not isinstance(template, str):
        raise RecipeError("name_template must be a string", field=f"{where}.name_template")
    body = {k: v for k, v in raw.items() if k not in ("variants", "name_template", "name")}
    expanded, names = [], []
    for combo in itertools.product(*(matrix[k] for k in keys)):
        values = dict(zip(keys, combo))
        used: set[str] = set()
        entry = _substitute(body, values, where, used)
        try:
            name = template.format(asset=base, **{k: _name_piece(v) for k, v in values.items()})
        except (KeyError, IndexError, ValueError) as exc:
            raise RecipeError(f"cannot fill the name template: {exc}", field=f"{where}.name_template",
                              hint=f"use {{asset}} and the variant keys {keys} in braces") from None
        named = set(re.findall(r"\{(\w+)\}", raw["name_template"])) if "name_template" in raw else set()
        unused = set(keys) - used - named
        if unused:
            raise RecipeError(f"variant keys {sorted(unused)} are never used", field=f"{where}.variants",
                              hint="reference them as ${key} in the asset or in the name_template")
        names.append(name)
        expanded.append({"name": name, "variant": values, **entry})
    repeated = sorted(n for n, c in Counter(names).items() if c > 1)
    if repeated:
        raise RecipeError(f"the variants expand to duplicate names {repeated[:5]}",
                          field=f"{where}.name_template",
                          hint="put every varying key into the name_template")
    return expanded


def expand_assets(raw_assets: list, max_assets: int | None = DEFAULT_MAX_ASSETS
                  ) -> tuple[list, list[tuple[int, str | None]]]:
    """Expand every asset; returns the raw assets and, per expanded asset, (recipe index, variant name or None).

    Raises RecipeError before expanding anything when the recipe would give more than
    ``max_assets`` assets (None: no cap) or more than ``MAX_EXPANDED_VALUES`` values.
    """
    sizes = [matrix_size(raw) for raw in raw_assets]
    total = sum(sizes)
    if max_assets is not None and total > max_assets:
        biggest = max(range(len(sizes)), key=sizes.__getitem__)
        raise RecipeError(f"the recipe expands to {total:,} assets, more than the cap of {max_assets:,} "
                          f"(assets[{biggest}] alone gives {sizes[biggest]:,})", field="assets",
                          hint="split the batch over several recipes, or raise the cap with --max-assets N")
    values = sum(count_values({k: v for k, v in raw.items() if k not in ("variants", "name_template")}) * size
                 for raw, size in zip(raw_assets, sizes) if size > 1)
    if values > MAX_EXPANDED_VALUES:
        raise RecipeError(f"the expanded assets would hold {values:,} values, more than {MAX_EXPANDED_VALUES:,}",
                          field="assets", hint="use fewer variants of large assets (e.g. long extrude profiles)")
    out: list = []
    origin: list[tuple[int, str | None]] = []
    for i, raw in enumerate(raw_assets):
        if not isinstance(raw, dict):
            out.append(raw)
            origin.append((i, None))
            continue
        items = expand_asset(raw, i)
        out.extend(items)
        origin.extend((i, item["name"] if "variant" in item else None) for item in items)
    return out, origin
