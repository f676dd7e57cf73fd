"""Reading a recipe file: YAML → a validated ``Recipe`` (``core/recipe.py``), with errors naming file and field.

The file is read within its size limit (``core/files.py``, ``InputKind.RECIPE``)
and parsed by the bounded YAML reader (``core/safe_yaml.py``: YAML 1.2 numbers,
no alias bombs, bounded nesting, unique keys); then the recipe's ``defaults``
apply to every asset, variants expand (``core/variants.py``, within the
``max_assets`` cap) and the result is validated strictly. Any problem raises
``RecipeError`` naming the file and the field path (``assets[2].source.font``),
or the line and column for YAML problems.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from core.errors import RecipeError
from core.files import InputKind, read_input_bytes, resolve_relative
from core.recipe import Defaults, Recipe
from core.safe_yaml import YamlLimitError, load_yaml
from core.variants import DEFAULT_MAX_ASSETS, expand_assets


class LoadedRecipe:
    """A validated recipe plus where it came from (for relative paths and messages)."""

    def __init__(self, recipe: Recipe, path: Path, text: str) -> None:
        self.recipe = recipe
        self.path = path
        self.base_dir = path.parent
        self.text = text

    def where(self, index: int) -> tuple[str, str | None]:
        """(field path of expanded asset ``index`` in the recipe file, its variant name or None)."""
        recipe_index, variant = self.recipe._origin[index]
        return f"assets[{recipe_index}]", variant

    def resolve(self, relative: str) -> Path:
        """A path from the recipe, resolved against the recipe's folder."""
        return resolve_relative(relative, self.base_dir)


def format_loc(loc: tuple) -> str:
    """``('assets', 2, 'regions', 0, 'style')`` → ``assets[2].regions[0].style``."""
    out = ""
    for item in loc:
        if isinstance(item, int):
            out += f"[{item}]"
        else:
            out += ("." if out else "") + str(item)
    return out


_TAGGED_UNION_MEMBERS = {"text", "cad", "mesh", "voxels", "vox", "box", "cylinder", "sphere", "cone", "torus",
                         "extrude", "union", "difference", "intersection"}


def _clean_loc(loc: tuple) -> tuple:
    """Drop pydantic's union-member tags (``source.text.font`` → ``source.font``)."""
    cleaned = []
    for i, item in enumerate(loc):
        prev = loc[i - 1] if i else None
        if isinstance(item, str) and item in _TAGGED_UNION_MEMBERS and prev in ("source", "parts", "children") or (
            isinstance(item, str) and item in _TAGGED_UNION_MEMBERS and isinstance(prev, int)
        ):
            continue
        if isinstance(item, str) and item.startswith(("function-", "literal[", "list[")):
            continue
        cleaned.append(item)
    return tuple(cleaned)


def _hint_for(err: dict) -> str | None:
    kind = err.get("type", "")
    if kind == "extra_forbidden":
        return "remove it or check its spelling; 'decollage schema' lists every allowed key"
    if kind == "missing":
        return "add this field"
    if kind == "union_tag_invalid":
        return None
    if kind.endswith("_type") or kind.endswith("_parsing"):
        return "check the value's type"
    return None


def _message_for(err: dict) -> str:
    kind = err.get("type", "")
    msg = err.get("msg", "invalid value")
    if kind == "extra_forbidden":
        return "unknown key"
    if kind == "union_tag_invalid":
        ctx = err.get("ctx", {})
        return f"unknown {ctx.get('discriminator', 'kind').strip(chr(39))} {ctx.get('tag')!r} (known: {ctx.get('expected_tags')})"
    if kind == "union_tag_not_found":
        ctx = err.get("ctx", {})
        return f"missing {ctx.get('discriminator', 'kind').strip(chr(39))}"
    msg = re.sub(r"^(Value error|Assertion failed), ", "", msg)
    if "input" in err and kind not in ("missing",) and not isinstance(err["input"], (dict, list)):
        msg += f" (got {err['input']!r})"
    return msg


def validation_error(exc: ValidationError, path: Path) -> RecipeError:
    """Turn pydantic's errors into one RecipeError naming the first problem (and how many more)."""
    errors = exc.errors()
    first = errors[0]
    field = format_loc(_clean_loc(tuple(first["loc"]))) or "(top level)"
    message = _message_for(first)
    if len(errors) > 1:
        message += f" [+{len(errors) - 1} more problem(s); fix this one and validate again]"
    return RecipeError(message, file=path, field=field, hint=_hint_for(first))


def parse_recipe(text: str, path: Path, max_assets: int | None = DEFAULT_MAX_ASSETS) -> Recipe:
    """Parse and validate recipe text; ``path`` is used for messages only.

    ``max_assets`` caps the number of assets after variant expansion (None: no cap, for a
    recipe whose expansion the caller already checked).
    """
    try:
        return _parse(text, path, max_assets)
    except RecursionError:  # a safety net: YAML depth and CAD depth are bounded before any deep walk
        raise RecipeError("the recipe is nested too deeply", file=path,
                          hint="flatten the data; lists and mappings nest at most a few dozen levels") from None


def _parse(text: str, path: Path, max_assets: int | None) -> Recipe:
    try:
        data = load_yaml(text)
    except YamlLimitError as exc:
        where = f"line {exc.line}, column {exc.column}" if exc.line else None
        raise RecipeError(exc.message, file=path, field=where, hint=exc.hint) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        context = getattr(exc, "context", None)
        if context and context.startswith("expected"):  # "expected a single document..., but found another"
            problem = f"{context}, {problem}"
        raise RecipeError(f"not valid YAML: {problem}", file=path, field=where,
                          hint="check indentation, colons and quotes") from None
    if data is None:
        raise RecipeError("the file is empty", file=path, hint="a recipe needs 'version: 1' and a list of 'assets'")
    if not isinstance(data, dict):
        raise RecipeError(f"the top level is a {type(data).__name__}, not a mapping", file=path,
                          hint="start the file with 'version: 1' and 'assets:'")
    try:
        as_json = json.dumps(data)
    except (TypeError, ValueError) as exc:
        raise RecipeError(f"contains a value that is not plain data: {exc}", file=path,
                          hint="quote dates and other special values") from None
    defaults = data.get("defaults", {})
    try:
        Defaults.model_validate_json(json.dumps(defaults), strict=True)
    except ValidationError as exc:
        err = validation_error(exc, path)
        err.field = "defaults" + ("." + err.field if err.field != "(top level)" else "")
        raise err from None
    origin = None
    if isinstance(defaults, dict) and isinstance(data.get("assets"), list):

        try:
            assets, origin = expand_assets(data["assets"], max_assets)
        except RecipeError as exc:
            raise exc.located(file=path) from None
        data = dict(data)
        data["assets"] = [_with_defaults(a, defaults) for a in assets]
        as_json = json.dumps(data)
    try:
        recipe = Recipe.model_validate_json(as_json, strict=True)
    except ValidationError as exc:
        raise _at_recipe_index(validation_error(exc, path), origin) from None
    recipe._origin = origin or [(i, None) for i in range(len(recipe.assets))]
    return recipe


def _at_recipe_index(err: RecipeError, origin: list[tuple[int, str | None]] | None) -> RecipeError:
    """Point an error in an expanded asset back at the recipe's own asset (and name the variant)."""
    match = re.match(r"^assets\[(\d+)\](.*)$", err.field or "")
    if origin is None or not match or int(match.group(1)) >= len(origin):
        return err
    index, variant = origin[int(match.group(1))]
    err.field = f"assets[{index}]{match.group(2)}"
    if variant:
        err.message += f" (in variant {variant})"
    return err


def _with_defaults(asset: Any, defaults: dict) -> Any:
    """Merge ``defaults.{grid,detailize,export}`` under an asset's own settings (asset wins)."""
    if not isinstance(asset, dict):
        return asset
    merged = dict(asset)
    for key in ("grid", "detailize", "export"):
        base = defaults.get(key) or {}
        own = asset.get(key)
        if isinstance(own, dict) or own is None:
            merged[key] = {**base, **(own or {})}
    return merged


def load_recipe(path: str | Path, max_assets: int | None = DEFAULT_MAX_ASSETS) -> LoadedRecipe:
    """Read (within the recipe size limit), parse and validate a recipe file. Raises RecipeError."""
    path = Path(path)
    raw = read_input_bytes(path, InputKind.RECIPE, error=RecipeError, file=path)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise RecipeError("not UTF-8 text (is this a binary file?)", file=path,
                          hint="a recipe is a YAML text file") from None
    recipe = parse_recipe(text, path, max_assets)
    return LoadedRecipe(recipe, path, text)


def json_schema() -> dict:
    """The JSON Schema of recipe version 1, for editor autocomplete."""
    schema = Recipe.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "decollage recipe"
    return schema
