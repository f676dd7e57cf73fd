"""A 2-step CPU training smoke test on a tiny config, resuming, and refusal of a foreign resume."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from model.checkpoint import load_checkpoint
from model.config import ModelConfig
from model.data import Exemplar
from model.infer import DecollageDetailizer
from model.networks import Generator
from model.train import TrainConfig, train
from core.errors import DetailizeError
from core.grid import EMPTY, LabeledGrid

R = 64
PARTS = ("bottom", "top")


def _box(name, size, split, holes):
    lab = np.full((R, R, R), EMPTY, dtype=np.int16)
    x, y, z = size
    h = int(y * split)
    lab[2 : 2 + x, 1 : 1 + h, 3 : 3 + z] = 0
    lab[2 : 2 + x, 1 + h : 1 + y, 3 : 3 + z] = 1
    lab[2 : 2 + x : holes, 1 + h : 1 + y, 3 : 3 + z : holes] = EMPTY  # some "detail" in the top part
    return Exemplar(name, "thing", lab, PARTS, resolution=R)


EXS = [_box("crate", (38, 32, 26), 0.5, 4), _box("tower", (20, 44, 20), 0.3, 3)]


def _cfg() -> ModelConfig:
    return ModelConfig.lean(2, 2).scaled(0.125)  # widths 8 / 4 / 2 generator, 1–4 discriminators


def _tcfg(tmp_path, steps, **kw) -> TrainConfig:
    args = dict(out_dir=str(tmp_path / "run"), steps=steps, resolution=R, device="cpu", seed=3,
                recon_steps_early=2, recon_early_iters=1, checkpoint_every=1, command="pytest")
    return TrainConfig(**{**args, **kw})


def _log(path):
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_two_steps_finite_checkpoint_loads_and_resume_continues(tmp_path):
    res = train(EXS, _cfg(), _tcfg(tmp_path, 2), resume=False)
    assert res.step == 2 and res.seconds_per_iteration > 0
    log = _log(res.log)
    assert [r["step"] for r in log] == [1, 2]
    for row in log:
        for key in ("recon", "gan", "down", "up", "g_total", "d_real", "d_fake", "d_total"):
            assert np.isfinite(row[key]), key
        assert row["d_total"] > 0 and row["recon"] > 0
    ck = load_checkpoint(res.checkpoint, training_state=True)
    assert ck.training["step"] == 2 and ck.training["seed"] == 3 and ck.training["command"] == "pytest"
    assert ck.style_names == ("crate", "tower") and ck.part_names == PARTS
    assert ck.style_parts == (PARTS, PARTS) and ck.optimizers and ck.discriminators
    shipped = load_checkpoint(res.model)
    assert shipped.discriminators is None and shipped.training["step"] == 2

    # The trained generator is a working detailizer.
    occ = np.zeros((2, 3, 2), dtype=bool)
    occ[:, :2] = True
    part = np.where(occ, 0, EMPTY).astype(np.int16)
    style = np.where(occ, 1, EMPTY).astype(np.int16)
    fine = DecollageDetailizer(str(res.model), "cpu").detailize(LabeledGrid(occ, part, style, PARTS, ("crate", "tower"), 1.0))
    assert fine.shape == (32, 48, 32)

    # Resume continues from step 2 to step 3 (rows a stopped run logged after its last checkpoint are dropped) ...
    with open(res.log, "a", encoding="utf-8") as f:
        f.write(json.dumps({"step": 3, "recon": 9.9}) + "\n")
    res3 = train(EXS, _cfg(), _tcfg(tmp_path, 3))
    assert res3.step == 3 and [r["step"] for r in _log(res3.log)] == [1, 2, 3]
    assert _log(res3.log)[-1]["recon"] != 9.9
    # ... and ends where an unbroken 3-step run ends (data is a function of (seed, step); state restored).
    ref = train(EXS, _cfg(), dataclasses.replace(_tcfg(tmp_path, 3), out_dir=str(tmp_path / "ref")), resume=False)
    a = load_checkpoint(res3.checkpoint).generator
    b = load_checkpoint(ref.checkpoint).generator
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=1e-5, atol=1e-6)


def test_resume_refuses_another_config(tmp_path):
    train(EXS, _cfg(), _tcfg(tmp_path, 1, recon_steps_early=1), resume=False)
    other = ModelConfig.lean(2, 2).scaled(0.25)
    with pytest.raises(DetailizeError, match="another config"):
        train(EXS, other, _tcfg(tmp_path, 2))


@pytest.mark.parametrize("whole_levels", [0, 2, 3])
def test_window_forward_equals_whole_shape_on_the_window(whole_levels):
    from model.networks import Generator
    from model.train import window_forward

    cfg = _cfg()
    torch.manual_seed(0)
    gen = Generator(cfg)
    g = torch.Generator().manual_seed(1)
    shape = (10, 5, 11)
    occ = torch.rand(1, *shape, generator=g) > 0.4
    ins = gen.make_inputs(occ, torch.randint(0, 2, (1, *shape), generator=g), torch.randint(0, 2, (1, *shape), generator=g))
    window = (slice(0, 4), slice(1, 5), slice(4, 8))  # touches the grid border on x and y, interior on z
    with torch.no_grad():
        dense = gen(*ins)
        win = window_forward(gen, *ins, whole_levels, window)
    for j, (d, w) in enumerate(zip(dense, win)):
        if j < whole_levels:
            assert w.shape == d.shape
            torch.testing.assert_close(w, d)
        else:
            r = 2 ** (j + 1)
            ref = d[:, :, *(slice(s.start * r, s.stop * r) for s in window)]
            assert w.shape == ref.shape == (1, 1, 4 * r, 4 * r, 4 * r)
            torch.testing.assert_close(w, ref, rtol=1e-5, atol=1e-6)


def test_surface_window_and_window_check():
    from model.train import check_window, halo_cells, surface_window
    from model.data import rng_for

    occ = np.zeros((9, 3, 9), dtype=bool)
    occ[2:7, 1, 2:7] = True
    for step in range(5):
        w = surface_window(occ, 4, rng_for(0, step))
        assert [s.stop - s.start for s in w] == [4, 3, 4]  # whole axis where the grid is smaller
        assert occ[w].any()
    with pytest.raises(DetailizeError, match="too small"):
        check_window(_cfg(), 2, 1)
    check_window(_cfg(), 2, 4)
    assert halo_cells(_cfg(), 2) == 1 and halo_cells(_cfg(), 0) == 3


def test_dense_training_without_windows(tmp_path):
    res = train(EXS, _cfg(), _tcfg(tmp_path, 1, recon_steps_early=1, window_cells=0), resume=False)
    assert np.isfinite(list(res.last_losses.values())).all()


def test_bad_training_settings_refused(tmp_path):
    with pytest.raises(DetailizeError, match="recon_steps_early") as e:
        _tcfg(tmp_path, 1, recon_steps_early=9)
    assert e.value.field == "recon_steps_early" and e.value.hint
    with pytest.raises(DetailizeError, match="checkpoint_every"):
        _tcfg(tmp_path, 1, checkpoint_every=0)


@pytest.mark.parametrize("whole_levels, block", [(2, 2), (1, 3), (3, 2)])
def test_blockwise_forward_equals_dense(whole_levels, block):
    from model.windows import blockwise_forward

    torch.manual_seed(0)
    cfg = ModelConfig.lean(2, 2).scaled(0.25)
    gen = Generator(cfg).eval()
    occ = torch.zeros(1, 5, 4, 6)
    occ[0, 1:4, 0:3, 1:5] = 1
    parts = (torch.arange(4).view(1, 1, 4, 1) >= 2).long().expand(1, 5, 4, 6).contiguous()
    styles = (torch.arange(6).view(1, 1, 1, 6) >= 3).long().expand(1, 5, 4, 6).contiguous()
    with torch.no_grad():
        ins = gen.make_inputs(occ, parts, styles)
        dense = gen(*ins, final_only=True)[-1]
        blocks = blockwise_forward(gen, *ins, block_cells=block, whole_levels=whole_levels, skip_empty=False)
    assert blocks.shape == dense.shape == (1, 1, 80, 64, 96)
    torch.testing.assert_close(blocks, dense, atol=1e-5, rtol=0)


def test_blockwise_skips_only_blocks_far_from_the_shape():
    from model.windows import blockwise_forward, halo_cells

    torch.manual_seed(1)
    cfg = ModelConfig.lean(2, 2).scaled(0.25)
    gen = Generator(cfg).eval()
    occ = torch.zeros(1, 12, 2, 2)
    occ[0, 0:2] = 1  # only at the start of a long grid: the far blocks have nothing near them
    lab = torch.zeros(1, 12, 2, 2, dtype=torch.long)
    with torch.no_grad():
        ins = gen.make_inputs(occ, lab, lab)
        dense = gen(*ins, final_only=True)[-1]
        sparse = blockwise_forward(gen, *ins, block_cells=2, whole_levels=2, skip_empty=True)
    assert halo_cells(cfg, 2) == 1
    # Blocks [0, 2) and [2, 4) have occupied cells within 1 cell: computed; from cell 4 on: skipped.
    torch.testing.assert_close(sparse[..., :64, :, :], dense[..., :64, :, :], atol=1e-5, rtol=0)
    assert torch.count_nonzero(sparse[..., 64:, :, :]) == 0 and torch.count_nonzero(dense[..., 64:, :, :]) > 0


def test_train_config_recorded_reads_a_states_json_settings_and_applies_checked_changes(tmp_path):
    from model.strict_json import to_plain

    tcfg = _tcfg(tmp_path, 3)
    settings = json.loads(json.dumps(to_plain(tcfg)))  # as a state file holds them: betas a list
    assert isinstance(settings["betas"], list)
    assert TrainConfig.recorded(settings) == tcfg
    changed = TrainConfig.recorded(settings, steps=7, monitor_every=0)
    assert changed == dataclasses.replace(tcfg, steps=7, monitor_every=0)
    with pytest.raises(DetailizeError, match="steps"):
        TrainConfig.recorded(settings, steps=-1)
