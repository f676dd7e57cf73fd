"""The evaluation protocol (evaluation/protocol.py) and ``decollage eval`` on a tiny protocol and style set."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from evaluation.cls_score import ClsConfig
from cli.app import app
from evaluation.protocol import (
    DEFAULT_PROTOCOL,
    ProtocolError,
    check_detailizer,
    load_protocol,
    style_assignments,
    write_protocol,
)
from stylesets.format import THINGS, Exemplar, encode_set, load_set

RUNNER = CliRunner()
R = 64  # tiny set resolution: 4³ coarse contents → 64³ outputs
TINY_STYLES = (("blocky", "building"), ("ridged", "plant"), ("stepped", "cake"))


@pytest.fixture(autouse=True)
def _one_thread(monkeypatch):
    before = torch.get_num_threads()
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _exemplar(i: int, name: str, category: str) -> Exemplar:
    """A 64³ two-part exemplar with its own surface texture (bottom = label 1, top = label 2)."""
    lab = np.zeros((R, R, R), np.uint8)
    lab[12:52, 6:36, 12:52] = 1
    lab[16:48, 36:54, 16:48] = 2
    x, y, z = np.meshgrid(*[np.arange(R)] * 3, indexing="ij")
    period = 3 + 2 * i
    lab[((x + y + z) % period == 0) & (lab == 1) & ((x < 14) | (x > 49) | (z < 14) | (z > 49))] = 0  # grooves
    idx = np.argwhere(lab)
    lo, hi = idx.min(axis=0), idx.max(axis=0) + 1
    crop = lab[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    return Exemplar(crop, tuple(int(v) for v in lo),
                    {"name": name, "category": category, "shape": list(crop.shape), "offset": [int(v) for v in lo]})


def _content(seed: int) -> np.ndarray:
    """A 4³-with-margin coarse content: a 2×1×2 bottom under a 2×1×2 top, plus a random extra cell."""
    lab = np.full((4, 4, 4), -1, np.int8)
    lab[1:3, 1, 1:3] = 0
    lab[1:3, 2, 1:3] = 1
    if seed % 2:
        lab[1, 2, 2] = -1
    return lab


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    """A tiny style set (3 exemplars at 64³) and a protocol of 3 contents × (2 single + 2 mixed) = 12 outputs."""
    folder = tmp_path_factory.mktemp("tiny_protocol")
    exemplars = [_exemplar(i, n, c) for i, (n, c) in enumerate(TINY_STYLES)]
    (folder / "tiny.npz").write_bytes(encode_set("tiny", THINGS, R, "tiny-hash", exemplars))
    style_set = load_set(folder / "tiny.npz")
    made = [(f"c{k}", "cad", {"note": "hand-made"}, _content(k)) for k in range(3)]
    return write_protocol("tiny_v1", folder, "tiny.npz", style_set, made, n_single=2, n_mixed=2)


@pytest.fixture
def tiny_cls(monkeypatch):
    """Make the 'quick' Cls variant tiny (fast enough for a unit test)."""
    from evaluation import cls_score

    small = ClsConfig("quick", n_views=4, test_views=1, steps=10, batch=8, width=2, crop=32, test_crops=2)
    monkeypatch.setitem(cls_score.CLS_VARIANTS, "quick", small)


def _tiny_checkpoint(path: Path, styles: tuple[str, ...]) -> Path:
    from model.checkpoint import Checkpoint, save_checkpoint
    from model.config import ModelConfig
    from model.networks import Generator

    cfg = ModelConfig.lean(2, len(styles)).scaled(0.125)
    torch.manual_seed(0)
    gen = Generator(cfg)
    with torch.no_grad():  # a field mostly above iso: random weights alone give specks, which inference removes
        gen.levels[-1].up.bias.add_(0.5)
    ck = Checkpoint(cfg, styles, ("bottom", "top"), (("bottom", "top"),) * len(styles), gen.state_dict(),
                    {"step": 0})
    return save_checkpoint(path, ck)


# --------------------------------------------------------------------------- the shipped protocol


@pytest.mark.e2e  # builds the 256³ things set
def test_shipped_protocol_is_20_contents_by_16_styles():
    from stylesets.registry import builtin_set

    p = load_protocol(DEFAULT_PROTOCOL)
    assert len(p.contents) == 20 and len(p.outputs) == 320
    assert len({o.id for o in p.outputs}) == 320 and [o.index for o in p.outputs] == list(range(320))
    per_content = Counter(o.content for o in p.outputs)
    assert set(per_content.values()) == {16}
    assert all(sum(o.mixed for o in p.outputs if o.content == c) == 8 for c in p.contents)
    kinds = Counter(info["kind"] for info in p.content_info.values())
    assert set(kinds) == {"text", "cad", "mesh", "voxels", "augmented_exemplar"} and kinds["augmented_exemplar"] == 8
    for cid, lab in p.contents.items():  # at most 16³ (256³ fine), both parts present, one empty cell a side
        assert max(lab.shape) <= 16 and set(np.unique(lab)) == {-1, 0, 1}, cid
        assert (lab[0] == -1).all() and (lab[-1] == -1).all() and (lab[:, :, 0] == -1).all()
    # the styles are the 'things' set's exemplars, and each is the single style of 8 outputs
    assert list(p.styles) == [s.name for s in builtin_set("things")[1]]
    single = Counter(o.styles["bottom"] for o in p.outputs if not o.mixed)
    assert set(single) == set(p.styles) and set(single.values()) == {8}


@pytest.mark.e2e  # builds the 256³ things set
def test_output_grid_carries_the_assignment():
    p = load_protocol(DEFAULT_PROTOCOL)
    o = next(o for o in p.outputs if o.mixed)
    g = p.grid(o)
    lab = p.contents[o.content]
    assert g.part_names == ("bottom", "top") and np.array_equal(g.occupancy, lab >= 0)
    for part_index, part in enumerate(g.part_names):
        used = {g.style_names[s] for s in np.unique(g.style[lab == part_index])}
        assert used == {o.styles[part]}


def test_style_assignments_single_then_mixed():
    rows = style_assignments(["a", "b", "c", "d"], 2, ("bottom", "top"), seed=1, n_single=2, n_mixed=3)
    assert [r["bottom"] for r in rows[0][:2]] == ["a", "b"] and [r["bottom"] for r in rows[1][:2]] == ["c", "d"]
    for per in rows:
        mixed = per[2:]
        assert all(r["bottom"] != r["top"] for r in mixed)
        assert len({tuple(r.items()) for r in mixed}) == 3
    assert rows == style_assignments(["a", "b", "c", "d"], 2, ("bottom", "top"), seed=1, n_single=2, n_mixed=3)


def test_protocol_refuses_damaged_or_inconsistent_files(tiny, tmp_path):
    with pytest.raises(ProtocolError, match="not found"):
        load_protocol(tmp_path / "nope.json")
    meta = json.loads(tiny.read_text())
    folder = tmp_path / "p"
    folder.mkdir()
    (folder / "tiny_v1.npz").write_bytes((tiny.parent / "tiny_v1.npz").read_bytes() + b"x")
    (folder / "p.json").write_text(json.dumps(meta))
    with pytest.raises(ProtocolError, match="does not match the hash"):
        load_protocol(folder / "p.json")
    (folder / "tiny_v1.npz").write_bytes((tiny.parent / "tiny_v1.npz").read_bytes())
    meta["outputs"][3]["styles"]["top"] = "gothic"
    (folder / "p.json").write_text(json.dumps(meta))
    with pytest.raises(ProtocolError, match="gothic") as err:
        load_protocol(folder / "p.json")
    assert err.value.field == "outputs[3]"


def test_check_detailizer_names_unknown_styles(tiny):
    p = load_protocol(tiny)

    class Known:
        name = "stub"
        style_names = ("blocky", "other")
        part_names = ("bottom", "top")

    with pytest.raises(ProtocolError, match="2 style\\(s\\).*ridged, stepped"):
        check_detailizer(p, Known())
    Known.style_names = None  # accepts any name (the upsample baseline)
    check_detailizer(p, Known())


# --------------------------------------------------------------------------- decollage eval


def test_eval_upsample_writes_json_and_markdown(tiny, tmp_path, tiny_cls):
    out = tmp_path / "ev"
    res = RUNNER.invoke(app, ["eval", "--detailizer", "upsample", "--protocol", str(tiny), "--limit", "2",
                              "--cls", "quick", "--threads", "1", "--device", "cpu", "--out", str(out),
                              "--doc", str(tmp_path / "docs" / "benchmarks.md")])
    assert res.exit_code == 0, res.output
    report = json.loads((out / "eval.json").read_text())
    p = load_protocol(tiny)
    test_ids = [o.id for o in p.outputs_of("test")]
    assert report["protocol"]["split"] == "test" and report["protocol"]["in_split"] == len(test_ids) < 12
    assert report["protocol"]["evaluated"] == 2
    assert [r["id"] for r in report["outputs"]] == [test_ids[0], test_ids[len(test_ids) // 2]]  # spread
    assert all(r["split"] == "test" for r in report["outputs"])
    # the baseline keeps the coarse structure exactly: its ×16 max-pool is the content
    assert report["means"]["strict_iou"] == 1.0 and report["means"]["loose_iou"] == 1.0
    est = report["estimates"]
    for key in ("lp_detail", "lp_detail_all", "lp_iou", "lp_f", "selfrec_iou", "selfrec_lp_iou", "matched_cls"):
        assert 0.0 <= est[key]["mean"] <= 1.0, key
    assert est["lp_detail"]["mean"] <= est["lp_detail_all"]["mean"] <= est["lp_iou"]["mean"]
    # self-reconstruction: every exemplar as itself, then N_AUG held-out augmentations of each
    from evaluation.selfrec import N_AUG
    cases = report["selfrec"]
    assert len(cases) == 3 * (1 + N_AUG) and sum(c["held_out"] for c in cases) == 3 * N_AUG
    assert report["classifiers"]["matched_cls"]["real_shapes"] == 3 * N_AUG
    assert report["classifiers"]["paper_cls"]["fake_shapes"] == 2
    assert report["timings"]["peak_rss_gb"] > 0 and report["timings"]["total_s"] > 0
    assert report["style_set"]["matches_protocol"] is True and report["vs_baseline"] is None
    md = (out / "eval.md").read_text()
    assert "| **LP-detail** (own style; the primary figure) |" in md and "not the bar" in md
    assert "| Strict-IOU | 1.000 [1.000, 1.000] |" in md and "Classifiers: **quick**" in md
    doc = (tmp_path / "docs" / "benchmarks.md").read_text()
    assert "<!-- decollage:eval:upsample:begin -->" in doc and "LP-detail" in doc


def test_eval_learned_checkpoint_paired_against_the_baseline(tiny, tmp_path):
    base = tmp_path / "base"
    res = RUNNER.invoke(app, ["eval", "--detailizer", "upsample", "--protocol", str(tiny), "--cls", "none",
                              "--no-self-rec", "--threads", "1", "--device", "cpu", "--out", str(base)])
    assert res.exit_code == 0, res.output
    ckpt = _tiny_checkpoint(tmp_path / "tiny.pt", tuple(n for n, _ in TINY_STYLES))
    res = RUNNER.invoke(app, ["eval", "--checkpoint", str(ckpt), "--protocol", str(tiny), "--cls", "none",
                              "--no-self-rec", "--threads", "1", "--device", "cpu", "--out", str(tmp_path / "ev"),
                              "--baseline", str(base / "eval.json")])
    assert res.exit_code == 0, res.output
    report = json.loads((tmp_path / "ev" / "eval.json").read_text())
    baseline = json.loads((base / "eval.json").read_text())
    assert report["detailizer"]["name"] == "decollage" and report["classifiers"] == {}
    assert report["selfrec"] == [] and report["cls_variant"] == "none"
    vs = report["vs_baseline"]
    assert vs["detailizer"] == "upsample"
    # upsample is style-blind: its single-style outputs of one content are identical; mixed ones get no figure
    assert baseline["estimates"]["style_overlap"]["mean"] == 1.0
    assert all((r.get("style_overlap") is None) == r["mixed"] for r in baseline["outputs"])
    for key in ("strict_iou", "lp_iou", "lp_detail", "style_overlap"):
        want = report["estimates"][key]["mean"] - baseline["estimates"][key]["mean"]
        assert vs[key]["mean"] == pytest.approx(want, abs=1e-12), key
    res = RUNNER.invoke(app, ["eval", "--compare", str(base / "eval.json"), "--compare", str(tmp_path / "ev" / "eval.json"),
                              "--doc", str(tmp_path / "b.md")])
    assert res.exit_code == 0, res.output
    table = (tmp_path / "b.md").read_text()
    assert "| figure | upsample | decollage (tiny.pt) |" in table and "<br>Δ " in table


def _fails(args: list[str], *needles: str) -> None:
    res = RUNNER.invoke(app, ["eval", "--threads", "1", "--device", "cpu", *args])
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output and "error:" in res.output
    for needle in needles:
        assert needle in res.output, res.output


def test_eval_errors_are_one_line(tiny, tmp_path):
    _fails(["--checkpoint", str(tmp_path / "missing.pt"), "--protocol", str(tiny)], "checkpoint not found")
    wrong = _tiny_checkpoint(tmp_path / "wrong.pt", ("tower", "tree", "cake"))
    _fails(["--checkpoint", str(wrong), "--protocol", str(tiny), "--out", str(tmp_path / "o")],
           "does not know", "blocky")
    assert not (tmp_path / "o" / "eval.json").exists()
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    _fails(["--detailizer", "upsample", "--protocol", str(tiny), "--out", str(blocker / "sub")], str(blocker))
    _fails(["--protocol", str(tiny)], "--checkpoint")
    _fails(["--detailizer", "upsample", "--checkpoint", str(wrong), "--protocol", str(tiny)], "no checkpoint")
    _fails(["--detailizer", "upsample", "--protocol", str(tmp_path / "none.json")], "protocol file not found")


# --------------------------------------------------------------------------- decollage bench


def test_doc_sections_are_replaced_in_place(tmp_path):
    from evaluation.benchmarking import write_doc_section

    doc = tmp_path / "docs" / "benchmarks.md"
    doc.parent.mkdir()
    write_doc_section(doc, "bench", "speed v1")
    write_doc_section(doc, "eval:upsample", "table A")
    write_doc_section(doc, "bench", "speed v2\nsecond line")
    text = doc.read_text()
    assert text.startswith("# Benchmarks\n") and "speed v1" not in text
    assert text.index("speed v2\nsecond line") < text.index("table A")  # the section kept its place
    assert text.count("<!-- decollage:bench:begin -->") == 1 and text.count("<!-- decollage:eval:upsample:end -->") == 1


@pytest.mark.e2e  # a benchmark child process
def test_bench_measures_in_a_child_and_formats(tmp_path):
    from evaluation.evaluate import machine_info
    from cli.bench import bench_markdown
    from evaluation.benchmarking import measure_detailizer

    r = measure_detailizer("upsample", "cpu", repeats=1, threads=1)
    assert r["device"] == "cpu" and r["threads"] == 1 and 0 < r["median_s"] < 30 and r["peak_rss_gb"] > 0.05
    assert 0 < r["median_cpu_s"] < 30
    assets = [{"recipe": "r.yaml", "asset": "a", "detailizer": "upsample", "fine_grid": [256, 128, 64],
               "stages_s": dict.fromkeys(("source", "voxelize", "regions", "detailize", "mesh", "export"), 0.5),
               "total_s": 3.0, "triangles": 1234, "repeats": 1, "glb_bytes": 204800}]
    train = {"iterations": 2, "resolution": 256, "layout": "lean", "device": "cpu", "threads": 2,
             "early_s": 5.25, "later_s": 2.5}
    reference = {"median_s": 0.25, "load_average": [1.0, 1.0, 1.0]}
    md = bench_markdown(machine_info(), [r], assets, train, "random-lean", reference)
    assert "| upsample (baseline) | cpu | 1 |" in md and "| r.yaml | a | upsample | 256×128×64 |" in md
    assert "| 3.00 | 12.0 | 1234 | 200 |" in md and "0.250 s" in md  # total, × reference, triangles, GLB KB
    # a row's own reference (timed around that asset's builds) wins over the run's
    md = bench_markdown(machine_info(), [r], [{**assets[0], "reference_s": 0.3}], train, "random-lean", reference)
    assert "| 3.00 | 10.0 | 1234 | 200 |" in md
    assert "| early (4 reconstruction steps + 1 adversarial) | 5.25 |" in md and "cores" in md


def test_reference_workload_times_the_same_surface_every_run():
    from evaluation.benchmarking import reference_workload_seconds

    first, second = reference_workload_seconds(repeats=1), reference_workload_seconds(repeats=1)
    assert first["faces"] == second["faces"] > 300_000  # the same 256³ sphere, radius 100
    assert 0 < first["min_s"] <= first["median_s"] and first["median_cpu_s"] > 0


def test_bench_errors_are_one_line(tmp_path):
    res = RUNNER.invoke(app, ["bench", "--checkpoint", str(tmp_path / "missing.pt"), "--out", str(tmp_path / "b.md")])
    assert res.exit_code == 2 and "checkpoint not found" in res.output and "Traceback" not in res.output
    blocker = tmp_path / "file"
    blocker.write_text("x")
    res = RUNNER.invoke(app, ["bench", "--out", str(blocker / "b.md"), "--no-assets", "--train-iterations", "0"])
    assert res.exit_code == 2 and str(blocker) in res.output and "Traceback" not in res.output


def test_ablation_presets_change_one_thing_each(tmp_path):
    from model.ablations import ABLATIONS, ablation_configs
    from model.config import DownLoss, ModelConfig
    from model.train import TrainConfig

    cfg, tcfg = ModelConfig.lean(2, 20), TrainConfig(out_dir=str(tmp_path), steps=1)
    changed = {}
    for name in ABLATIONS:
        m, t = ablation_configs(name, cfg, tcfg)
        ModelConfig.from_dict(m.to_dict())  # still a valid, serialisable config
        diff = {k for k in ("losses", "use_part_labels", "pyramid") if getattr(m, k) != getattr(cfg, k)}
        diff |= {k for k in ("adaptive_alpha",) if getattr(t, k) != getattr(tcfg, k)}
        changed[name] = diff
    assert changed == {"full": set(), "no_down": {"losses"}, "no_up": {"losses"},
                       "no_adaptive_alpha": {"adaptive_alpha"}, "paper_losses": {"losses"},
                       "no_part_labels": {"use_part_labels"}, "no_pyramid": {"pyramid"},
                       "decor_gan": {"pyramid", "losses", "adaptive_alpha"}}
    assert ablation_configs("no_down", cfg, tcfg)[0].losses.gamma_down == 0.0
    assert ablation_configs("paper_losses", cfg, tcfg)[0].losses.down_loss is DownLoss.PAPER_MSE
    with pytest.raises(KeyError, match="known"):
        ablation_configs("no_such_row", cfg, tcfg)
    no_p = ablation_configs("no_pyramid", cfg, tcfg)[0]
    assert no_p.supervised_levels == (3,) and no_p.discriminators == cfg.discriminators[-1:]
    assert no_p.levels == cfg.levels and no_p.losses == cfg.losses  # the losses stay, at ×16
    decor = ablation_configs("decor_gan", cfg, tcfg)[0].losses
    assert decor.gamma_down == decor.gamma_up == 0.0


def test_markdown_names_the_ablation_a_checkpoint_was_trained_as():
    from evaluation.evaluate import markdown

    def report(training):
        return {"detailizer": {"name": "decollage", "checkpoint": "/x/row.pt", "training": training},
                "estimates": {}, "timings": {"total_s": 1.0, "per_output_all_in_s": 1.0}, "machine": {},
                "protocol": {"name": "p", "evaluated": 1, "outputs": 1}, "cls_variant": "none", "classifiers": {},
                "groups": {}, "style_set": {"matches_protocol": True}}

    assert "### Evaluation: decollage (row.pt), ablation `decor_gan` on p" in markdown(report({"ablation": "decor_gan"}))
    assert "### Evaluation: decollage (row.pt) on p" in markdown(report({"ablation": "full"}))
    assert "### Evaluation: decollage (row.pt) on p" in markdown(report({}))


def test_contact_sheet_has_one_column_per_detailizer_and_fixed_rows(tiny, tmp_path):
    from PIL import Image

    from evaluation.contact_sheet import CELL, HEADER_H, LABEL_W, N_MIXED_ROWS, N_SINGLE_ROWS, sheet_rows

    p = load_protocol(tiny)
    sset = __import__("evaluation.protocol", fromlist=["x"]).resolve_protocol_set(p)
    outputs, cases = sheet_rows(p, sset)
    assert [o.mixed for o in outputs] == [False] * N_SINGLE_ROWS + [True] * N_MIXED_ROWS
    assert {o.content for o in outputs} <= set(p.split["test"])
    assert len(cases) == 3 and all(c.held_out for c in cases)  # one per category (the tiny set has 3)
    assert sheet_rows(p, sset)[0] == outputs  # fixed
    res = RUNNER.invoke(app, ["eval", "--sheet", str(tmp_path / "docs" / "sheet.png"), "--protocol", str(tiny),
                              "--sheet-detailizers", "upsample,upsample", "--threads", "1", "--device", "cpu"])
    assert res.exit_code == 0, res.output
    img = Image.open(tmp_path / "docs" / "sheet.png")
    assert img.size == (LABEL_W + CELL * 3, HEADER_H + CELL * (len(outputs) + len(cases)))
    pixels = np.asarray(img)
    first_cell = pixels[HEADER_H:HEADER_H + CELL, LABEL_W:LABEL_W + CELL]
    assert (first_cell < 255).mean() > 0.02  # a shape was drawn
    truth_of_first_output = pixels[HEADER_H + 1:HEADER_H + CELL, LABEL_W + 2 * CELL:]  # below the row line
    assert (truth_of_first_output == 255).all()  # protocol outputs have no true shape
