"""Run an evaluation protocol through a detailizer: detail figures first, the paper's beside them.

Per output of the protocol's chosen split (content × style assignment of
``evaluation.protocol``; ``split="test"`` for acceptance figures, "dev" for
choices, None for every output):

* the detailizer's fine output, binarised at ISO_LEVEL (0.4);
* Strict-IOU and Loose-IOU against the coarse content (max-pool ×16);
* 1000 surface patches (seed = the output's index), each owned by the style
  of the coarse region at its centre, for LP-detail, style specificity and
  the paper's LP-IOU / LP-F (``evaluation.detail``);
* its views for the paper's Cls (seed = the output's index);
* for a single-style output, its style overlap: the mean IOU with the same
  content's other single-style outputs (``evaluation.style_overlap``).

Then the self-reconstruction cases (``evaluation.selfrec``): IOU at 256³,
Chamfer, LP-detail and LP-IOU against the own exemplar, and the
shape-matched Cls (real = the held-out augmentations' true fine shapes,
fake = their detailized coarse grids, same views, held-out views scored).

The patch search visits the exemplars one at a time after every output is
sampled (memory: one exemplar's table). Every figure gets a bootstrap 95 %
interval over contents (protocol outputs) or exemplars (self-reconstruction;
``evaluation.intervals``); with ``baseline`` (another report, e.g. upsample's),
paired differences against it on the same outputs and cases.

The paper's Cls (exemplars as real, every output as fake) is kept as an
extra; ``cls`` chooses the variant of both classifiers ("full", "quick",
"none"). ``evaluate`` returns a JSON-ready dict; ``write_report`` writes
``eval.json`` and ``eval.md`` (``evaluation.eval_report``).
"""

from __future__ import annotations

import os
import platform
import time
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from core.grid import ISO_LEVEL, UPSAMPLE_FACTOR as UPSAMPLE
from evaluation.eval_report import markdown, write_report  # noqa: F401  (the report's writers, re-exported)

#: The paper's per-output figures (kept for comparison; ``benchmarks/eval_ablations.py`` reads them).
METRICS = ("strict_iou", "loose_iou", "lp_iou", "lp_f")
REAL_VIEW_SEED = 100_000


def machine_info(device: str = "cpu") -> dict:
    """Where the figures were measured: CPU, cores, threads, memory, load, torch, GPU."""
    import torch

    info = {
        "platform": platform.platform(),
        "machine": platform.machine(),
        "processor": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(),
        "device": str(device),
    }
    try:
        info["memory_gb"] = round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 1024**3, 1)
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        pass
    try:
        info["load_average"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover
        pass
    if torch.cuda.is_available():
        info["cuda"] = torch.cuda.get_device_name(0)
    return info


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:  # pragma: no cover
        pass
    return platform.processor() or "unknown"


@dataclass
class _Timer:
    totals: dict

    def add(self, key: str, seconds: float) -> None:
        self.totals[key] = self.totals.get(key, 0.0) + seconds


@contextmanager
def _one_thread():
    """Torch on one thread inside: the splatting renderer and the small Cls network gain nothing from a
    second, contended core (the full classifier took 6 min on two threads at load average 3.5)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def pick_outputs(outputs, limit: int | None) -> list:
    """All outputs, or ``limit`` of them spread evenly over the protocol (output i·n // limit), in order."""
    outputs = list(outputs)
    if not limit or limit >= len(outputs):
        return outputs
    return [outputs[i * len(outputs) // limit] for i in range(limit)]


def exemplar_shapes(style_set) -> list[np.ndarray]:
    """The style set's exemplars as (R, R, R) bool occupancy at its resolution R (the LP dictionary's
    and the real Cls views' source)."""
    return [ex.full(style_set.resolution) > 0 for ex in style_set.exemplars]


def evaluate(protocol, detailizer, style_set, *, cls: str = "full", limit: int | None = None,
             split: str | None = "test", self_rec: bool = True, n_aug: int | None = None, device: str = "cpu",
             progress: Callable[[str], None] | None = None, baseline: dict | None = None) -> dict:
    """Evaluate ``detailizer`` on ``protocol`` (see the module docstring).

    Args:
        protocol: a ``evaluation.protocol.Protocol`` (already checked against the detailizer).
        detailizer: a pipeline Detailizer.
        style_set: the loaded ``stylesets.format.StyleSet`` the protocol's styles come from.
        cls: "full", "quick" or "none" (both classifiers).
        limit: evaluate only this many outputs of the split, spread evenly (``pick_outputs``).
        split: "test", "dev" or None (every output; the only choice for a version 1 protocol).
        self_rec: run the self-reconstruction suite and the shape-matched Cls.
        n_aug: held-out augmentations per exemplar (default ``selfrec.N_AUG``).
        device: torch device of the classifiers.
        progress: callable(line) for progress messages.
        baseline: a report of another detailizer on the same split (paired differences against it).
    Returns:
        The report (see ``evaluation.eval_report``).
    """
    import torch

    from core.processes import own_peak_rss_mb

    from core.structure import strict_loose_iou
    from evaluation.cls_score import CLS_VARIANTS, ViewBank
    from evaluation.detail import PatchRecords, match_all, patch_owners, region_exemplars
    from evaluation.eval_report import summarise
    from evaluation.protocol import set_digest
    from evaluation.render_eval import render_views
    from evaluation.selfrec import N_AUG, case_figures, self_cases
    from evaluation.style_overlap import StyleOverlap

    say = progress or (lambda line: None)
    started = time.perf_counter()
    machine_start = machine_info(device)
    timer = _Timer({})
    outputs = pick_outputs(protocol.outputs_of(split), limit)
    cls_cfg = CLS_VARIANTS.get(cls) if cls != "none" else None
    if cls != "none" and cls_cfg is None:
        raise ValueError(f"unknown Cls variant {cls!r}")
    names = [e.name for e in style_set.exemplars]
    categories = [e.category for e in style_set.exemplars]
    style_index = {n: i for i, n in enumerate(names)}
    R = style_set.resolution

    def exemplar(e: int) -> np.ndarray:
        return style_set.exemplars[e].full(R) > 0

    real = fake = None
    if cls_cfg is not None:
        t = time.perf_counter()
        real, fake = ViewBank(cls_cfg.n_views, cls_cfg.test_views), ViewBank(cls_cfg.n_views, cls_cfg.test_views)
        for e in range(len(names)):
            with _one_thread():
                real.add(render_views(exemplar(e), cls_cfg.n_views, seed=REAL_VIEW_SEED + e))
        timer.add("render_real_s", time.perf_counter() - t)

    kinds = {cid: info.get("kind", "?") for cid, info in protocol.content_info.items()}
    records = PatchRecords()
    overlap = StyleOverlap(outputs)
    rows = []
    loop_start = time.perf_counter()
    for n, out in enumerate(outputs):
        t0 = time.perf_counter()
        grid = protocol.grid(out)
        binary = np.asarray(detailizer.detailize(grid, seed=0).occupancy) > ISO_LEVEL
        t1 = time.perf_counter()
        strict, loose = strict_loose_iou(binary, grid.occupancy)
        regions = region_exemplars(grid, style_index)
        records.add(out.id, binary, lambda pos: patch_owners(pos, regions, UPSAMPLE), seed=out.index)
        t2 = time.perf_counter()
        if fake is not None:
            with _one_thread():
                fake.add(render_views(torch.from_numpy(binary), cls_cfg.n_views, seed=out.index))
        t3 = time.perf_counter()
        timer.add("detailize_s", t1 - t0)
        timer.add("patches_s", t2 - t1)
        timer.add("render_s", t3 - t2)
        rows.append({"id": out.id, "content": out.content, "kind": kinds.get(out.content, "?"), "mixed": out.mixed,
                     "split": protocol.split_of(out.content), "styles": out.styles, "strict_iou": strict,
                     "loose_iou": loose, "occupied_fine": int(binary.sum()), "seconds": round(t3 - t0, 3)})
        overlap.add(out, binary, rows[-1])
        eta = (time.perf_counter() - loop_start) / (n + 1) * (len(outputs) - n - 1)
        say(f"[{n + 1}/{len(outputs)}] {out.id}: strict {strict:.3f} loose {loose:.3f} "
            f"({t1 - t0:.2f} + {t2 - t1:.2f} + {t3 - t2:.2f} s; ETA {eta / 60:.1f} min)")
        del binary

    cases, case_rows, case_records = [], [], PatchRecords()
    m_real = m_fake = None
    if self_rec:
        cases = self_cases(style_set, n_aug=N_AUG if n_aug is None else n_aug)
        if cls_cfg is not None:
            m_real, m_fake = (ViewBank(cls_cfg.n_views, cls_cfg.test_views) for _ in range(2))
        for n, case in enumerate(cases):
            t0 = time.perf_counter()
            grid = case.grid(tuple(style_set.vocabulary.parts))
            binary = np.asarray(detailizer.detailize(grid, seed=0).occupancy) > ISO_LEVEL
            t1 = time.perf_counter()
            figures = case_figures(binary, case)
            case_records.add(case.id, binary, case.exemplar, seed=n)
            if m_real is not None and case.held_out:
                seed = 200_000 + n  # the same views of the true shape and of the output
                with _one_thread():
                    m_real.add(render_views(case.fine, cls_cfg.n_views, seed=seed))
                    m_fake.add(render_views(torch.from_numpy(binary), cls_cfg.n_views, seed=seed))
            t2 = time.perf_counter()
            timer.add("selfrec_detailize_s", t1 - t0)
            timer.add("selfrec_figures_s", t2 - t1)
            case_rows.append({"id": case.id, "exemplar": case.name, "category": categories[case.exemplar],
                              "held_out": case.held_out, **figures, "seconds": round(t2 - t0, 3)})
            say(f"[self {n + 1}/{len(cases)}] {case.id}: IOU {figures['iou']:.3f} "
                f"chamfer {figures['chamfer'] if figures['chamfer'] is None else round(figures['chamfer'], 2)}")
            del binary
        del cases

    t = time.perf_counter()
    say(f"patch search: {len(names)} exemplars, one at a time")
    search = match_all([records, case_records], exemplar, names, categories, progress=say)
    timer.add("patch_search_s", time.perf_counter() - t)
    for row, sc in zip(rows, (records.scores()[r["id"]] for r in rows)):
        row.update(sc)
    case_scores = case_records.scores()
    for row in case_rows:
        sc = case_scores[row["id"]]
        row.update(lp_detail=sc["lp_detail"], lp_iou=sc["own_lp_iou"], extrusions=sc["extrusions"],
                   patches=sc["patches"])
    search_stats = records.stats.to_json() | {"selfrec_pairs": case_records.stats.pairs,
                                              "selfrec_capped": case_records.stats.capped}
    del records, case_records, case_scores  # the packed patches are not needed by the classifiers

    classifiers = {}
    if cls_cfg is not None:
        from evaluation.cls_score import cls_score

        for key, (r_bank, f_bank) in (("matched_cls", (m_real, m_fake)), ("paper_cls", (real, fake))):
            if r_bank is None or r_bank.n_shapes == 0 or f_bank.n_shapes == 0:
                continue
            t = time.perf_counter()
            say(f"{key} ({cls_cfg.variant}): {r_bank.n_shapes} real + {f_bank.n_shapes} fake shapes")
            with _one_thread() if device == "cpu" else nullcontext():  # small convolutions: one thread is faster
                result = cls_score(r_bank, f_bank, cls_cfg, device=device)
            timer.add(f"{key}_s", time.perf_counter() - t)
            classifiers[key] = result.to_json()
            r_bank.train.clear(), r_bank.test.clear(), f_bank.train.clear(), f_bank.test.clear()  # views done
            say(f"{key} = {result.cls:.3f} (real acc {result.real_acc:.3f}, fake acc {result.fake_acc:.3f})")
        if "matched_cls" in classifiers:  # per held-out case: (real acc + fake acc) / 2 of its own pair
            mc = classifiers["matched_cls"]
            held = [r for r in case_rows if r["held_out"]]
            for r, ra, fa in zip(held, mc["real_acc_per_shape"], mc["fake_acc_per_shape"]):
                r["matched_cls"] = (ra + fa) / 2
        if "paper_cls" in classifiers:
            for row, acc in zip(rows, classifiers["paper_cls"]["fake_acc_per_shape"]):
                row["cls_fake_acc"] = acc

    total = time.perf_counter() - started
    timings = {k: round(v, 2) for k, v in timer.totals.items()}
    timings.update(total_s=round(total, 1), per_output_all_in_s=round(total / max(1, len(rows) + len(case_rows)), 3),
                   peak_rss_gb=round(own_peak_rss_mb() / 1024, 2),
                   **search)
    report = {
        "format": "decollage-eval", "version": 2,
        "protocol": {"name": protocol.name, "path": str(protocol.path), "split": split,
                     "contents_sha256": protocol.meta.get("contents_sha256"),
                     "outputs": len(protocol.outputs), "in_split": len(protocol.outputs_of(split)),
                     "evaluated": len(rows), "limit": limit},
        "detailizer": detailizer.describe(),
        "style_set": {"name": style_set.name, "inputs_hash": style_set.inputs_hash, "exemplars": len(names),
                      "matches_protocol": set_digest(style_set) == protocol.meta.get("style_set_digest")},
        "cls_variant": cls_cfg.variant if cls_cfg else "none",
        "classifiers": classifiers,
        "search": search_stats,
        "timings": timings,
        "machine": {**machine_info(device), "load_average_start": machine_start.get("load_average")},
        "outputs": rows,
        "selfrec": case_rows,
    }
    report.update(summarise(report, baseline))
    return report


