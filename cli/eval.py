"""``decollage eval``: the fixed evaluation protocol through a detailizer → eval.json + eval.md.

Role: resolve the detailizer (``--checkpoint`` for a trained model, or
``--detailizer upsample|quilt|decollage``), load and check the protocol
(``evaluation.protocol``; the test split by default), check the output
folder before the long run, load the protocol's style set, run
``evaluation.evaluate`` with progress on stderr (paired differences against
``--baseline``'s eval.json) and write the report. ``--sheet PNG`` draws the
fixed contact sheet instead (``evaluation.contact_sheet``); ``--compare``
writes the side-by-side table of several eval.json files. Errors are
``DecollageError`` subclasses; ``cli.app`` maps them to exit code 2 (one
line, no traceback).
"""

from __future__ import annotations

import os
from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from cli.console import fail, stderr
from core.detailizer import get_detailizer
from core.errors import DecollageError, UsageError
from core.files import ensure_writable_dir
from evaluation.benchmarking import write_doc_section
from evaluation.eval_report import markdown, write_report
from evaluation.evaluate import evaluate
from evaluation.protocol import DEFAULT_PROTOCOL, ProtocolError, check_detailizer, load_protocol, resolve_protocol_set
from model.infer import cpu_threads, resolve_device


class ClsChoice(str, Enum):
    FULL = "full"
    QUICK = "quick"
    NONE = "none"


class SplitChoice(str, Enum):
    TEST = "test"
    DEV = "dev"
    ALL = "all"


def eval_command(
    checkpoint: Optional[Path] = typer.Option(None, "--checkpoint", help="A trained model (.pt) to evaluate."),
    detailizer: Optional[str] = typer.Option(None, "--detailizer",
                                             help="'upsample' (the non-learned baseline) or 'decollage' (the "
                                                  "shipped model, or --checkpoint)."),
    protocol: Path = typer.Option(DEFAULT_PROTOCOL, "--protocol", help="Protocol .json (default: things_v2)."),
    split: SplitChoice = typer.Option(SplitChoice.TEST, "--split", help="Contents evaluated: test (acceptance "
                                      "figures), dev (choices) or all (a version 1 protocol has no split)."),
    baseline: Optional[Path] = typer.Option(None, "--baseline", help="eval.json of another detailizer on the same "
                                            "split (e.g. upsample): paired differences against it."),
    self_rec: bool = typer.Option(True, "--self-rec/--no-self-rec", help="Run the self-reconstruction suite and the "
                                  "shape-matched Cls."),
    sheet: Optional[Path] = typer.Option(None, "--sheet", help="Draw the fixed contact sheet (PNG) of "
                                         "--sheet-detailizers instead of evaluating."),
    sheet_detailizers: str = typer.Option("upsample,quilt,decollage", "--sheet-detailizers",
                                          help="Comma-separated detailizers, one column each."),
    compare: Optional[list[Path]] = typer.Option(None, "--compare", help="eval.json files to put side by side "
                                                 "(with --doc: its 'eval:compare' section) instead of evaluating."),
    out: Path = typer.Option(Path("out/eval"), "--out", "-o", help="Folder for eval.json and eval.md."),
    limit: Optional[int] = typer.Option(None, "--limit", min=1, help="Only N outputs, spread evenly over the protocol (quick checks)."),
    cls: ClsChoice = typer.Option(ClsChoice.FULL, "--cls", help="Cls-score variant: full, quick or none."),
    device: str = typer.Option("auto", "--device", help="auto, cpu, cuda or cuda:N."),
    threads: Optional[int] = typer.Option(None, "--threads", min=1, help="CPU threads (default: every core)."),
    doc: Optional[Path] = typer.Option(None, "--doc", help="Also put the tables into this markdown file's "
                                       "'eval:<detailizer>' section (e.g. docs/benchmarks.md)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress lines."),
) -> None:
    """Evaluate a detailizer on the fixed protocol: LP-detail, specificity, self-reconstruction, Cls, intervals."""

    try:
        if compare:
            _compare(compare, doc)
        elif sheet is not None:
            _sheet(sheet, sheet_detailizers, protocol, device, threads, quiet)
        else:
            _eval(checkpoint, detailizer, protocol, out, limit, cls.value, device, threads, doc, quiet,
                  None if split is SplitChoice.ALL else split.value, baseline, self_rec)
    except DecollageError as exc:
        fail(exc)


def _read_report(path: Path) -> dict:
    import json

    try:
        report = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise UsageError(f"cannot read the report ({type(exc).__name__})", file=path,
                         hint="give an eval.json written by 'decollage eval'") from None
    if not isinstance(report, dict) or report.get("format") != "decollage-eval" or report.get("version") != 2:
        raise UsageError("not a version 2 eval.json", file=path, hint="rerun 'decollage eval' to make one")
    return report


def _compare(paths: list[Path], doc: Optional[Path]) -> None:
    from evaluation.eval_report import compare_markdown

    text = compare_markdown([_read_report(p) for p in paths])
    typer.echo(text)
    if doc is not None:
        ensure_writable_dir(Path(doc).parent)
        write_doc_section(doc, "eval:compare", text)


def _sheet(path: Path, names: str, protocol_path: Path, device: str, threads: Optional[int], quiet: bool) -> None:
    import torch

    from evaluation.contact_sheet import contact_sheet

    console = stderr()
    say = (lambda line: None) if quiet else (lambda line: console.print(line, markup=False, highlight=False))
    torch.set_num_threads(threads or cpu_threads())
    protocol = load_protocol(protocol_path)
    dets = [get_detailizer(n.strip(), None, str(resolve_device(device))) for n in names.split(",") if n.strip()]
    if not dets:
        raise UsageError("no detailizer to draw", field="--sheet-detailizers", hint="e.g. upsample,quilt,decollage")
    for det in dets:
        check_detailizer(protocol, det)
    ensure_writable_dir(Path(path).parent)
    contact_sheet(protocol, dets, resolve_protocol_set(protocol), Path(path), progress=say)
    say(f"wrote {path}")


def _eval(checkpoint, detailizer, protocol_path, out, limit, cls, device, threads, doc, quiet, split, baseline_path,
          self_rec) -> None:
    import torch


    console = stderr()
    say = (lambda line: None) if quiet else (lambda line: console.print(line, markup=False, highlight=False))
    if checkpoint is None and detailizer is None:
        raise UsageError("say what to evaluate", field="--checkpoint",
                         hint="give --checkpoint model.pt or --detailizer upsample")
    name = detailizer or "decollage"
    if checkpoint is not None and name == "upsample":
        raise UsageError("the 'upsample' baseline takes no checkpoint", field="--checkpoint",
                         hint="drop --checkpoint, or use --detailizer decollage")
    if threads:
        os.environ["OMP_NUM_THREADS"] = str(threads)  # the learned detailizer reads it for every call
    torch.set_num_threads(threads or cpu_threads())
    dev = str(resolve_device(device))
    protocol = load_protocol(protocol_path)
    protocol.outputs_of(split)  # a split asked of a protocol without one fails here, before the long run
    baseline = _read_report(baseline_path) if baseline_path is not None else None
    if baseline is not None and baseline["protocol"].get("split") != split:
        raise UsageError(f"the baseline was measured on the {baseline['protocol'].get('split') or 'whole'} "
                         f"protocol, not the {split or 'whole'} one", file=baseline_path, field="--baseline")
    det = get_detailizer(name, str(checkpoint) if checkpoint is not None else None, dev)
    check_detailizer(protocol, det)
    ensure_writable_dir(out)
    if doc is not None:
        ensure_writable_dir(Path(doc).parent)
    in_split = len(protocol.outputs_of(split))
    say(f"protocol {protocol.name}: {in_split} outputs in the {split or 'whole'} split"
        + (f", evaluating {min(limit, in_split)} spread over them" if limit else "")
        + f"; detailizer {det.name}; Cls {cls}; device {dev}, {torch.get_num_threads()} threads")
    style_set = resolve_protocol_set(protocol)
    missing = sorted({s for o in protocol.outputs for s in o.styles.values()} - {e.name for e in style_set.exemplars})
    if missing:
        raise ProtocolError(f"the protocol names styles that set '{style_set.name}' has no exemplar for: "
                            f"{', '.join(missing)}", file=protocol.path, field="styles",
                            hint="regenerate the protocol with 'python benchmarks/make_protocol.py'")
    report = evaluate(protocol, det, style_set, cls=cls, limit=limit, split=split, self_rec=self_rec, device=dev,
                      progress=say, baseline=baseline)
    js, md = write_report(report, out)
    typer.echo(markdown(report))
    say(f"wrote {js} and {md}")
    if doc is not None:

        key = "eval:" + det.name + (f":{Path(checkpoint).stem}" if checkpoint is not None else "")
        write_doc_section(doc, key, markdown(report))
        say(f"wrote the '{key}' section of {doc}")
