"""A bounded YAML reader for recipes: YAML 1.2 core-schema scalars, no alias bombs, bounded nesting.

Role: ``load_yaml(text)`` turns recipe text into plain Python data (dicts,
lists, str, int, float, bool, None), or raises ``YamlLimitError`` /
``yaml.YAMLError`` with the line and column of the problem. It is PyYAML's
pure-Python ``SafeLoader`` (no Python tags, no object construction) with
these changes:

- **Scalars follow the YAML 1.2 core schema**, not YAML 1.1: ``1e-3``, ``1E6``
  and ``-2.5e+3`` are floats; ``.inf``/``-.inf``/``.nan`` are floats (the
  recipe schema then refuses them); ``012`` is the integer 12 (not octal),
  ``0o17`` and ``0x1F`` are octal and hex; only ``true``/``false`` (any of
  ``true, True, TRUE``) are booleans, so ``yes``, ``no``, ``on``, ``off`` and
  ``NO`` stay strings; ``null``/``~``/empty are null; ``1_000``, ``1:20`` and
  dates stay strings.
- **Nesting**: at most ``MAX_DEPTH`` levels of lists and mappings (the
  document's top level is level 1); deeper data is refused while it is read,
  before any recursion could run out of stack.
- **Aliases** (``*name``) are allowed, but the document with every alias
  expanded may hold at most ``MAX_VALUES`` values (scalars, lists and
  mappings, counted as if each alias were a copy); an alias that refers to a
  list or mapping containing it (recursive data) is refused. A "billion
  laughs" document therefore stops after counting, without being expanded.
- **Mapping keys** must be unique and hashable (PyYAML keeps the last of two
  equal keys silently; here it is an error at the second key's line).

Merge keys (``<<: *base``) keep working; they count towards ``MAX_VALUES``
like any alias.
"""

from __future__ import annotations

import re
from typing import Any

import yaml
from yaml.constructor import ConstructorError
from yaml.nodes import MappingNode, Node, ScalarNode

#: Deepest nesting of lists and mappings a recipe may use (the top-level mapping is level 1).
MAX_DEPTH: int = 100

#: Most values (scalars + lists + mappings) a recipe may hold with every alias expanded.
MAX_VALUES: int = 250_000


class YamlLimitError(Exception):
    """The document is too deep or too large; ``line``/``column`` are 1-based (or None)."""

    def __init__(self, message: str, mark: Any = None, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint
        self.line = mark.line + 1 if mark is not None else None
        self.column = mark.column + 1 if mark is not None else None


# --------------------------------------------------------------------------- YAML 1.2 core schema

_BOOL = re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$")
_NULL = re.compile(r"^(?:~|null|Null|NULL|)$")
_INT = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_FLOAT = re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$")
_MERGE = re.compile(r"^<<$")


class _Core12Resolver(yaml.resolver.Resolver):
    """Implicit tags of the YAML 1.2 core schema (plus the merge key)."""

    yaml_implicit_resolvers: dict = {}


for _tag, _regexp, _first in (
    ("tag:yaml.org,2002:bool", _BOOL, list("tTfF")),
    ("tag:yaml.org,2002:null", _NULL, ["~", "n", "N", ""]),
    ("tag:yaml.org,2002:int", _INT, list("-+0123456789")),
    ("tag:yaml.org,2002:float", _FLOAT, list("-+.0123456789")),
    ("tag:yaml.org,2002:merge", _MERGE, ["<"]),
):
    _Core12Resolver.add_implicit_resolver(_tag, _regexp, _first)


class _BoundedLoader(yaml.reader.Reader, yaml.scanner.Scanner, yaml.parser.Parser, yaml.composer.Composer,
                     yaml.constructor.SafeConstructor, _Core12Resolver):
    """SafeLoader with the 1.2 resolver, a depth bound while composing, unique keys, 1.2 integers."""

    def __init__(self, stream: str) -> None:
        yaml.reader.Reader.__init__(self, stream)
        yaml.scanner.Scanner.__init__(self)
        yaml.parser.Parser.__init__(self)
        yaml.composer.Composer.__init__(self)
        yaml.constructor.SafeConstructor.__init__(self)
        _Core12Resolver.__init__(self)
        self._depth = 0

    def compose_node(self, parent: Node | None, index: Any) -> Node:
        is_collection = self.check_event(yaml.SequenceStartEvent, yaml.MappingStartEvent)
        if is_collection:
            self._depth += 1
            if self._depth > MAX_DEPTH:
                raise YamlLimitError(f"lists and mappings are nested more than {MAX_DEPTH} levels deep",
                                     self.peek_event().start_mark,
                                     hint="flatten the data; a recipe never needs this depth")
        try:
            return super().compose_node(parent, index)
        finally:
            if is_collection:
                self._depth -= 1


def _construct_int(loader: _BoundedLoader, node: ScalarNode) -> int:
    value = loader.construct_scalar(node)
    sign, digits = (-1, value[1:]) if value.startswith("-") else (1, value.lstrip("+"))
    if digits.startswith("0o"):
        return sign * int(digits[2:], 8)
    if digits.startswith("0x"):
        return sign * int(digits[2:], 16)
    return sign * int(digits, 10)


def _construct_mapping(loader: _BoundedLoader, node: MappingNode, deep: bool = False) -> dict:
    """A mapping whose own keys are unique and hashable; merged keys (``<<``) are overridden by own keys."""
    own: set[Any] = set()
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=deep)
        try:
            hash(key)
        except TypeError:
            raise ConstructorError(None, None, "a list or mapping is used as a mapping key",
                                   key_node.start_mark) from None
        if key in own:
            raise ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
        own.add(key)
    loader.flatten_mapping(node)  # merged pairs first, then the node's own: the own value wins
    data: dict[Any, Any] = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            data[key] = loader.construct_object(value_node, deep=deep)
        except TypeError:  # an unhashable key that came in through a merge
            raise ConstructorError(None, None, "a list or mapping is used as a mapping key",
                                   key_node.start_mark) from None
    return data


def _construct_map(loader: _BoundedLoader, node: MappingNode):
    data: dict = {}
    yield data
    data.update(_construct_mapping(loader, node))


_BoundedLoader.add_constructor("tag:yaml.org,2002:int", _construct_int)
_BoundedLoader.add_constructor("tag:yaml.org,2002:map", _construct_map)


# --------------------------------------------------------------------------- expanded size


def _expanded_size(root: Node) -> int:
    """Values in the document with every alias expanded; iterative, each node counted once (memoised).

    Raises YamlLimitError past ``MAX_VALUES`` or on a node that contains itself.
    """
    sizes: dict[int, int] = {}
    in_progress: set[int] = set()
    stack: list[tuple[Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        key = id(node)
        if key in sizes:
            continue
        if isinstance(node, ScalarNode):
            sizes[key] = 1
            continue
        children = [c for pair in node.value for c in pair] if isinstance(node, MappingNode) else list(node.value)
        if not children_done:
            if key in in_progress:
                raise YamlLimitError("an alias refers to a list or mapping that contains it (recursive data)",
                                     node.start_mark, hint="recipes hold plain, finite data")
            in_progress.add(key)
            stack.append((node, True))
            for child in children:
                if id(child) in in_progress and id(child) not in sizes:
                    raise YamlLimitError("an alias refers to a list or mapping that contains it (recursive data)",
                                         child.start_mark, hint="recipes hold plain, finite data")
                if id(child) not in sizes:
                    stack.append((child, False))
            continue
        total = 1 + sum(sizes[id(c)] for c in children)
        if total > MAX_VALUES:
            raise YamlLimitError(f"the document holds more than {MAX_VALUES:,} values once its aliases are "
                                 "expanded", node.start_mark,
                                 hint="write the data out, or use fewer and smaller aliases")
        sizes[key] = total
        in_progress.discard(key)
    return sizes[id(root)]


def load_yaml(text: str) -> Any:
    """Plain data from YAML text (see the module docstring); None for an empty document.

    Raises:
        YamlLimitError: too deep, too many values once aliases are expanded, recursive aliases.
        yaml.YAMLError: not YAML (scanner, parser, composer or constructor errors, with marks),
            several documents in one file.
    """
    loader = _BoundedLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _expanded_size(node)
        return loader.construct_document(node)
    except RecursionError:  # a safety net: the depth bound should make this unreachable
        raise YamlLimitError(f"the data is nested too deeply (more than {MAX_DEPTH} levels)") from None
    finally:
        loader.dispose()


__all__ = ["MAX_DEPTH", "MAX_VALUES", "YamlLimitError", "load_yaml"]
