"""``decollage train`` end to end on a tiny style set made in code: files, previews, resume, errors."""

from __future__ import annotations

import json
from functools import partial

from typer.testing import CliRunner

from model.checkpoint import load_checkpoint
from cli.app import app
from stylesets.format import THINGS, ExemplarSpec, build_set
from stylesets.catalogues.prims import box, rod

R = 64


def _hut(height: float) -> dict:
    """body + roof of a tiny building (module level: picklable)."""
    return {"body": box((0.6, height, 0.6), (0, height / 2, 0)),
            "roof": [box((0.7, 0.08, 0.7), (0, height + 0.04, 0)), rod((0, height, 0), (0, height + 0.3, 0), 0.05)]}


def _tiny_set(tmp_path):
    specs = [ExemplarSpec("hut_low", "building", partial(_hut, 0.3), "hut 0.3"),
             ExemplarSpec("hut_tall", "building", partial(_hut, 0.6), "hut 0.6")]
    return build_set("huts", THINGS, specs, tmp_path / "huts.npz", resolution=R).path


def _train(set_path, out, steps, *extra):
    return CliRunner().invoke(app, ["train", "--set", str(set_path), "--out", str(out), "--steps", str(steps),
                                    "--resolution", str(R), "--preview-every", "2", "--checkpoint-every", "1",
                                    "--recon-early-iters", "0", "--device", "cpu", "--quiet", *extra])


def test_train_writes_model_log_previews_and_resumes(tmp_path):
    set_path, out = _tiny_set(tmp_path), tmp_path / "run"
    result = _train(set_path, out, 2)
    assert result.exit_code == 0, result.output
    ck = load_checkpoint(out / "model.pt")
    assert ck.style_names == ("hut_low", "hut_tall") and ck.part_names == ("bottom", "top")
    assert ck.part_aliases["roof"] == "top" and ck.part_aliases["body"] == "bottom"
    assert ck.style_categories == ("building", "building") and ck.training["step"] == 2
    assert ck.training["command"].startswith("decollage ")  # the command line is recorded
    lines = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines()]
    assert [x["step"] for x in lines] == [1, 2] and all(x["recon"] > 0 for x in lines)
    assert (out / "previews" / "step_000002.png").stat().st_size > 1000
    # Asking for more steps continues from last.pt: the log grows, nothing restarts.
    result = _train(set_path, out, 3)
    assert result.exit_code == 0, result.output
    lines = [json.loads(x) for x in (out / "log.jsonl").read_text().splitlines()]
    assert [x["step"] for x in lines] == [1, 2, 3]
    assert load_checkpoint(out / "model.pt").training["step"] == 3


def test_train_refuses_unknown_set_and_bad_settings(tmp_path, monkeypatch):
    monkeypatch.setenv("DECOLLAGE_STYLES_DIR", str(tmp_path / "styles"))
    result = CliRunner().invoke(app, ["train", "--set", "nosuchset", "--out", str(tmp_path / "r"), "--steps", "1"])
    assert result.exit_code == 2 and "unknown style set 'nosuchset'" in result.output
    assert "Traceback" not in result.output
    result = _train(_tiny_set(tmp_path), tmp_path / "r2", -1)
    assert result.exit_code == 2 and "steps" in result.output


def test_train_ablation_option_trains_the_named_row_and_records_it(tmp_path):
    set_path = _tiny_set(tmp_path)
    result = _train(set_path, tmp_path / "nop", 1, "--ablation", "no_pyramid", "--preview-every", "0")
    assert result.exit_code == 0, result.output
    ck = load_checkpoint(tmp_path / "nop" / "model.pt")
    assert not ck.config.pyramid and ck.config.supervised_levels == (3,) and len(ck.config.discriminators) == 1
    assert ck.training["ablation"] == "no_pyramid"
    full = load_checkpoint(tmp_path / "nop" / "last.pt")
    assert full.training["train_config"]["ablation"] == "no_pyramid"
    # Without the option the full model trains, recorded as such.
    result = _train(set_path, tmp_path / "full", 1, "--preview-every", "0")
    assert result.exit_code == 0, result.output
    ck = load_checkpoint(tmp_path / "full" / "model.pt")
    assert ck.config.pyramid and ck.training["ablation"] == "full"
    result = _train(set_path, tmp_path / "bad", 1, "--ablation", "no_such_row")
    assert result.exit_code == 2 and "no_such_row" in result.output and "decor_gan" in result.output


def test_train_recipe_option_records_the_recipe_and_a_resume_must_name_it(tmp_path):
    set_path, out = _tiny_set(tmp_path), tmp_path / "warm"
    result = _train(set_path, out, 1, "--recipe", "warmup", "--preview-every", "0")
    assert result.exit_code == 0, result.output
    ck = load_checkpoint(out / "last.pt")
    assert ck.training["recipe"] == "warmup" and ck.config.output_mask and ck.config.min_cell_fill == 0.5
    assert ck.training["train_config"]["warmup_iters"] > 1 and ck.config.style_init_std > 0
    result = _train(set_path, out, 2, "--preview-every", "0")  # the reference recipe: another run
    assert result.exit_code == 2 and "another config" in result.output


def test_train_ema_option_writes_the_average_beside_the_model_and_refuses_a_bad_beta(tmp_path):
    set_path, out = _tiny_set(tmp_path), tmp_path / "ema"
    result = _train(set_path, out, 2, "--ema-decay", "0.9", "--preview-every", "0")
    assert result.exit_code == 0, result.output
    average, last = load_checkpoint(out / "model_ema.pt"), load_checkpoint(out / "model.pt")
    assert average.training["weights"] == {"ema_decay": 0.9, "ema_started_at": 0}
    assert any(not (average.generator[k] == last.generator[k]).all() for k in last.generator)
    assert load_checkpoint(out / "last.pt").training["train_config"]["ema_decay"] == 0.9
    result = _train(set_path, tmp_path / "bad", 1, "--ema-decay", "1.5")
    assert result.exit_code == 2 and "ema_decay" in result.output and "Traceback" not in result.output
