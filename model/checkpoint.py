"""Self-describing DECOLLAGE checkpoints: weights + config + vocabularies + format version.

On disk a checkpoint is one ``torch.save`` file holding a plain dict that
``torch.load(weights_only=True)`` can read (no pickled classes, so loading a
file never runs code from it):

- ``"format"``: ``FORMAT_NAME``; ``"version"``: ``FORMAT_VERSION`` (int);
- ``"meta"``: a JSON string with the ``ModelConfig`` dict, ``style_names``,
  ``part_names``, ``style_parts`` (for each style exemplar, the part names it
  has) and ``training`` metadata (step, seed, command, wall time, machine...);
  optionally ``part_aliases`` (a category's own name for a part → the part,
  e.g. ``roof → top``) and ``style_categories`` (per style, e.g. ``building``);
- ``"generator"``: the generator's state dict (CPU, contiguous tensors);
- optionally ``"discriminators"``, ``"optimizers"`` (name → optimizer state
  dict) and ``"rng"`` (name → state tensor), only needed to resume training.

``load_checkpoint`` checks everything before returning: format name and
version, the metadata's types, the config, the vocabularies' sizes against the
config, and every state dict's keys and shapes against networks built from the
config on the ``meta`` device. A file that fails any check is refused with a
``DetailizeError`` naming the file; nothing is half-loaded.

``save_checkpoint`` is atomic: it writes a temporary file beside the target,
fsyncs it and ``os.replace``-s it into place, so a crash never leaves a
truncated checkpoint under the final name.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from model.config import ModelConfig
from core.errors import DetailizeError
from core.files import InputKind, check_input_file

#: Value of the ``"format"`` entry; anything else is a foreign file.
FORMAT_NAME = "decollage-checkpoint"
#: Bumped whenever the layout of the file changes incompatibly.
FORMAT_VERSION = 1

_REQUIRED = ("format", "version", "meta", "generator")
_OPTIONAL = ("discriminators", "optimizers", "rng", "generator_ema")


@dataclass(frozen=True, eq=False)
class Checkpoint:
    """Everything a checkpoint holds, validated.

    Attributes:
        config: the model's sizes and weights.
        style_names: (N,) names of the style exemplars, index = style code / D head.
        part_names: (P,) the set-level part vocabulary, index = part channel.
        style_parts: (N,) per style, the part names its exemplar has (a part absent
            from an exemplar was never painted in that style during training).
        generator: generator state dict (name → CPU tensor).
        training: JSON-able metadata (step, seed, command, wall_time_s, ...).
        discriminators: discriminators' state dict, or None (inference-only file).
        optimizers: name → optimizer state dict, or None.
        rng: name → RNG state tensor (e.g. ``"torch"``), or None.
        part_aliases: other accepted names of parts (alias → a name in ``part_names``),
            e.g. ``{"body": "bottom", "roof": "top"}`` for the "things" set.
        style_categories: (N,) category of each style exemplar, or () when unknown.
        generator_ema: the exponential moving average of the generator's weights
            (``TrainConfig.ema_decay``; same keys and shapes as ``generator``), or None.
            Training state: read only with ``training_state``.
    """

    config: ModelConfig
    style_names: tuple[str, ...]
    part_names: tuple[str, ...]
    style_parts: tuple[tuple[str, ...], ...]
    generator: dict[str, Any]
    training: dict[str, Any] = field(default_factory=dict)
    discriminators: dict[str, Any] | None = None
    optimizers: dict[str, Any] | None = None
    rng: dict[str, Any] | None = None
    part_aliases: dict[str, str] = field(default_factory=dict)
    style_categories: tuple[str, ...] = ()
    generator_ema: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        _check_vocab(self.config, self.style_names, self.part_names, self.style_parts)
        _check_aliases(self.part_names, self.part_aliases, self.style_names, self.style_categories)

    def part_index(self) -> dict[str, int]:
        """Every accepted part name (vocabulary and aliases) → its part channel."""
        index = {n: i for i, n in enumerate(self.part_names)}
        index.update({a: index[p] for a, p in self.part_aliases.items()})
        return index

    def meta(self) -> dict[str, Any]:
        """The JSON part of the file (everything but tensors)."""
        return {
            "config": self.config.to_dict(),
            "style_names": list(self.style_names),
            "part_names": list(self.part_names),
            "style_parts": [list(p) for p in self.style_parts],
            "training": self.training,
            "part_aliases": dict(sorted(self.part_aliases.items())),
            "style_categories": list(self.style_categories),
        }


# ----------------------------------------------------------------------------- save


def _cpu_state(state: dict[str, Any]) -> dict[str, Any]:
    """Detached, contiguous CPU copies (weights trained in channels_last keep no odd strides on disk)."""
    import torch

    return {k: (v.detach().cpu().contiguous() if isinstance(v, torch.Tensor) else v) for k, v in state.items()}


def save_checkpoint(path: str | Path, ckpt: Checkpoint) -> Path:
    """Write ``ckpt`` to ``path`` atomically (temp file + fsync + ``os.replace``); returns the path.

    Raises:
        DetailizeError: the training metadata is not JSON-able, or the file cannot be written.
    """
    import torch

    path = Path(path)
    _check_states(ckpt.config, ckpt.generator, ckpt.discriminators, path, ckpt.generator_ema)
    try:
        meta = json.dumps(ckpt.meta(), sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise DetailizeError(f"checkpoint metadata is not plain JSON: {exc}", file=path, field="training",
                             hint="store only str/int/float/bool/list/dict in the training metadata") from None
    payload: dict[str, Any] = {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "meta": meta,
        "generator": _cpu_state(ckpt.generator),
    }
    if ckpt.discriminators is not None:
        payload["discriminators"] = _cpu_state(ckpt.discriminators)
    if ckpt.optimizers is not None:
        payload["optimizers"] = ckpt.optimizers
    if ckpt.rng is not None:
        payload["rng"] = {k: v.detach().cpu() for k, v in ckpt.rng.items()}
    if ckpt.generator_ema is not None:
        payload["generator_ema"] = _cpu_state(ckpt.generator_ema)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as fh:
            torch.save(payload, fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        raise DetailizeError(f"cannot write checkpoint: {exc.strerror or exc}", file=path,
                             hint="check that the folder exists, is writable and the disk has room") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


# ----------------------------------------------------------------------------- load


def load_checkpoint(path: str | Path, *, training_state: bool = False) -> Checkpoint:
    """Read and fully validate a checkpoint (tensors on the CPU).

    Args:
        path: the ``.pt`` file.
        training_state: also return discriminators, optimizers and RNG states (when
            present); False drops them, which is all inference needs.
    Raises:
        DetailizeError: missing/unreadable file, not a torch file or truncated, foreign
            format, other format version, bad metadata, or state dicts that do not
            match the config (missing/unexpected keys, wrong shapes).
    """
    import torch

    path = Path(path)
    if not path.exists():
        raise DetailizeError("checkpoint not found", file=path, hint="check the path, or train one with decollage train")
    if not path.is_file():
        raise DetailizeError("checkpoint is not a file", file=path, hint="point to the .pt file itself")
    check_input_file(path, InputKind.CHECKPOINT, error=DetailizeError, file=path)  # no device, within its size limit
    try:
        with open(path, "rb") as handle:
            magic = handle.read(4)
    except OSError as exc:
        raise DetailizeError(f"cannot read checkpoint: {exc.strerror or exc}", file=path) from None
    # torch.save writes a zip (PK..); older torch a pickle (protocol 2+: 0x80 then the protocol number).
    if not (magic.startswith(b"PK\x03\x04") or (len(magic) > 1 and magic[0] == 0x80 and 2 <= magic[1] <= 5)):
        raise DetailizeError("not a readable decollage checkpoint (it is not a torch file or it is truncated)",
                             file=path, hint="re-download or re-train it; only files written by decollage are accepted")
    try:
        raw = torch.load(path, map_location="cpu", weights_only=True)
    except OSError as exc:
        raise DetailizeError(f"cannot read checkpoint: {exc.strerror or exc}", file=path,
                             hint="check the file's permissions") from None
    except Exception as exc:  # noqa: BLE001 - torch raises many kinds for junk/truncated/unsafe files
        kind = "it holds objects other than tensors and plain data" if "weights_only" in str(exc).lower() \
            else "it is not a torch file or it is truncated"
        raise DetailizeError(f"not a readable decollage checkpoint ({kind})", file=path,
                             hint="re-download or re-train it; only files written by decollage are accepted") from None
    if not isinstance(raw, dict) or raw.get("format") != FORMAT_NAME:
        found = raw.get("format") if isinstance(raw, dict) else type(raw).__name__
        raise DetailizeError(f"foreign file: format {found!r}, expected {FORMAT_NAME!r}", file=path,
                             hint="pass a checkpoint written by decollage train")
    version = raw.get("version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise DetailizeError(f"checkpoint version {version!r} is not an integer", file=path,
                             hint="the file is damaged; re-train or re-download it")
    if version > FORMAT_VERSION:
        raise DetailizeError(f"checkpoint format version {version} is newer than this decollage reads "
                             f"({FORMAT_VERSION})", file=path, hint="upgrade decollage")
    if version < FORMAT_VERSION:
        raise DetailizeError(f"checkpoint format version {version} is older than this decollage reads "
                             f"({FORMAT_VERSION})", file=path, hint="re-train the model with this version")
    missing = [k for k in _REQUIRED if k not in raw]
    extra = sorted(set(raw) - set(_REQUIRED) - set(_OPTIONAL))
    if missing or extra:
        what = f"missing {missing}" if missing else f"unexpected entries {extra}"
        raise DetailizeError(f"checkpoint is incomplete or altered: {what}", file=path,
                             hint="re-train or re-download it")
    ckpt = _from_raw(raw, path, training_state)
    _check_states(ckpt.config, ckpt.generator, ckpt.discriminators, path, ckpt.generator_ema)
    return ckpt


def _from_raw(raw: dict[str, Any], path: Path, training_state: bool) -> Checkpoint:
    if not isinstance(raw["meta"], str):
        raise DetailizeError("checkpoint metadata is not a JSON string", file=path, hint="re-train or re-download it")
    try:
        meta = json.loads(raw["meta"])
    except json.JSONDecodeError as exc:
        raise DetailizeError(f"checkpoint metadata is not valid JSON ({exc.msg})", file=path,
                             hint="re-train or re-download it") from None
    required = {"config", "style_names", "part_names", "style_parts", "training"}
    if not isinstance(meta, dict) or not required <= set(meta) <= required | {"part_aliases", "style_categories"}:
        raise DetailizeError("checkpoint metadata lacks or adds entries", file=path, field="meta",
                             hint="re-train or re-download it")
    try:
        config = ModelConfig.from_dict(meta["config"])
    except DetailizeError as err:
        err.file = str(path)
        raise
    names = {}
    for key in ("style_names", "part_names"):
        value = meta[key]
        if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
            raise DetailizeError(f"{key} must be a list of strings", file=path, field=key, hint="re-train it")
        names[key] = tuple(value)
    sp = meta["style_parts"]
    if not isinstance(sp, list) or not all(isinstance(p, list) and all(isinstance(x, str) for x in p) for p in sp):
        raise DetailizeError("style_parts must be a list of lists of part names", file=path, field="style_parts",
                             hint="re-train it")
    aliases, categories = meta.get("part_aliases", {}), meta.get("style_categories", [])
    if not isinstance(aliases, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in aliases.items()) \
            or not isinstance(categories, list) or not all(isinstance(c, str) for c in categories):
        raise DetailizeError("part_aliases / style_categories are malformed", file=path, field="meta",
                             hint="re-train it")
    if not isinstance(meta["training"], dict):
        raise DetailizeError("training metadata must be an object", file=path, field="training", hint="re-train it")
    for key in ("generator", "discriminators", "generator_ema"):
        if key in raw and not isinstance(raw[key], dict):
            raise DetailizeError(f"{key} is not a state dict", file=path, field=key, hint="re-train it")
    try:
        return Checkpoint(
            config=config,
            style_names=names["style_names"],
            part_names=names["part_names"],
            style_parts=tuple(tuple(p) for p in sp),
            generator=raw["generator"],
            training=meta["training"],
            discriminators=raw.get("discriminators") if training_state else None,
            optimizers=raw.get("optimizers") if training_state else None,
            rng=raw.get("rng") if training_state else None,
            generator_ema=raw.get("generator_ema") if training_state else None,
            part_aliases=aliases,
            style_categories=tuple(categories),
        )
    except DetailizeError as err:
        err.file = str(path)
        raise


# ----------------------------------------------------------------------------- checks


def _check_vocab(cfg: ModelConfig, styles: tuple[str, ...], parts: tuple[str, ...],
                 style_parts: tuple[tuple[str, ...], ...]) -> None:
    if len(styles) != cfg.n_styles or len(set(styles)) != len(styles):
        raise DetailizeError(f"{len(styles)} style names (distinct: {len(set(styles))}) for a model of "
                             f"{cfg.n_styles} styles", field="style_names", hint="one distinct name per style code")
    if len(parts) != cfg.n_parts or len(set(parts)) != len(parts):
        raise DetailizeError(f"{len(parts)} part names (distinct: {len(set(parts))}) for a model of "
                             f"{cfg.n_parts} parts", field="part_names", hint="one distinct name per part channel")
    if len(style_parts) != len(styles):
        raise DetailizeError(f"style_parts has {len(style_parts)} entries for {len(styles)} styles",
                             field="style_parts", hint="list the parts of every style exemplar")
    for i, ps in enumerate(style_parts):
        unknown = sorted(set(ps) - set(parts))
        if unknown:
            raise DetailizeError(f"style {styles[i]!r} lists unknown parts {unknown}", field=f"style_parts[{i}]",
                                 hint=f"use part names from {list(parts)}")


def _check_aliases(parts: tuple[str, ...], aliases: dict[str, str], styles: tuple[str, ...],
                   categories: tuple[str, ...]) -> None:
    bad = sorted(a for a, p in aliases.items() if p not in parts or a in parts)
    if bad:
        raise DetailizeError(f"part aliases {bad} name unknown parts or shadow a part name", field="part_aliases",
                             hint=f"map other names onto {list(parts)}")
    if categories and len(categories) != len(styles):
        raise DetailizeError(f"{len(categories)} style categories for {len(styles)} styles", field="style_categories",
                             hint="give one category per style, or none")


def expected_shapes(cfg: ModelConfig) -> tuple[dict[str, tuple[int, ...]], dict[str, tuple[int, ...]]]:
    """State-dict key → shape of the generator and of the discriminators built from ``cfg`` (no memory used)."""
    import torch

    from model.networks import Generator, build_discriminators

    with torch.device("meta"):
        gen, discs = Generator(cfg), build_discriminators(cfg)
    return ({k: tuple(v.shape) for k, v in gen.state_dict().items()},
            {k: tuple(v.shape) for k, v in discs.state_dict().items()})


def _check_states(cfg: ModelConfig, generator: dict[str, Any], discriminators: dict[str, Any] | None,
                  path: Path, generator_ema: dict[str, Any] | None = None) -> None:
    import torch

    gen_shapes, disc_shapes = expected_shapes(cfg)
    for what, state, shapes in (("generator", generator, gen_shapes), ("discriminators", discriminators, disc_shapes),
                                ("generator_ema", generator_ema, gen_shapes)):
        if state is None:
            continue
        missing = sorted(set(shapes) - set(state))
        extra = sorted(set(state) - set(shapes))
        if missing or extra:
            detail = f"missing {missing[:3]}" if missing else f"unexpected {extra[:3]}"
            raise DetailizeError(f"{what} weights do not match the config ({detail}"
                                 f"{', …' if len(missing or extra) > 3 else ''})", file=path, field=what,
                                 hint="the weights and config come from different models; re-train")
        for key, shape in shapes.items():
            t = state[key]
            if not isinstance(t, torch.Tensor) or tuple(t.shape) != shape:
                got = tuple(t.shape) if isinstance(t, torch.Tensor) else type(t).__name__
                raise DetailizeError(f"{what} weight {key!r} has shape {got}, the config needs {shape}", file=path,
                                     field=what, hint="the weights and config come from different models; re-train")
            if not t.is_floating_point() or not bool(torch.isfinite(t).all()):
                raise DetailizeError(f"{what} weight {key!r} is not finite floating point", file=path, field=what,
                                     hint="the training diverged or the file is damaged; use an earlier checkpoint")
