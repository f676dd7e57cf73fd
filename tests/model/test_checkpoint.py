"""Checkpoint round trip and refusal of every kind of bad file."""

from __future__ import annotations

import dataclasses
import fractions
import json

import pytest
import torch

from model.checkpoint import FORMAT_NAME, FORMAT_VERSION, Checkpoint, load_checkpoint, save_checkpoint
from model.config import ModelConfig
from model.networks import Generator, build_discriminators
from core.errors import DetailizeError


def _tiny_cfg() -> ModelConfig:
    return ModelConfig.lean(2, 3).scaled(0.125)


def _ckpt(cfg=None, with_training=False) -> Checkpoint:
    cfg = cfg or _tiny_cfg()
    torch.manual_seed(0)
    gen = Generator(cfg)
    with torch.no_grad():
        gen.style_codes.copy_(torch.arange(gen.style_codes.numel(), dtype=torch.float32).view_as(gen.style_codes))
    extra = {}
    if with_training:
        discs = build_discriminators(cfg)
        opt = torch.optim.Adam(gen.parameters(), lr=1e-4)
        gen(*gen.make_inputs(torch.ones(1, 2, 2, 2), torch.zeros(1, 2, 2, 2, dtype=torch.long),
                             torch.zeros(1, 2, 2, 2, dtype=torch.long)))[-1].sum().backward()
        opt.step()
        extra = dict(discriminators=discs.state_dict(), optimizers={"g": opt.state_dict()},
                     rng={"torch": torch.get_rng_state()})
    return Checkpoint(
        config=cfg,
        style_names=("tower", "tree", "cake"),
        part_names=("body", "top"),
        style_parts=(("body", "top"), ("body",), ("body", "top")),
        generator=gen.state_dict(),
        training={"step": 7, "seed": 3, "command": "decollage train x", "wall_time_s": 1.5},
        **extra,
    )


def test_round_trip_keeps_everything(tmp_path):
    ck = _ckpt(with_training=True)
    path = save_checkpoint(tmp_path / "sub" / "m.pt", ck)
    assert path.exists() and not list(path.parent.glob(".*tmp*"))  # temp file replaced, not left behind
    back = load_checkpoint(path, training_state=True)
    assert back.config == ck.config
    assert back.style_names == ("tower", "tree", "cake") and back.part_names == ("body", "top")
    assert back.style_parts == (("body", "top"), ("body",), ("body", "top"))
    assert back.training == {"step": 7, "seed": 3, "command": "decollage train x", "wall_time_s": 1.5}
    for k, v in ck.generator.items():
        assert torch.equal(back.generator[k], v), k
    assert set(back.discriminators) == set(ck.discriminators)
    assert back.optimizers["g"]["state"][0]["step"] == ck.optimizers["g"]["state"][0]["step"]
    assert torch.equal(back.rng["torch"], ck.rng["torch"])
    gen = Generator(back.config)
    gen.load_state_dict(back.generator)  # strict: loads into a fresh generator


def test_inference_load_drops_training_state(tmp_path):
    path = save_checkpoint(tmp_path / "m.pt", _ckpt(with_training=True))
    back = load_checkpoint(path)
    assert back.discriminators is None and back.optimizers is None and back.rng is None
    plain = load_checkpoint(save_checkpoint(tmp_path / "p.pt", _ckpt()))
    assert torch.equal(plain.generator["style_codes"].flatten(), torch.arange(24, dtype=torch.float32))


def test_missing_file(tmp_path):
    with pytest.raises(DetailizeError, match="not found") as e:
        load_checkpoint(tmp_path / "nope.pt")
    assert e.value.file.endswith("nope.pt") and e.value.hint


def test_not_a_torch_file(tmp_path):
    p = tmp_path / "junk.pt"
    p.write_bytes(b"hello, not a checkpoint" * 10)
    with pytest.raises(DetailizeError, match="not a torch file or it is truncated"):
        load_checkpoint(p)


def test_truncated_file(tmp_path):
    p = save_checkpoint(tmp_path / "m.pt", _ckpt())
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(DetailizeError, match="truncated"):
        load_checkpoint(p)


def test_pickled_objects_are_refused_not_run(tmp_path):
    p = tmp_path / "obj.pt"
    torch.save({"format": FORMAT_NAME, "thing": fractions.Fraction(1, 3)}, p)
    with pytest.raises(DetailizeError, match="objects other than tensors"):
        load_checkpoint(p)


def test_foreign_format(tmp_path):
    p = tmp_path / "f.pt"
    torch.save({"state_dict": {"w": torch.zeros(2)}}, p)
    with pytest.raises(DetailizeError, match="foreign file"):
        load_checkpoint(p)
    torch.save(torch.zeros(3), p)  # a bare tensor
    with pytest.raises(DetailizeError, match="foreign file"):
        load_checkpoint(p)


def _rewrite(path, **changes):
    raw = torch.load(path, weights_only=True)
    raw.update(changes)
    for k, v in list(raw.items()):
        if v is None:
            del raw[k]
    torch.save(raw, path)


@pytest.mark.parametrize("version, word", [(FORMAT_VERSION + 1, "newer"), (FORMAT_VERSION - 1, "older")])
def test_other_format_version(tmp_path, version, word):
    p = save_checkpoint(tmp_path / "m.pt", _ckpt())
    _rewrite(p, version=version)
    with pytest.raises(DetailizeError, match=word):
        load_checkpoint(p)


def test_state_missing_key(tmp_path):
    p = save_checkpoint(tmp_path / "m.pt", _ckpt())
    raw = torch.load(p, weights_only=True)
    del raw["generator"]["style_codes"]
    torch.save(raw, p)
    with pytest.raises(DetailizeError, match="missing.*style_codes") as e:
        load_checkpoint(p)
    assert e.value.field == "generator"


def test_state_wrong_shape(tmp_path):
    p = save_checkpoint(tmp_path / "m.pt", _ckpt())
    raw = torch.load(p, weights_only=True)
    raw["generator"]["style_codes"] = torch.zeros(8, 5)
    torch.save(raw, p)
    with pytest.raises(DetailizeError, match=r"style_codes.*\(8, 5\).*\(8, 3\)"):
        load_checkpoint(p)


def test_config_not_matching_weights(tmp_path):
    p = save_checkpoint(tmp_path / "m.pt", _ckpt())
    raw = torch.load(p, weights_only=True)
    meta = json.loads(raw["meta"])
    meta["config"]["backbone_widths"][0] += 1  # a config the weights were not trained with
    raw["meta"] = json.dumps(meta)
    torch.save(raw, p)
    with pytest.raises(DetailizeError, match="has shape"):
        load_checkpoint(p)


def test_bad_config_and_vocab_in_meta(tmp_path):
    p = save_checkpoint(tmp_path / "m.pt", _ckpt())
    raw = torch.load(p, weights_only=True)
    meta = json.loads(raw["meta"])
    del meta["config"]["n_parts"]
    raw["meta"] = json.dumps(meta)
    torch.save(raw, p)
    with pytest.raises(DetailizeError, match="missing key 'n_parts'") as e:
        load_checkpoint(p)
    assert e.value.file == str(p)

    p2 = save_checkpoint(tmp_path / "m2.pt", _ckpt())
    raw = torch.load(p2, weights_only=True)
    meta = json.loads(raw["meta"])
    meta["style_names"] = ["a", "b"]  # 2 names for 3 style codes
    raw["meta"] = json.dumps(meta)
    torch.save(raw, p2)
    with pytest.raises(DetailizeError, match="2 style names"):
        load_checkpoint(p2)


def test_non_finite_weights_refused(tmp_path):
    p = save_checkpoint(tmp_path / "m.pt", _ckpt())
    raw = torch.load(p, weights_only=True)
    raw["generator"]["style_codes"][0, 0] = float("nan")
    torch.save(raw, p)
    with pytest.raises(DetailizeError, match="not finite"):
        load_checkpoint(p)


def test_save_refuses_non_json_metadata_and_mismatched_state(tmp_path):
    ck = _ckpt()
    with pytest.raises(DetailizeError, match="not plain JSON"):
        save_checkpoint(tmp_path / "m.pt", dataclasses.replace(ck, training={"when": object()}))
    bad = dict(ck.generator)
    bad.pop("style_codes")
    with pytest.raises(DetailizeError, match="missing"):
        save_checkpoint(tmp_path / "m.pt", dataclasses.replace(ck, generator=bad))
    assert not (tmp_path / "m.pt").exists()
    with pytest.raises(DetailizeError, match="unknown parts"):
        dataclasses.replace(ck, style_parts=(("body",), ("roof",), ()))


def test_part_aliases_and_categories_round_trip(tmp_path):
    ck = dataclasses.replace(_ckpt(), part_aliases={"roof": "top", "pot": "body"},
                             style_categories=("building", "plant", "cake"))
    back = load_checkpoint(save_checkpoint(tmp_path / "a.pt", ck))
    assert back.part_aliases == {"pot": "body", "roof": "top"}
    assert back.style_categories == ("building", "plant", "cake")
    assert back.part_index() == {"body": 0, "top": 1, "roof": 1, "pot": 0}


@pytest.mark.parametrize("aliases, categories", [({"roof": "lid"}, ()), ({"top": "body"}, ()),
                                                 ({}, ("building",))])
def test_bad_aliases_or_categories_refused(aliases, categories):
    with pytest.raises(DetailizeError, match="alias|categor"):
        dataclasses.replace(_ckpt(), part_aliases=aliases, style_categories=categories)
