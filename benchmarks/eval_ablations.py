"""Evaluate the Table 4 rows (``model.ablations``) trained at one reduced budget, and tabulate them (not a test).

Run: ``python benchmarks/eval_ablations.py OUT [--limit 80] [--cls quick] [--doc docs/benchmarks.md]``
after ``bash scripts/train_ablations.sh OUT``. Every row with a model ``OUT/<row>.pt`` is
evaluated on ``--limit`` outputs of the default protocol, spread evenly over it, into
``OUT/eval_<row>/eval.{json,md}`` (a row already evaluated with the same limit and Cls
variant is kept), all in one process so that the style patch dictionary is built once.
Then one markdown table is printed (and written into the ``ablations`` section of
``--doc``): per row the training budget and end losses from ``OUT/<row>/log.jsonl`` and
the five metrics. Rows missing a log or an evaluation are listed as such.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from model.ablations import ABLATIONS  # noqa: E402
from evaluation.evaluate import METRICS  # noqa: E402

LOSS_TAIL = 25  # iterations the end-of-training losses are averaged over


def _read_log(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]


def _fmt(v) -> str:
    return "–" if v is None else f"{v:.3f}"


def row_figures(out: Path, row: str) -> dict | None:
    """Training and evaluation figures of one row, or None if it has no log."""
    log_path, eval_path = out / row / "log.jsonl", out / f"eval_{row}" / "eval.json"
    if not log_path.is_file():
        return None
    log = _read_log(log_path)
    tail = log[-LOSS_TAIL:]
    fig = {"steps": log[-1]["step"] if log else 0,
           "s_per_iter": statistics.median(r["seconds"] for r in log) if log else None,
           "recon_end": statistics.fmean(r["recon"] for r in tail) if tail else None,
           "gan_end": statistics.fmean(r["gan"] for r in tail) if tail else None,
           "eval": None}
    if eval_path.is_file():
        fig["eval"] = json.loads(eval_path.read_text(encoding="utf-8"))
    return fig


def table(out: Path) -> str:
    """The markdown section: budget line, one row per ablation, reading notes."""
    figs = {row: row_figures(out, row) for row in ABLATIONS}
    evals = [f["eval"] for f in figs.values() if f and f["eval"]]
    lines = ["## Table 4 rows at a reduced budget", ""]
    if evals:
        e = evals[0]
        p, m, tr = e["protocol"], e["machine"], e["detailizer"].get("training", {})
        lines += [f"Every row trained with `bash scripts/train_ablations.sh {out}` (set `things`, "
                  f"R = {tr.get('augment', {}).get('resolution', '?')}, seed {tr.get('seed', '?')}, "
                  "early-phase iterations: 4 reconstruction G-steps + 1 adversarial G-step + 1 D-step each; "
                  "two rows at a time on one thread each) and evaluated with `python benchmarks/eval_ablations.py "
                  f"{out} --limit {p['limit']} --cls {e['cls_variant']}`: {p['evaluated']} of the "
                  f"{p['outputs']} outputs of {p['name']} (spread evenly over every content), "
                  f"Cls **{e['cls_variant']}**. "
                  f"Machine: {m.get('processor')}, {m.get('cpu_count')} cores, torch {m.get('torch')}. "
                  "These figures compare the rows with each other at this budget; they are not comparable "
                  "with the full-protocol figures above (other budget, other subset, other Cls variant).", ""]
    lines += ["| row | Table 4 | iterations | s / iteration | recon (end) | G adv (end) | Strict-IOU | "
              "Loose-IOU | LP-IOU | LP-F | Cls |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for row, (label, _) in ABLATIONS.items():
        f = figs[row]
        if f is None:
            lines.append(f"| `{row}` | {label} | not trained | | | | | | | | |")
            continue
        mm = (f["eval"] or {}).get("means") or {}
        ev = [_fmt(mm.get(k)) for k in (*METRICS, "cls")] if f["eval"] \
            else ["not evaluated", "", "", "", ""]
        lines.append(f"| `{row}` | {label} | {f['steps']} | {f['s_per_iter']:.2f} | {_fmt(f['recon_end'])} | "
                     f"{_fmt(f['gan_end'])} | " + " | ".join(ev) + " |")
    lines += ["", f"recon / G adv (end): means over the last {LOSS_TAIL} iterations of the training log; "
              "recon is β·Σ_levels MSE, so the paper-loss row (β = 1) is on a tenth of the others' scale; "
              "s / iteration: median, with the other row of the pair sharing the cores. Strict/Loose-IOU, "
              "LP-IOU, LP-F: higher is better; Cls: lower is better (0.5 ideal).", ""]
    return "\n".join(lines)


def evaluate_rows(out: Path, limit: int, cls: str, say=print) -> None:
    """Evaluate every trained row not yet evaluated with this ``limit`` and ``cls`` (see the module docstring)."""
    import torch

    from evaluation.evaluate import evaluate, write_report
    from model.infer import cpu_threads
    from core.detailizer import get_detailizer
    from evaluation.protocol import check_detailizer, load_protocol, resolve_protocol_set
    from core.files import ensure_writable_dir

    torch.set_num_threads(cpu_threads())
    todo = []
    for row in ABLATIONS:
        model, report = out / f"{row}.pt", out / f"eval_{row}" / "eval.json"
        if not model.is_file():
            continue
        if report.is_file():
            old = json.loads(report.read_text(encoding="utf-8"))
            if old["protocol"]["limit"] == limit and old["cls_variant"] == cls:
                continue
        todo.append(row)
    if not todo:
        return
    for row in todo:  # before the long run, not after it
        ensure_writable_dir(out / f"eval_{row}")
    protocol = load_protocol()
    style_set = resolve_protocol_set(protocol)
    say(f"evaluating {', '.join(todo)}")
    for row in todo:
        det = get_detailizer("decollage", str(out / f"{row}.pt"), "cpu")
        check_detailizer(protocol, det)
        report = evaluate(protocol, det, style_set, cls=cls, limit=limit, split=None,
                          self_rec=False, device="cpu")
        write_report(report, out / f"eval_{row}")
        m = report["means"]
        say(f"{row}: " + ", ".join(f"{k} {m[k]:.3f}" for k in (*METRICS, "cls")
                                   if m.get(k) is not None) + f" ({report['timings']['total_s']:.0f} s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="the folder scripts/train_ablations.sh wrote")
    ap.add_argument("--limit", type=int, default=80, help="outputs of the protocol to evaluate (spread evenly)")
    ap.add_argument("--cls", choices=("quick", "full", "none"), default="quick", help="Cls-score variant")
    ap.add_argument("--doc", type=Path, help="also write the 'ablations' section of this markdown file")
    args = ap.parse_args()
    evaluate_rows(args.out, args.limit, args.cls, say=lambda line: print(line, file=sys.stderr, flush=True))
    text = table(args.out)
    print(text)
    if args.doc:
        from evaluation.benchmarking import write_doc_section

        write_doc_section(args.doc, "ablations", text)
        print(f"wrote the 'ablations' section of {args.doc}", file=sys.stderr)


if __name__ == "__main__":
    main()
