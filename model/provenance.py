"""Which style set a checkpoint learned from, and the provenance extras a detailizer reports.

A checkpoint trained by this version records its set in the training metadata
(``training["style_set"]``: a ``stylesets.provenance.StyleSetRecord``, written
by ``model/train.py``). Older checkpoints (the shipped ``model/weights/things.pt``
among them) only record the training command; for those the set is the
built-in one the command named (``--set NAME``, the CLI's default ``things``
when absent) and its record is computed from the registry's specs, marked as
such (``origin = "registry"``). ``exemplar_extras`` builds the
``FineGrid.extras`` keys of ``core/provenance.py``.
"""

from __future__ import annotations

import shlex

from core.provenance import EXEMPLARS, STYLE_SET, STYLE_SET_DIGEST
from stylesets.provenance import StyleSetRecord, builtin_record

#: The set ``decollage train`` uses when its command names none (cli/train.py's ``--set`` default).
TRAIN_DEFAULT_SET = "things"


def checkpoint_style_set(training: dict) -> tuple[StyleSetRecord | None, str]:
    """(the set's record or None, where it came from: ``"checkpoint"``, ``"registry"`` or ``"unknown"``)."""
    recorded = training.get("style_set")
    if isinstance(recorded, dict) and recorded.get("name"):
        return StyleSetRecord.from_json(recorded), "checkpoint"
    name = _set_in_command(str(training.get("command", "")))
    record = builtin_record(name) if name else None
    return record, "registry" if record else "unknown"


def _set_in_command(command: str) -> str | None:
    """The ``--set`` value of a recorded ``decollage train ...`` command (its default when absent)."""
    try:
        words = shlex.split(command)
    except ValueError:
        return None
    if "train" not in words:
        return None
    for i, word in enumerate(words):
        if word == "--set" and i + 1 < len(words):
            return words[i + 1]
        if word.startswith("--set="):
            return word.split("=", 1)[1]
    return TRAIN_DEFAULT_SET


def exemplar_extras(record: StyleSetRecord | None, exemplars: list[str]) -> dict:
    """``FineGrid.extras`` provenance keys for the given exemplar (style) names, in the given order."""
    if record is None:
        return {EXEMPLARS: [{"name": n, "style_set": "", "licence": "unclear: the style set is not known",
                             "attribution": "", "source": "", "requires": "unclear"} for n in exemplars],
                STYLE_SET: None, STYLE_SET_DIGEST: None}
    return {EXEMPLARS: [record.credit(n).to_json() for n in exemplars],
            STYLE_SET: record.name, STYLE_SET_DIGEST: record.digest}
