"""The evaluation report: figures with intervals, paired differences, markdown, and the side-by-side table.

``FIGURES`` lists every reported figure once: its key, where its per-item
values are (protocol outputs, grouped by content; or self-reconstruction
cases, grouped by exemplar), its label, and whether higher is better. The
paper's figures (LP-IOU, LP-F, Cls with exemplars as real) are kept for
comparison and marked *not the bar*, with the reason (``NOT_THE_BAR``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from evaluation.intervals import Estimate, bootstrap_mean, paired_difference


@dataclass(frozen=True)
class Figure:
    """One reported figure.

    Attributes:
        key: its name in the report.
        source: "outputs" (protocol outputs, bootstrap over contents) or "selfrec"
            (cases, bootstrap over exemplars).
        field: the per-item value's key in that source's rows.
        label: markdown label.
        higher_better: direction (Cls: closer to 0.5 is better, reported as lower).
        paper: one of the paper's figures (not the bar).
    """

    key: str
    source: str
    field: str
    label: str
    higher_better: bool = True
    paper: bool = False


FIGURES: tuple[Figure, ...] = (
    Figure("lp_detail", "outputs", "lp_detail", "**LP-detail** (own style; the primary figure)"),
    Figure("lp_detail_all", "outputs", "lp_detail_all", "LP-detail against all exemplars"),
    Figure("lp_detail_other", "outputs", "lp_detail_other", "LP-detail against the other categories", False),
    Figure("specificity", "outputs", "specificity", "**style specificity** (own − other categories)"),
    Figure("style_overlap", "outputs", "style_overlap",
           "style overlap (IOU between single-style outputs of one content; 1 = style-blind)", False),
    Figure("selfrec_iou", "selfrec", "iou", "self-reconstruction IOU (full resolution, 256³)"),
    Figure("selfrec_lp_detail", "selfrec", "lp_detail", "self-reconstruction LP-detail (own exemplar)"),
    Figure("selfrec_lp_iou", "selfrec", "lp_iou", "self-reconstruction LP-IOU (own exemplar)"),
    Figure("selfrec_chamfer", "selfrec", "chamfer", "self-reconstruction Chamfer (fine voxels)", False),
    Figure("matched_cls", "selfrec", "matched_cls", "**shape-matched Cls** (0.5 ideal)", False),
    Figure("strict_iou", "outputs", "strict_iou", "Strict-IOU"),
    Figure("loose_iou", "outputs", "loose_iou", "Loose-IOU"),
    Figure("lp_iou", "outputs", "lp_iou", "LP-IOU (paper)", paper=True),
    Figure("lp_f", "outputs", "lp_f", "LP-F (paper; bounded search, a lower bound)", paper=True),
    Figure("cls_fake_acc", "outputs", "cls_fake_acc", "Cls fake accuracy per output (paper classifier)", False,
           paper=True),
)

NOT_THE_BAR = (
    "*Not the bar* (kept to compare with the paper): at ×16 a 12³ patch is smaller than one coarse cell, so "
    "most surface patches of blurred blocks are flat faces and straight edges that every exemplar also has — "
    "LP-IOU rewards them (the upsample baseline scores highest); LP-F's 1-voxel tolerance makes it saturate "
    "and ignore the style; the paper's Cls separates exemplars from letters and CAD parts by their silhouettes, "
    "not by detail. LP-F here checks a bounded set of candidates (`evaluation/detail_index.py`), a lower bound "
    "of the exhaustive search.")


def _values(report: dict, fig: Figure) -> tuple[dict[str, float | None], dict[str, str]]:
    """id → value and id → group (content or exemplar) of one figure."""
    if fig.source == "outputs":
        rows = report.get("outputs", [])
        return {r["id"]: r.get(fig.field) for r in rows}, {r["id"]: r["content"] for r in rows}
    rows = report.get("selfrec", [])
    return {r["id"]: r.get(fig.field) for r in rows}, {r["id"]: r["exemplar"] for r in rows}


def summarise(report: dict, baseline: dict | None = None) -> dict:
    """Estimates (mean + interval) of every figure, group means, paired differences against ``baseline``.

    Returns:
        {"estimates": key → Estimate json, "means": key → mean (the paper's keys too, for old readers),
        "groups": name → {n, figure means}, "vs_baseline": None or {"detailizer", key → Estimate json}}
    """
    estimates = {}
    for fig in FIGURES:
        values, groups = _values(report, fig)
        ids = list(values)
        estimates[fig.key] = bootstrap_mean([values[i] for i in ids], [groups[i] for i in ids]).to_json()
    paper_cls = (report.get("classifiers", {}).get("paper_cls") or {}).get("cls")
    means = {k: v["mean"] for k, v in estimates.items()} | {"cls": paper_cls}
    groups = {}
    rows = report.get("outputs", [])
    kinds = list(dict.fromkeys(r["kind"] for r in rows))
    for name, pick in [*((f"kind={k}", (lambda r, k=k: r["kind"] == k)) for k in kinds),
                       ("single style", lambda r: not r["mixed"]), ("mixed styles", lambda r: r["mixed"])]:
        sel = [r for r in rows if pick(r)]
        if sel:
            groups[name] = {"n": len(sel)} | {k: _mean([r.get(k) for r in sel]) for k in
                                             ("lp_detail", "specificity", "strict_iou", "lp_iou", "extrusions")}
    for name, held in (("self-reconstruction: exemplars", False), ("self-reconstruction: held-out augmentations", True)):
        sel = [r for r in report.get("selfrec", []) if r["held_out"] == held]
        if sel:
            groups[name] = {"n": len(sel)} | {k: _mean([r.get(k) for r in sel]) for k in
                                             ("iou", "lp_detail", "lp_iou", "chamfer")}
    vs = None
    if baseline is not None:
        vs = {"detailizer": baseline.get("detailizer", {}).get("name", "?")}
        for fig in FIGURES:
            a, groups_a = _values(report, fig)
            b, _ = _values(baseline, fig)
            vs[fig.key] = paired_difference(a, b, groups_a).to_json()
    return {"estimates": estimates, "means": means, "groups": groups, "vs_baseline": vs}


def _mean(values: list) -> float | None:
    vals = [float(v) for v in values if v is not None]
    return sum(vals) / len(vals) if vals else None


def _est(d: dict | None, signed: bool = False) -> str:
    if not d:
        return "–"
    return Estimate(d["mean"], d["lo"], d["hi"], d.get("n", 0), d.get("contents", 0)).format(signed=signed)


def detailizer_name(report: dict) -> str:
    det = report["detailizer"]
    name = det.get("name", "?") + (f" ({Path(det['checkpoint']).name})" if det.get("checkpoint") else "")
    ablation = (det.get("training") or {}).get("ablation")
    if ablation and ablation != "full":  # a Table 4 row or baseline trained by the same code (model.ablations)
        name += f", ablation `{ablation}`"
    return name


def _cost_lines(report: dict) -> list[str]:
    t, mach = report["timings"], report["machine"]
    parts = ", ".join(f"{k[:-2].replace('_', ' ')} {v:.0f} s" for k, v in t.items()
                      if k.endswith("_s") and k not in ("total_s", "per_output_all_in_s", "tables_s", "search_s"))
    s = report.get("search", {})
    return [f"Cost: **{t['total_s']:.0f} s** wall, **peak RSS {t.get('peak_rss_gb', '?')} GB**; "
            f"{t['per_output_all_in_s']:.2f} s per output or case all in ({parts}; exemplar tables "
            f"{t.get('tables_s', 0):.0f} s, largest {t.get('table_mb_max', '?')} MB, search {t.get('search_s', 0):.0f} s). "
            f"Bounded search: {s.get('capped', 0)} of {s.get('pairs', 0)} (patch, exemplar) pairs left undecided "
            f"(counted as no match).",
            f"Machine: {mach.get('processor')}, {mach.get('cpu_count')} cores, {mach.get('memory_gb', '?')} GB, "
            f"torch {mach.get('torch')} ({mach.get('torch_threads')} threads), device {mach.get('device')}"
            + (f", GPU {mach['cuda']}" if mach.get("cuda") else "")
            + f"; load average {mach.get('load_average_start')} at the start, {mach.get('load_average')} at the end."]


def markdown(report: dict) -> str:
    """One detailizer's report as markdown: figures with intervals (and Δ), groups, Cls details, cost."""
    p, est, vs = report["protocol"], report["estimates"], report.get("vs_baseline")
    name = detailizer_name(report)
    cls = report.get("classifiers", {})
    split = p.get("split") or "all"
    lines = [f"### Evaluation: {name} on {p['name']}, {split} split ({p['evaluated']} of {p.get('in_split', '?')} "
             f"outputs{', limit ' + str(p['limit']) if p.get('limit') else ''}; "
             f"{len(report.get('selfrec', []))} self-reconstruction cases)", "",
             f"Classifiers: **{report['cls_variant']}**. Intervals: 95 % bootstrap over contents (outputs) or "
             f"exemplars (self-reconstruction).", "",
             "| figure | value [95 % interval] | Δ vs " + (vs["detailizer"] if vs else "baseline") + " [95 %] |",
             "|---|---|---|"]
    for fig in FIGURES:
        if fig.key == "cls_fake_acc":
            continue
        if fig.paper and fig.key == "lp_iou":
            pc = (cls.get("paper_cls") or {}).get("cls")
            lines.append(f"| Cls (paper: exemplars vs outputs; not the bar) | {'–' if pc is None else f'{pc:.3f}'} | – |")
        label = fig.label + (" — not the bar" if fig.paper else "") + ("" if fig.higher_better else " ↓")
        lines.append(f"| {label} | {_est(est.get(fig.key))} | {_est(vs.get(fig.key) if vs else None, True)} |")
    lines += ["", "↓: lower is better. " + NOT_THE_BAR, "",
              "| group | n | LP-detail | specificity | Strict-IOU | LP-IOU (paper) | extrusion share |",
              "|---|---|---|---|---|---|---|"]
    f = (lambda v: "–" if v is None else f"{v:.3f}")
    for g, v in report["groups"].items():
        if g.startswith("self-"):
            continue
        lines.append(f"| {g} | {v['n']} | {f(v['lp_detail'])} | {f(v['specificity'])} | {f(v['strict_iou'])} | "
                     f"{f(v['lp_iou'])} | {f(v['extrusions'])} |")
    lines += ["", "| self-reconstruction | n | IOU | LP-detail | LP-IOU | Chamfer |", "|---|---|---|---|---|---|"]
    for g, v in report["groups"].items():
        if g.startswith("self-"):
            lines.append(f"| {g[len('self-reconstruction: '):]} | {v['n']} | {f(v['iou'])} | {f(v['lp_detail'])} | "
                         f"{f(v['lp_iou'])} | {f(v['chamfer'])} |")
    for key, what in (("matched_cls", "shape-matched"), ("paper_cls", "paper")):
        c = cls.get(key)
        if c:
            lines.append(f"\nCls ({what}): {c['cls']:.3f} = (real acc {c['real_acc']:.3f} + fake acc "
                         f"{c['fake_acc']:.3f}) / 2 on held-out views; {c['real_shapes']} real, {c['fake_shapes']} fake "
                         f"shapes; {c['config']['n_views']} views a shape, {c['config']['test_views']} held out.")
    lines += [""] + _cost_lines(report) + [""]
    if not report["style_set"]["matches_protocol"]:
        lines.insert(-1, "Note: the style set's exemplars differ from those the protocol was made from.")
    return "\n".join(lines)


def compare_markdown(reports: list[dict]) -> str:
    """Side by side: one column per report (value [interval], then Δ vs the first report's detailizer)."""
    if not reports:
        return ""
    names = [detailizer_name(r) for r in reports]
    p = reports[0]["protocol"]
    head = (f"Protocol {p['name']}, {p.get('split') or 'all'} split, {p['evaluated']} outputs per detailizer "
            f"(limit {p.get('limit') or 'none'}); classifiers {reports[0]['cls_variant']}; 95 % bootstrap intervals; "
            "Δ = paired difference against the upsample baseline on the same outputs and cases.")
    lines = [head, "", "| figure | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for fig in FIGURES:
        if fig.key == "cls_fake_acc":
            continue
        cells = []
        for r in reports:
            cell = _est(r["estimates"].get(fig.key))
            vs = r.get("vs_baseline")
            if vs and vs.get(fig.key) and vs[fig.key]["mean"] is not None:
                cell += f"<br>Δ {_est(vs[fig.key], True)}"
            cells.append(cell)
        label = fig.label + (" — not the bar" if fig.paper else "") + ("" if fig.higher_better else " ↓")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    pc = [((r.get("classifiers", {}).get("paper_cls") or {}).get("cls")) for r in reports]
    lines.append("| Cls (paper: exemplars vs outputs) — not the bar ↓ | "
                 + " | ".join("–" if v is None else f"{v:.3f}" for v in pc) + " |")
    lines += ["", "| cost | " + " | ".join(names) + " |", "|---|" + "---|" * len(names),
              "| wall (s) | " + " | ".join(f"{r['timings']['total_s']:.0f}" for r in reports) + " |",
              "| peak RSS (GB) | " + " | ".join(str(r["timings"].get("peak_rss_gb", "?")) for r in reports) + " |",
              "| load average (start → end) | " + " | ".join(
                  f"{r['machine'].get('load_average_start')} → {r['machine'].get('load_average')}" for r in reports)
              + " |", "", "↓: lower is better. " + NOT_THE_BAR, ""]
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
