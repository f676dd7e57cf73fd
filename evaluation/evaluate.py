"""Run an evaluation protocol through a detailizer and measure the paper's five metrics (method.md §5).

Per output (content × style assignment of ``evaluation.protocol``):

* the detailizer's fine output, binarised at ISO_LEVEL (0.4);
* Strict-IOU and Loose-IOU against the coarse content (max-pool ×16);
* LP-IOU and LP-F-score of 1000 surface patches (seed = the output's index)
  against the dictionary of *all* the style set's exemplars (as the reference
  builds it against the whole style split);
* its views for the Cls-score (seed = the output's index).

Cls is one classifier for the whole run: real = the style set's exemplars
(view seeds 100000 + i), fake = every evaluated output; it is measured on
held-out views (``evaluation.cls_score``), and each output's own held-out fake
accuracy is kept so the worst outputs can be found. ``cls="none"`` skips the
renders and the classifier; ``"quick"`` uses fewer views and steps. The
report records the variant.

``evaluate`` returns a JSON-ready dict; ``write_report`` writes ``eval.json``
and ``eval.md`` (a markdown table of the means, overall and per content kind
and single/mixed styles).
"""

from __future__ import annotations

import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from core.grid import ISO_LEVEL

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


def _mean(rows: list[dict], key: str) -> float | None:
    vals = [r[key] for r in rows if r.get(key) is not None]
    return float(np.mean(vals)) if vals else None


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
             device: str = "cpu", progress: Callable[[str], None] | None = None, dictionary=None) -> dict:
    """Evaluate ``detailizer`` on ``protocol`` (first ``limit`` outputs if given).

    Args:
        protocol: a ``evaluation.protocol.Protocol`` (already checked against the detailizer).
        detailizer: a pipeline Detailizer.
        style_set: the loaded ``stylesets.format.StyleSet`` the protocol's styles come from.
        limit: evaluate only this many outputs, spread evenly (``pick_outputs``).
        cls: "full", "quick" or "none".
        device: torch device for the LP search and the Cls classifier.
        progress: callable(line) for progress messages.
        dictionary: the ``metrics.StyleDictionary`` of ``style_set`` when the caller already has it
            (several detailizers evaluated in one process: it costs about 2 minutes to build);
            None = build it here. Its build time is then not in the report's timings.
    Returns:
        The report (see ``write_report``).
    """
    import torch

    from evaluation.cls_score import CLS_VARIANTS, ViewBank, cls_score
    from core.structure import strict_loose_iou
    from evaluation.lp import lp_scores
    from evaluation.patch_index import style_patch_dictionary
    from evaluation.render_eval import render_views
    from evaluation.protocol import set_digest

    say = progress or (lambda line: None)
    started = time.perf_counter()
    machine_start = machine_info(device)
    timer = _Timer({})
    outputs = pick_outputs(protocol.outputs, limit)
    cls_cfg = CLS_VARIANTS.get(cls) if cls != "none" else None
    if cls != "none" and cls_cfg is None:
        raise ValueError(f"unknown Cls variant {cls!r}")

    t = time.perf_counter()
    exemplars = exemplar_shapes(style_set)
    if dictionary is None:
        dictionary = style_patch_dictionary(exemplars)
        timer.add("dictionary_s", time.perf_counter() - t)
    dictionary = dictionary.to(device)
    say(f"style dictionary: {len(dictionary.occ_count)} occupancy + {len(dictionary.surf_count)} surface patches "
        f"of {len(exemplars)} exemplars ({time.perf_counter() - t:.1f} s)")
    real = fake = None
    if cls_cfg is not None:
        t = time.perf_counter()
        real = ViewBank(cls_cfg.n_views, cls_cfg.test_views)
        for i, shape in enumerate(exemplars):
            real.add(render_views(shape, cls_cfg.n_views, seed=REAL_VIEW_SEED + i))
        fake = ViewBank(cls_cfg.n_views, cls_cfg.test_views)
        timer.add("render_real_s", time.perf_counter() - t)
        say(f"exemplar views: {len(exemplars)} × {cls_cfg.n_views} ({time.perf_counter() - t:.1f} s)")
    del exemplars

    kinds = {cid: info.get("kind", "?") for cid, info in protocol.content_info.items()}
    rows = []
    loop_start = time.perf_counter()
    for n, out in enumerate(outputs):
        t0 = time.perf_counter()
        grid = protocol.grid(out)
        fine = detailizer.detailize(grid, seed=0)
        binary = torch.from_numpy(np.asarray(fine.occupancy) > ISO_LEVEL)
        t1 = time.perf_counter()
        strict, loose = strict_loose_iou(binary, grid.occupancy)
        lp_iou, lp_f = lp_scores(binary.to(device) if device != "cpu" else binary, dictionary, seed=out.index)
        t2 = time.perf_counter()
        if fake is not None:
            fake.add(render_views(binary, cls_cfg.n_views, seed=out.index))
        t3 = time.perf_counter()
        timer.add("detailize_s", t1 - t0)
        timer.add("metrics_s", t2 - t1)
        timer.add("render_s", t3 - t2)
        rows.append({"id": out.id, "content": out.content, "kind": kinds.get(out.content, "?"), "mixed": out.mixed,
                     "styles": out.styles, "strict_iou": strict, "loose_iou": loose, "lp_iou": lp_iou, "lp_f": lp_f,
                     "occupied_fine": int(binary.sum()), "seconds": round(t3 - t0, 3)})
        eta = (time.perf_counter() - loop_start) / (n + 1) * (len(outputs) - n - 1)
        say(f"[{n + 1}/{len(outputs)}] {out.id}: strict {strict:.3f} loose {loose:.3f} LP-IOU {lp_iou:.3f} "
            f"LP-F {lp_f:.3f} ({t1 - t0:.2f} + {t2 - t1:.2f} + {t3 - t2:.2f} s; ETA {eta / 60:.1f} min)")

    cls_json = None
    if cls_cfg is not None and rows:
        t = time.perf_counter()
        say(f"Cls ({cls_cfg.variant}): training the classifier on {len(real.train)} real + {len(fake.train)} fake "
            f"views, testing on {len(real.test)} + {len(fake.test)} held-out views")
        result = cls_score(real, fake, cls_cfg, device=device,
                           progress=lambda s, total: say(f"  Cls step {s}/{total}"))
        timer.add("cls_s", time.perf_counter() - t)
        for row, acc in zip(rows, result.fake_acc_per_shape):
            row["cls_fake_acc"] = acc
        cls_json = result.to_json()
        cls_json["real_acc_per_exemplar"] = dict(zip([e.name for e in style_set.exemplars],
                                                    cls_json.pop("real_acc_per_shape")))
        cls_json.pop("fake_acc_per_shape")
        say(f"Cls ({cls_cfg.variant}) = {result.cls:.3f} (real acc {result.real_acc:.3f}, fake acc "
            f"{result.fake_acc:.3f}; {time.perf_counter() - t:.1f} s)")

    total = time.perf_counter() - started
    means = {k: _mean(rows, k) for k in METRICS}
    means["cls"] = cls_json["cls"] if cls_json else None
    groups = {}
    for name, pick in [*((f"kind={k}", (lambda r, k=k: r["kind"] == k)) for k in dict.fromkeys(kinds.values())),
                       ("single style", lambda r: not r["mixed"]), ("mixed styles", lambda r: r["mixed"])]:
        sel = [r for r in rows if pick(r)]
        if sel:
            groups[name] = {"n": len(sel), **{k: _mean(sel, k) for k in METRICS},
                            "cls_fake_acc": _mean(sel, "cls_fake_acc")}
    timings = {k: round(v, 2) for k, v in timer.totals.items()}
    timings["total_s"] = round(total, 1)
    timings["per_output_s"] = round((timer.totals.get("detailize_s", 0) + timer.totals.get("metrics_s", 0)
                                     + timer.totals.get("render_s", 0)) / max(1, len(rows)), 3)
    timings["per_output_all_in_s"] = round(total / max(1, len(rows)), 3)
    return {
        "format": "decollage-eval", "version": 1,
        "protocol": {"name": protocol.name, "path": str(protocol.path),
                     "contents_sha256": protocol.meta.get("contents_sha256"),
                     "outputs": len(protocol.outputs), "evaluated": len(rows), "limit": limit},
        "detailizer": detailizer.describe(),
        "style_set": {"name": style_set.name, "inputs_hash": style_set.inputs_hash,
                      "exemplars": len(style_set.exemplars),
                      "matches_protocol": set_digest(style_set) == protocol.meta.get("style_set_digest")},
        "cls_variant": cls_cfg.variant if cls_cfg else "none",
        "means": means,
        "groups": groups,
        "cls": cls_json,
        "timings": timings,
        "machine": {**machine_info(device), "load_average_start": machine_start.get("load_average")},
        "outputs": rows,
    }


def _fmt(v, digits: int = 3) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def markdown(report: dict) -> str:
    """The report as markdown: a table of the means, groups, Cls details, timings and the machine."""
    det = report["detailizer"]
    name = det.get("name", "?") + (f" ({Path(det['checkpoint']).name})" if det.get("checkpoint") else "")
    ablation = (det.get("training") or {}).get("ablation")
    if ablation and ablation != "full":  # a Table 4 row or baseline trained by the same code (model.ablations)
        name += f", ablation `{ablation}`"
    m, t, mach = report["means"], report["timings"], report["machine"]
    p = report["protocol"]
    lines = [
        f"### Evaluation: {name} on {p['name']} ({p['evaluated']} of {p['outputs']} outputs)",
        "",
        f"Cls variant: **{report['cls_variant']}**"
        + (f" ({report['cls']['config']['n_views']} views a shape, {report['cls']['config']['test_views']} held out, "
           f"{report['cls']['config']['steps']} steps); lower is better, 0.5 ideal." if report["cls"] else "."),
        "Strict/Loose-IOU, LP-IOU, LP-F: higher is better.",
        "",
        "| detailizer | outputs | Strict-IOU | Loose-IOU | LP-IOU | LP-F | Cls |",
        "|---|---|---|---|---|---|---|",
        f"| {name} | {p['evaluated']} | {_fmt(m['strict_iou'])} | {_fmt(m['loose_iou'])} | {_fmt(m['lp_iou'])} | "
        f"{_fmt(m['lp_f'])} | {_fmt(m['cls'])} ({report['cls_variant']}) |",
        "",
        "| group | outputs | Strict-IOU | Loose-IOU | LP-IOU | LP-F | fake acc. (held-out) |",
        "|---|---|---|---|---|---|---|",
    ]
    for g, v in report["groups"].items():
        lines.append(f"| {g} | {v['n']} | {_fmt(v['strict_iou'])} | {_fmt(v['loose_iou'])} | {_fmt(v['lp_iou'])} | "
                     f"{_fmt(v['lp_f'])} | {_fmt(v.get('cls_fake_acc'))} |")
    lines += ["", f"Timings: total {t['total_s']:.0f} s; {t['per_output_all_in_s']:.2f} s per output all in "
              f"(detailize {t.get('detailize_s', 0):.0f} s, IOU + LP {t.get('metrics_s', 0):.0f} s, "
              f"views {t.get('render_s', 0):.0f} s, style dictionary {t.get('dictionary_s', 0):.0f} s, "
              f"exemplar views {t.get('render_real_s', 0):.0f} s, Cls classifier {t.get('cls_s', 0):.0f} s).",
              f"Machine: {mach.get('processor')}, {mach.get('cpu_count')} cores, {mach.get('memory_gb', '?')} GB, "
              f"torch {mach.get('torch')} ({mach.get('torch_threads')} threads), device {mach.get('device')}"
              + (f", GPU {mach['cuda']}" if mach.get("cuda") else "")
              + f"; load average {mach.get('load_average_start')} at the start, {mach.get('load_average')} at the end.",
              ""]
    if not report["style_set"]["matches_protocol"]:
        lines.insert(-1, "Note: the style set's exemplars differ from those the protocol was made from "
                         "(regenerate it with `python benchmarks/make_protocol.py`).")
    return "\n".join(lines)


def write_report(report: dict, out_dir: Path) -> tuple[Path, Path]:
    """Write ``eval.json`` and ``eval.md`` into ``out_dir`` (atomic writes)."""
    import json

    from core.files import write_bytes_atomic

    out_dir = Path(out_dir)
    js, md = out_dir / "eval.json", out_dir / "eval.md"
    write_bytes_atomic(js, (json.dumps(report, indent=1) + "\n").encode())
    write_bytes_atomic(md, markdown(report).encode())
    return js, md
