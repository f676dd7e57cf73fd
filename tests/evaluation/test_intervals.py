"""Bootstrap intervals over contents and paired differences (evaluation/intervals.py), and the dev/test split."""

from __future__ import annotations

import json

import numpy as np
import pytest

from evaluation.intervals import bootstrap_mean, paired_difference
from evaluation.protocol import DEFAULT_PROTOCOL, PROTOCOL_DIR, ProtocolError, load_protocol, make_split


def _draw(n_contents: int, per: int = 4, seed: int = 0):
    rng = np.random.default_rng(seed)
    effects = rng.permutation(np.linspace(0.3, 0.7, n_contents))  # the same spread whatever the count
    values = [float(e + rng.normal(0, 0.02)) for e in effects for _ in range(per)]
    groups = [f"c{i}" for i in range(n_contents) for _ in range(per)]
    return values, groups


def test_interval_holds_the_mean_and_shrinks_with_more_contents():
    widths = []
    for n in (5, 20, 80):
        values, groups = _draw(n)
        est = bootstrap_mean(values, groups)
        assert est.lo < est.mean < est.hi and est.n_contents == n and est.n_outputs == 4 * n
        widths.append(est.hi - est.lo)
    assert widths[0] > widths[1] > widths[2]
    assert widths[0] / widths[2] > 2.5  # about √16 = 4 in theory


def test_resampling_is_by_content_not_by_output():
    """Outputs of one content move together: many outputs per content must not narrow the interval."""
    few, groups_few = _draw(10, per=2, seed=1)
    many = [v for v in few for _ in range(8)]
    groups_many = [g for g in groups_few for _ in range(8)]
    a, b = bootstrap_mean(few, groups_few), bootstrap_mean(many, groups_many)
    assert b.hi - b.lo == pytest.approx(a.hi - a.lo, rel=0.02)


def test_interval_is_seeded_and_skips_missing_values():
    values, groups = _draw(8)
    assert bootstrap_mean(values, groups) == bootstrap_mean(values, groups)
    est = bootstrap_mean(values + [None], groups + ["c0"])
    assert est.n_outputs == len(values)
    one = bootstrap_mean([0.2, 0.4], ["c0", "c0"])
    assert one.mean == pytest.approx(0.3) and one.lo is None and one.format() == "0.300"


def test_paired_difference_cancels_what_both_share():
    values, groups = _draw(12)
    ids = [f"o{i}" for i in range(len(values))]
    base = dict(zip(ids, values))
    better = {o: v + 0.01 for o, v in base.items()}
    diff = paired_difference(better, base, dict(zip(ids, groups)))
    assert diff.mean == pytest.approx(0.01) and diff.hi - diff.lo < 1e-9
    unpaired = bootstrap_mean(list(better.values()), groups)
    assert unpaired.hi - unpaired.lo > 0.05  # the same 0.01 step is invisible without pairing
    assert "+0.010 [+0.010, +0.010]" == diff.format(signed=True)


def test_split_is_stratified_fixed_by_the_ids_and_stored():
    contents = [(f"t{i}", "text") for i in range(4)] + [(f"a{i}", "aug") for i in range(5)]
    split = make_split(contents)
    assert {k: set(v) for k, v in make_split(list(reversed(contents))).items()} == {k: set(v) for k, v in split.items()}
    assert sum(c.startswith("t") for c in split["test"]) == 2 and sum(c.startswith("a") for c in split["test"]) == 3
    assert not set(split["dev"]) & set(split["test"])
    # adding a content of another kind moves nothing
    more = make_split(contents + [("m0", "mesh")])
    assert set(split["test"]) <= set(more["test"]) and set(split["dev"]) <= set(more["dev"])


def test_shipped_split_is_the_recorded_one_and_v1_stays_readable():
    p = load_protocol(DEFAULT_PROTOCOL)
    assert p.meta["version"] == 2 and p.split is not None
    kinds = [(cid, info["kind"]) for cid, info in p.content_info.items()]
    assert {k: list(v) for k, v in p.split.items()} == make_split(kinds)
    test, dev = p.outputs_of("test"), p.outputs_of("dev")
    assert len(test) + len(dev) == len(p.outputs) and not {o.id for o in test} & {o.id for o in dev}
    v1 = load_protocol(PROTOCOL_DIR / "things_v1.json")
    assert v1.split is None and [o.id for o in v1.outputs] == [o.id for o in p.outputs]
    with pytest.raises(ProtocolError, match="no dev/test split"):
        v1.outputs_of("test")


def test_a_broken_split_is_refused(tmp_path):
    meta = json.loads(DEFAULT_PROTOCOL.read_text())
    meta["split"]["dev"].append(meta["split"]["test"][0])
    (tmp_path / meta["contents_file"]).write_bytes((PROTOCOL_DIR / meta["contents_file"]).read_bytes())
    (tmp_path / "p.json").write_text(json.dumps(meta))
    with pytest.raises(ProtocolError, match="exactly one"):
        load_protocol(tmp_path / "p.json")
