"""The learned detailizer's provenance: the set recorded at training (or found from the command), the exemplars used."""

from __future__ import annotations

import torch

from core.provenance import EXEMPLARS, STYLE_SET, STYLE_SET_DIGEST, ExemplarCredit
from model.checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from model.config import ModelConfig
from model.infer import DecollageDetailizer
from model.networks import Generator
from model.provenance import checkpoint_style_set
from model.train import train
from stylesets.provenance import StyleSetRecord, builtin_record
from tests.model.test_infer import _grid
from tests.model.test_train import EXS, _cfg, _tcfg

STYLES = ("tower", "tree", "cake")
RECORD = StyleSetRecord("mine", "abc123", {
    "tower": ExemplarCredit("tower", "mine", "CC-BY-4.0", "Tower by A. Artist", "user"),
    "tree": ExemplarCredit("tree", "mine", "CC0-1.0", "", "user"),
    "cake": ExemplarCredit("cake", "mine", "CC-BY-4.0", "Cake by B. Baker", "user")})


def test_recorded_set_wins_then_the_command_then_unknown():
    record, origin = checkpoint_style_set({"style_set": RECORD.to_json(), "command": "decollage train --set x"})
    assert origin == "checkpoint" and record == RECORD
    record, origin = checkpoint_style_set({"command": "decollage train --set things --out o --steps 5"})
    assert origin == "registry" and record.name == "things" and record.digest == builtin_record("things").digest
    assert checkpoint_style_set({"command": "decollage train --out o --steps 5"})[0].name == "things"  # the default
    assert checkpoint_style_set({"command": "decollage train --set /x/set.npz"}) == (None, "unknown")
    assert checkpoint_style_set({"command": "pytest"}) == (None, "unknown")


def test_detailizer_reports_the_exemplars_of_the_styles_assigned(tmp_path):
    cfg = ModelConfig.lean(2, len(STYLES)).scaled(0.125)
    torch.manual_seed(0)
    ck = Checkpoint(cfg, STYLES, ("body", "roof"), (("body", "roof"),) * 3, Generator(cfg).state_dict(),
                    {"step": 0, "style_set": RECORD.to_json()})
    det = DecollageDetailizer(save_checkpoint(tmp_path / "tiny.pt", ck), device="cpu")
    fine = det.detailize(_grid(style_names=("cake", "tower", "tree"), style_of=(0, 1)))  # tree is not assigned
    assert [c["name"] for c in fine.extras[EXEMPLARS]] == ["cake", "tower"]
    assert fine.extras[EXEMPLARS][0] == {"name": "cake", "style_set": "mine", "licence": "CC-BY-4.0",
                                         "attribution": "Cake by B. Baker", "source": "user", "requires": "attribution"}
    assert fine.extras[STYLE_SET] == "mine" and fine.extras[STYLE_SET_DIGEST] == "abc123"
    assert det.describe()["style_set"] == {"name": "mine", "digest": "abc123", "from": "checkpoint"}


def test_shipped_model_credits_the_things_set():
    det = DecollageDetailizer(device="cpu")
    grid = _grid(shape=(3, 3, 3), style_names=("cottage", "fern"), part_names=("body", "roof"))
    fine = det.detailize(grid)
    assert {c["name"] for c in fine.extras[EXEMPLARS]} <= {"cottage", "fern"}
    assert all(c["style_set"] == "things" and c["requires"] == "none" for c in fine.extras[EXEMPLARS])
    assert det.describe()["style_set"]["from"] == "registry"  # trained before checkpoints recorded the set


def test_training_records_the_set_in_the_checkpoints(tmp_path):
    res = train(EXS, _cfg(), _tcfg(tmp_path, 1, recon_steps_early=1), resume=False, style_set=RECORD.to_json())
    for path in (res.model, res.checkpoint):
        assert load_checkpoint(path, training_state=path == res.checkpoint).training["style_set"] == RECORD.to_json()
