"""``decollage eval``: the fixed evaluation protocol through a detailizer → eval.json + eval.md.

Role: resolve the detailizer (``--checkpoint`` for a trained model, or
``--detailizer upsample|decollage``), load and check the protocol
(``evaluation.protocol``), check the output folder before the long run,
load the protocol's style set, run ``evaluation.evaluate`` with progress on
stderr and write the report. Errors are ``DecollageError`` subclasses;
``cli.app`` maps them to exit code 2 (one line, no traceback).
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
from evaluation.evaluate import evaluate, markdown, write_report
from evaluation.protocol import DEFAULT_PROTOCOL, ProtocolError, check_detailizer, load_protocol, resolve_protocol_set
from model.infer import cpu_threads, resolve_device


class ClsChoice(str, Enum):
    FULL = "full"
    QUICK = "quick"
    NONE = "none"


def eval_command(
    checkpoint: Optional[Path] = typer.Option(None, "--checkpoint", help="A trained model (.pt) to evaluate."),
    detailizer: Optional[str] = typer.Option(None, "--detailizer",
                                             help="'upsample' (the non-learned baseline) or 'decollage' (the "
                                                  "shipped model, or --checkpoint)."),
    protocol: Path = typer.Option(DEFAULT_PROTOCOL, "--protocol", help="Protocol .json (default: things_v1)."),
    out: Path = typer.Option(Path("out/eval"), "--out", "-o", help="Folder for eval.json and eval.md."),
    limit: Optional[int] = typer.Option(None, "--limit", min=1, help="Only N outputs, spread evenly over the protocol (quick checks)."),
    cls: ClsChoice = typer.Option(ClsChoice.FULL, "--cls", help="Cls-score variant: full, quick or none."),
    device: str = typer.Option("auto", "--device", help="auto, cpu, cuda or cuda:N."),
    threads: Optional[int] = typer.Option(None, "--threads", min=1, help="CPU threads (default: every core)."),
    doc: Optional[Path] = typer.Option(None, "--doc", help="Also put the tables into this markdown file's "
                                       "'eval:<detailizer>' section (e.g. docs/benchmarks.md)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress lines."),
) -> None:
    """Evaluate a detailizer on the fixed protocol: Strict/Loose-IOU, LP-IOU, LP-F and Cls."""

    try:
        _eval(checkpoint, detailizer, protocol, out, limit, cls.value, device, threads, doc, quiet)
    except DecollageError as exc:
        fail(exc)


def _eval(checkpoint, detailizer, protocol_path, out, limit, cls, device, threads, doc, quiet) -> None:
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
    det = get_detailizer(name, str(checkpoint) if checkpoint is not None else None, dev)
    check_detailizer(protocol, det)
    ensure_writable_dir(out)
    if doc is not None:
        ensure_writable_dir(Path(doc).parent)
    say(f"protocol {protocol.name}: {len(protocol.outputs)} outputs"
        + (f", evaluating {min(limit, len(protocol.outputs))} spread over them" if limit else "")
        + f"; detailizer {det.name}; Cls {cls}; device {dev}, {torch.get_num_threads()} threads")
    style_set = resolve_protocol_set(protocol)
    missing = sorted({s for o in protocol.outputs for s in o.styles.values()} - {e.name for e in style_set.exemplars})
    if missing:
        raise ProtocolError(f"the protocol names styles that set '{style_set.name}' has no exemplar for: "
                            f"{', '.join(missing)}", file=protocol.path, field="styles",
                            hint="regenerate the protocol with 'python benchmarks/make_protocol.py'")
    report = evaluate(protocol, det, style_set, cls=cls, limit=limit, device=dev, progress=say)
    js, md = write_report(report, out)
    typer.echo(markdown(report))
    say(f"wrote {js} and {md}")
    if doc is not None:

        key = "eval:" + det.name + (f":{Path(checkpoint).stem}" if checkpoint is not None else "")
        write_doc_section(doc, key, markdown(report))
        say(f"wrote the '{key}' section of {doc}")
