"""The ``quilt`` detailizer: structure on odd shapes, determinism, styles and parts, sets, errors.

Style sets are made in code at 64³ (4³ coarse cells an exemplar; the real sets use 256³), so no
test builds a real set.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import ndimage

from core.detailizer import get_detailizer
from core.errors import DetailizeError
from core.grid import EMPTY, ISO_LEVEL, LabeledGrid
from model.quilt import QuiltDetailizer
from model.quilt import assemble as asm
from model.quilt import graphcut, search
from model.quilt import detailizer as quilt_detailizer
from model.quilt import library as libm
from model.quilt.search import continuation
from stylesets.format import THINGS, Exemplar, StyleSet, build_set, encode_set

R = 64
SIX = ndimage.generate_binary_structure(3, 1)


# --------------------------------------------------------------------------- sets made in code


def _ribbed() -> np.ndarray:
    """A block (bottom) with a cap (top); horizontal grooves every 4 voxels on its sides."""
    lab = np.zeros((R, R, R), np.uint8)
    lab[6:58, 2:60, 6:58] = 1
    lab[6:58, 44:60, 6:58] = 2
    for y in range(4, 44, 4):
        lab[6:8, y, 6:58] = lab[56:58, y, 6:58] = 0
        lab[6:58, y, 6:8] = lab[6:58, y, 56:58] = 0
    return lab


def _studded() -> np.ndarray:
    """A block with square studs on its sides and top, and a stepped top part."""
    lab = np.zeros((R, R, R), np.uint8)
    lab[8:56, 2:50, 8:56] = 1
    lab[8:56, 40:50, 8:56] = 2
    lab[14:50, 50:56, 14:50] = 2
    for a in range(12, 52, 8):
        for b in range(6, 44, 8):
            lab[a:a + 3, b:b + 3, 5:8] = lab[a:a + 3, b:b + 3, 56:59] = 1
            lab[5:8, b:b + 3, a:a + 3] = lab[56:59, b:b + 3, a:a + 3] = 1
    return lab


def _exemplar(name: str, labels: np.ndarray, category: str = "building") -> Exemplar:
    nz = [np.flatnonzero((labels > 0).any(axis=tuple(b for b in range(3) if b != a))) for a in range(3)]
    crop = labels[tuple(slice(i[0], i[-1] + 1) for i in nz)].copy()
    return Exemplar(labels=crop, offset=tuple(int(i[0]) for i in nz),
                    meta={"name": name, "category": category, "shape": list(crop.shape),
                          "offset": [int(i[0]) for i in nz]})


def _set(*pairs: tuple[str, np.ndarray], name: str = "tiny") -> StyleSet:
    exemplars = tuple(_exemplar(n, lab) for n, lab in pairs)
    return StyleSet(name=name, vocabulary=THINGS, resolution=R, inputs_hash=f"test-{name}-{len(exemplars)}",
                    exemplars=exemplars)


@pytest.fixture(scope="module")
def two() -> QuiltDetailizer:
    return QuiltDetailizer(style_set=_set(("ribbed", _ribbed()), ("studded", _studded())))


def _grid(occ: np.ndarray, styles=("ribbed",), parts=("body", "roof"), style_of=None, part_of=None) -> LabeledGrid:
    style = np.where(occ, 0 if style_of is None else style_of, EMPTY).astype(np.int16)
    if part_of is None:  # the upper third is the roof
        ys = np.nonzero(occ)[1]
        cut = ys.min() + 2 * (ys.max() - ys.min() + 1) // 3 if occ.any() else 0
        part_of = (np.arange(occ.shape[1]) >= cut)[None, :, None].astype(np.int16) * np.ones_like(occ, np.int16)
    part = np.where(occ, part_of, EMPTY).astype(np.int16)
    return LabeledGrid(occupancy=occ, part=part, style=style, part_names=parts, style_names=tuple(styles),
                       voxel_size_m=0.1)


def _check_structure(fine: np.ndarray, occ: np.ndarray) -> None:
    """The coarse shape exactly (Strict = Loose = 1), one body per coarse component, no cavities."""
    binary = fine > ISO_LEVEL
    x, y, z = occ.shape
    pooled = binary.reshape(x, 16, y, 16, z, 16).any(axis=(1, 3, 5))
    assert np.array_equal(pooled, occ), "material outside the coarse cells, or an occupied cell without any"
    _, n_fine = ndimage.label(binary, structure=SIX)
    _, n_coarse = ndimage.label(occ, structure=SIX)
    assert n_fine == n_coarse, f"{n_fine - n_coarse} floating fragment(s)"
    _, n_empty = ndimage.label(np.pad(~binary, 1, constant_values=True), structure=SIX)
    assert n_empty == 1, f"{n_empty - 1} enclosed cavit(y/ies)"
    assert fine.dtype == np.float32 and fine.min() >= 0.0 and fine.max() <= 1.0


# --------------------------------------------------------------------------- structure


def _odd_shapes() -> dict[str, np.ndarray]:
    wall = np.zeros((8, 8, 3), bool)
    wall[1:7, 1:7, 1] = True  # one cell thick
    single = np.zeros((3, 3, 3), bool)
    single[1, 1, 1] = True
    rod_y = np.zeros((3, 22, 3), bool)
    rod_y[1, 1:21, 1] = True  # 1×20×1, upright
    rod_x = np.zeros((22, 3, 3), bool)
    rod_x[1:21, 1, 1] = True  # 1×1×20, lying
    spire = np.zeros((7, 10, 7), bool)
    spire[1:6, 1:4, 1:6] = True
    spire[3, 4:9, 3] = True  # a block with a 1-cell spire
    two = np.zeros((8, 4, 3), bool)
    two[1:3, 1:3, 1] = two[5:7, 1:3, 1] = True  # two separate bodies
    return {"wall": wall, "single": single, "rod_y": rod_y, "rod_x": rod_x, "spire": spire, "two": two}


@pytest.mark.parametrize("shape", list(_odd_shapes()))
def test_odd_shapes_keep_their_structure(two, shape):
    occ = _odd_shapes()[shape]
    fine = two.detailize(_grid(occ), seed=0)
    assert fine.shape == tuple(16 * n for n in occ.shape) and fine.detailizer == "quilt"
    _check_structure(fine.occupancy, occ)


def test_a_box_copies_exemplar_detail_not_a_blob(two):
    """A box in the ribbed style carries the exemplar's grooves on its front, where upsample is flat."""
    occ = np.zeros((6, 6, 6), bool)
    occ[1:5, 1:5, 1:5] = True
    grid = _grid(occ)
    fine = two.detailize(grid, seed=0).occupancy > ISO_LEVEL
    body = fine[24:72, 16:56, :]  # middle of the front, the body part (below the roof third)
    depth = body.shape[2] - 1 - np.argmax(body[:, :, ::-1], axis=2)  # the front surface along +z per (x, y)
    steps = (np.diff(depth, axis=1) != 0).mean()
    assert steps > 0.15, f"the front should be grooved like the exemplar, not flat ({steps:.2f})"
    content, lib, result = two.source_field(grid, 0)
    assert result.continuation > 0.5  # neighbours mostly continue each other in the exemplar


def test_deterministic_and_seeded(two):
    occ = _odd_shapes()["spire"]
    a = two.detailize(_grid(occ), seed=3).occupancy
    b = QuiltDetailizer(style_set=two.style_set).detailize(_grid(occ), seed=3).occupancy
    assert np.array_equal(a, b)
    assert two.detailize(_grid(occ), seed=3).extras["seed"] == 3


def test_prepare_loads_what_detailize_needs_and_changes_nothing(two, monkeypatch):
    """``prepare`` (run before a block process forks) builds the grid's exemplar tables and smoothed
    exemplars, so ``detailize`` loads nothing more; the output is the same as without it."""
    occ = np.zeros((8, 4, 4), bool)
    occ[1:7, 1:3, 1:3] = True
    style_of = (np.arange(8) >= 4)[:, None, None].astype(np.int16) * np.ones((8, 4, 4), np.int16)
    grid = _grid(occ, styles=("studded", "ribbed"), style_of=style_of)
    cold = QuiltDetailizer(style_set=two.style_set)
    want = cold.detailize(grid, seed=2).occupancy
    fresh = QuiltDetailizer(style_set=two.style_set)
    fresh.prepare(grid)
    assert sorted(fresh._tables) == [0, 1] and sorted(fresh._fine) == [0, 1]

    def no_more(*args):
        raise AssertionError("detailize loaded an exemplar that prepare should have loaded")
    monkeypatch.setattr(quilt_detailizer.libm, "build_table", no_more)
    monkeypatch.setattr(quilt_detailizer.asm, "smooth_source", no_more)
    assert np.array_equal(fresh.detailize(grid, seed=2).occupancy, want)
    with pytest.raises(DetailizeError, match="unknown style"):
        fresh.prepare(_grid(occ, styles=("nope",)))


def test_expansions_cut_together_give_what_one_by_one_gives(two):
    """Proposals whose reaches are disjoint are cut as one graph (``commuting_levels``): the field after a
    round is the one that running every proposal alone, in list order, gives; and the levels do batch."""
    occ = np.zeros((10, 6, 6), bool)
    occ[1:9, 1:5, 1:5] = True
    occ[3:7, 2:4, 5] = True
    style_of = (np.arange(10) >= 5)[:, None, None].astype(np.int16) * np.ones(occ.shape, np.int16)
    grid = _grid(occ, styles=("studded", "ribbed"), style_of=style_of)
    content, lib, _ = two.source_field(grid, 0)
    knn = search.nearest_entries(content, lib, np.random.default_rng(3))
    together = knn[:, 0].copy()
    graphcut.expansion_moves(content, lib, together, knn)
    alone = knn[:, 0].copy()
    keys = graphcut.proposals(content, lib, alone, knn)
    costs = graphcut.FieldCosts(content, lib, alone)
    switched = sum(graphcut.expand(costs, graphcut.label_entries(content, lib, k)) for k in keys)
    assert switched > 0 and not np.array_equal(alone, knn[:, 0])
    np.testing.assert_array_equal(together, alone)
    supports = [np.flatnonzero(graphcut.label_entries(content, lib, k) >= 0) for k in keys]
    levels = graphcut.commuting_levels(content, supports)
    assert len(levels) < len(keys) and sorted(i for level in levels for i in level) == list(range(len(keys)))
    for level in levels:  # within a level, no two reaches (support and its neighbours) meet
        seen = np.zeros(len(content), bool)
        for i in level:
            nb = content.nb[supports[i]]
            reach = np.unique(np.concatenate([supports[i], nb[nb >= 0]]))
            assert not seen[reach].any()
            seen[reach] = True


def test_slabs_do_not_change_the_result(two, monkeypatch):
    """Long grids are assembled in slabs of coarse cells along x: the result is the same as in one."""
    occ = np.zeros((12, 3, 3), bool)
    occ[1:11, 1, 1] = True
    occ[3:9, 1, 2] = True
    grid = _grid(occ)
    whole = two.detailize(grid, seed=0).occupancy
    monkeypatch.setattr(asm, "SLAB_CELLS", 2)
    assert np.allclose(two.detailize(grid, seed=0).occupancy, whole, atol=1e-6)


def test_empty_grid_gives_an_empty_field(two):
    occ = np.zeros((3, 3, 3), bool)
    fine = two.detailize(_grid(occ), seed=0)
    assert fine.shape == (48, 48, 48) and not fine.occupancy.any()


# --------------------------------------------------------------------------- styles, parts, sets


def test_two_styles_each_copy_their_own_exemplar(two):
    occ = np.zeros((8, 4, 4), bool)
    occ[1:7, 1:3, 1:3] = True
    style_of = (np.arange(8) >= 4)[:, None, None].astype(np.int16) * np.ones((8, 4, 4), np.int16)
    grid = _grid(occ, styles=("studded", "ribbed"), style_of=style_of)
    content, lib, result = two.source_field(grid, 0)
    names = [two.style_names[lib.exemplars[t]] for t in lib.style[result.field]]
    expected = ["ribbed" if x >= 4 else "studded" for x in content.cells[:, 0]]
    assert names == expected
    fine = two.detailize(grid, seed=0)
    _check_structure(fine.occupancy, occ)
    assert set(np.unique(fine.style[fine.occupancy > ISO_LEVEL])) == {0, 1}


def test_parts_use_their_own_cells_and_accept_aliases(two):
    occ = np.zeros((5, 7, 5), bool)
    occ[1:4, 1:6, 1:4] = True
    for parts in (("body", "roof"), ("bottom", "top")):
        grid = _grid(occ, parts=parts)
        content, lib, result = two.source_field(grid, 0)
        same = lib.part[result.field] == content.part
        assert same.mean() > 0.9
    assert {"bottom", "top", "body", "roof", "pot", "leaf"} <= set(two.part_names)


def test_a_set_with_one_exemplar():
    det = QuiltDetailizer(style_set=_set(("studded", _studded()), name="one"))
    assert det.style_names == ("studded",) and det.learned is False
    occ = _odd_shapes()["wall"]
    _check_structure(det.detailize(_grid(occ, styles=("studded",)), seed=1).occupancy, occ)


def test_library_has_eight_symmetries_and_continuations():
    stats = libm.exemplar_stats(_exemplar("r", _ribbed()).full(R), 2)
    table = libm.build_table(stats)
    assert set(np.unique(table.sym)) == set(range(8))
    assert len(table) == 8 * int((stats.counts >= libm.MIN_FILL * 16**3).sum())
    # an entry's +x continuation sits one cell further along x, same symmetry
    e = int(np.flatnonzero(table.shift[:, 1] >= 0)[0])
    f = table.shift[e, 1]
    assert table.sym[f] == table.sym[e] and list(table.pos[f] - table.pos[e]) == [1, 0, 0]
    # a mirrored, turned block is the same transform of the original cell's block
    ex = _exemplar("r", _ribbed())
    block = asm.smooth_source(ex.labels, ex.offset, R)
    assert np.array_equal(block, asm.smooth_source(ex.full(R)))  # the box gives what the whole grid gives
    whole = libm.exemplar_stats(ex.full(R), 2)
    boxed = libm.exemplar_stats_of(ex.labels, ex.offset, R, 2)
    assert all(np.array_equal(getattr(whole, k), getattr(boxed, k)) for k in ("counts", "part", "mid"))
    lib = libm.combine([table], [0])
    for entry in np.flatnonzero(table.sym == 5)[:3]:
        o = table.orig[entry] * 16
        original = block[o[0]:o[0] + 24, o[1]:o[1] + 24, o[2]:o[2] + 24]
        assert np.array_equal(asm.source_block(lib, [block], int(entry)), libm.apply_sym(original, 5))


def test_continuation_is_one_for_a_copied_exemplar(two):
    """Max-pooling an exemplar and detailizing it in its own style finds it again, seams and all."""
    labels = two.style_set.exemplars[0].full(R)
    occ = np.pad((labels > 0).reshape(4, 16, 4, 16, 4, 16).any(axis=(1, 3, 5)), 1)
    grid = _grid(occ)
    content, lib, result = two.source_field(grid, 0)
    assert continuation(content, lib, result.field) > 0.9


# --------------------------------------------------------------------------- set files, cache, registry


def _write_set(folder, style_set: StyleSet):
    path = folder / f"{style_set.name}.npz"
    path.write_bytes(encode_set(style_set.name, style_set.vocabulary, R, style_set.inputs_hash,
                                style_set.exemplars))
    return path


def test_set_files_by_path_and_name_and_the_stats_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("DECOLLAGE_STYLES_DIR", str(tmp_path))
    path = _write_set(tmp_path, _set(("ribbed", _ribbed()), ("studded", _studded()), name="mine"))
    by_path = get_detailizer("quilt", str(path))
    assert by_path.name == "quilt" and by_path.learned is False
    assert by_path.style_names == ("ribbed", "studded")
    occ = _odd_shapes()["spire"]
    first = by_path.detailize(_grid(occ), seed=0).occupancy
    cached = list((tmp_path / "quilt").glob("mine-*.npz"))
    assert len(cached) == 1
    by_name = QuiltDetailizer(checkpoint="mine")  # also as the build passes it: <recipe dir>/mine
    again = QuiltDetailizer(checkpoint=str(tmp_path / "recipes" / "mine")).detailize(_grid(occ), seed=0)
    assert np.array_equal(by_name.detailize(_grid(occ), seed=0).occupancy, first)
    assert np.array_equal(again.occupancy, first)


def test_a_user_imported_set(tmp_path, monkeypatch):
    from stylesets.user_import import import_folder

    monkeypatch.setenv("DECOLLAGE_STYLES_DIR", str(tmp_path / "styles"))
    folder = tmp_path / "meshes"
    (folder / "hut").mkdir(parents=True)
    body = trimesh.creation.box((0.8, 0.5, 0.8))
    body.apply_translation((0, 0.25, 0))
    for x in (-0.3, 0.0, 0.3):  # pilasters: detail on the walls
        post = trimesh.creation.box((0.08, 0.5, 0.9))
        post.apply_translation((x, 0.25, 0))
        body = trimesh.util.concatenate([body, post])
    body.export(folder / "hut" / "body.stl")
    roof = trimesh.creation.cone(0.6, 0.4)
    roof.apply_translation((0, 0.5, 0))
    roof.export(folder / "hut" / "roof.stl")
    import_folder(folder, "huts", THINGS, resolution=R)
    det = get_detailizer("quilt", "huts")
    assert det.style_names == ("hut",)
    occ = np.zeros((6, 6, 4), bool)
    occ[1:5, 1:5, 1:3] = True
    _check_structure(det.detailize(_grid(occ, styles=("hut",)), seed=0).occupancy, occ)


@pytest.mark.parametrize("case, message", [
    ("unknown_style", "unknown style 'gothic'"),
    ("unknown_part", "unknown part 'chimney'"),
    ("empty_set", "has no exemplars"),
    ("unknown_set", "unknown style set 'nowhere'"),
    ("broken_file", "not a usable style set"),
])
def test_bad_inputs_are_one_line_errors(case, message, two, tmp_path, monkeypatch):
    monkeypatch.setenv("DECOLLAGE_STYLES_DIR", str(tmp_path))
    occ = _odd_shapes()["single"]
    with pytest.raises(DetailizeError) as err:
        if case == "unknown_style":
            two.detailize(_grid(occ, styles=("gothic",)), seed=0)
        elif case == "unknown_part":
            two.detailize(_grid(occ, parts=("chimney", "roof"), part_of=np.zeros(occ.shape, np.int16)), seed=0)
        elif case == "empty_set":
            QuiltDetailizer(style_set=_set(name="void"))
        elif case == "unknown_set":
            QuiltDetailizer(checkpoint="nowhere")
        else:
            (tmp_path / "broken.npz").write_bytes(b"not a zip")
            QuiltDetailizer(checkpoint=str(tmp_path / "broken.npz"))
    line = err.value.one_line()
    assert message in line and "\n" not in line and err.value.hint


def test_build_set_then_detailize_through_the_registry(tmp_path, monkeypatch):
    """A set built by the project's own builder (procedural specs) is usable by name at once."""
    from functools import partial

    from stylesets.catalogues.prims import box
    from stylesets.format import ExemplarSpec

    monkeypatch.setenv("DECOLLAGE_STYLES_DIR", str(tmp_path))

    def steps() -> dict:
        return {"bottom": [box((1.0 - 0.2 * i, 0.2, 1.0 - 0.2 * i), (0, 0.1 + 0.2 * i, 0)) for i in range(4)],
                "top": box((0.15, 0.3, 0.15), (0, 0.95, 0))}

    build_set("stairs", THINGS, [ExemplarSpec("ziggurat", "building", partial(steps), "steps")],
              resolution=R)
    det = get_detailizer("quilt", "stairs")
    occ = _odd_shapes()["rod_y"]
    _check_structure(det.detailize(_grid(occ, styles=("ziggurat",)), seed=0).occupancy, occ)


def test_blend_weights_are_normalised_per_neighbourhood():
    """``den_blocks`` (per 3×3×3 pattern) equals the scattered sum of the occupied cells' block weights,
    exactly (every weight is a multiple of 1/(4·HALO)), and one code alone gives the same bits as a batch."""
    rng = np.random.default_rng(0)
    occ = rng.random((5, 5, 5)) < 0.6
    h, b = asm.HALO, 16 + 2 * asm.HALO
    total = np.zeros((5 * 16 + 2 * h,) * 3, np.float32)
    for i, j, k in np.argwhere(occ):
        total[16 * i:16 * i + b, 16 * j:16 * j + b, 16 * k:16 * k + b] += asm.ramp_weights()
    codes = asm.neighbourhood_codes(occ)
    uniq, dens = asm.den_blocks(codes[occ])
    assert len(uniq) > 20
    for i, j, k in np.argwhere(occ):
        got = dens[np.searchsorted(uniq, codes[i, j, k])]
        want = total[h + 16 * i:h + 16 * i + 16, h + 16 * j:h + 16 * j + 16, h + 16 * k:h + 16 * k + 16]
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(asm.den_blocks(codes[i, j, k:k + 1])[1][0], got)
        assert got.min() > 0.05  # a cell's own block always weighs in


def test_a_thin_exemplar_and_a_one_cell_grid():
    """A wire exemplar (no cell even 8 % full) still serves every cell, joined into one body; a grid of
    a single occupied cell touching every border works too."""
    wire = np.zeros((R, R, R), np.uint8)
    wire[30:32, 2:62, 30:32] = 1
    wire[30:32, 50:62, 30:32] = 2
    det = QuiltDetailizer(style_set=_set(("wire", wire), name="wire"))
    occ = np.zeros((5, 5, 5), bool)
    occ[1:4, 1:4, 1:4] = True
    _check_structure(det.detailize(_grid(occ, styles=("wire",)), seed=0).occupancy, occ)
    one = np.ones((1, 1, 1), bool)
    _check_structure(det.detailize(_grid(one, styles=("wire",)), seed=0).occupancy, one)


def test_a_recipe_names_quilts_style_set_with_style_set(tmp_path, monkeypatch):
    """``detailize.style_set`` picks the set (by name, resolved like the build resolves it); ``checkpoint`` with
    quilt and ``style_set`` with the model are recipe errors that say which field to write."""
    from pipeline.batch import build_recipe
    from core.errors import RecipeError
    from core.recipe_loader import load_recipe

    monkeypatch.setenv("DECOLLAGE_STYLES_DIR", str(tmp_path / "styles"))
    (tmp_path / "styles").mkdir()
    _write_set(tmp_path / "styles", _set(("ribbed", _ribbed()), ("studded", _studded()), name="mine"))
    asset = ("  - name: block\n    source: {kind: cad, parts: [{name: b, shape: box, size: [0.4, 0.4, 0.4]}]}\n"
             "    regions: [{part: body, style: studded}]\n")
    (tmp_path / "r.yaml").write_text("version: 1\ndefaults: {detailize: {detailizer: quilt, style_set: mine}}\n"
                                     "assets:\n" + asset)
    reports = build_recipe(load_recipe(tmp_path / "r.yaml"), tmp_path / "out")
    assert [r.status for r in reports] == ["built"], [r.error for r in reports]
    manifest = (tmp_path / "out" / "manifest.json").read_text()
    assert '"style_set": "mine"' in manifest
    for settings, field in (("{detailizer: quilt, checkpoint: mine}", "style_set"),
                            ("{detailizer: decollage, style_set: mine}", "remove 'style_set'")):
        (tmp_path / "bad.yaml").write_text(f"version: 1\ndefaults: {{detailize: {settings}}}\nassets:\n" + asset)
        with pytest.raises(RecipeError) as err:
            load_recipe(tmp_path / "bad.yaml")
        assert field in err.value.one_line() and "detailize" in err.value.one_line()


@pytest.mark.parametrize("empty", [False, True])
def test_block_labels_number_each_block_as_labelling_it_alone(empty):
    from model.quilt import repair

    rng = np.random.default_rng(3)
    fine = (rng.random((3 * 16, 2 * 16, 16)) < 0.45).astype(np.float32)
    fine[:16, :16] = 1.0  # a full block
    fine[16:32, :16] = 0.0  # an empty one
    cells = np.argwhere(np.ones((3, 2, 1), bool))
    labels, counts = repair.block_labels(fine, cells, empty)
    six = ndimage.generate_binary_structure(3, 1)
    seen = 0
    for q, (i, j, k) in enumerate(cells):
        block = fine[16 * i:16 * i + 16, 16 * j:16 * j + 16, 16 * k:16 * k + 16]
        alone, m = ndimage.label(block < ISO_LEVEL if empty else block >= ISO_LEVEL, structure=six)
        np.testing.assert_array_equal(labels[q], np.where(alone > 0, alone + seen, 0))
        assert counts[q] == m
        seen += m
    only_full, n_full = repair.block_labels(np.ones((32, 16, 16), np.float32), np.array([[0, 0, 0], [1, 0, 0]]))
    assert list(n_full) == [1, 1] and (only_full[0] == 1).all() and (only_full[1] == 2).all()


def test_block_parts_refreshed_in_the_changed_cells_equal_a_fresh_labelling():
    from model.quilt import repair

    rng = np.random.default_rng(5)
    occ = np.ones((3, 2, 2), bool)
    occ[2, 1, 1] = False
    fine = (rng.random((48, 32, 32)) < 0.5).astype(np.float32) * occ.repeat(16, 0).repeat(16, 1).repeat(16, 2)
    content = repair.cell_graph(occ)
    parts = repair.BlockParts.of(fine, content)
    fine[16:32, 0:16, 16:32] = 1.0  # cell (1, 0, 1): one component now
    fine[0:16, 16:32, 0:16] = (rng.random((16, 16, 16)) < 0.3)  # cell (0, 1, 0): new components
    parts.refresh(fine, content, np.array([content.ids[1, 0, 1], content.ids[0, 1, 0]]))
    fresh = repair.BlockParts.of(fine, content)
    np.testing.assert_array_equal(parts.count, fresh.count)
    np.testing.assert_array_equal(parts.faces, fresh.faces)
    assert all(np.array_equal(a, b) for a, b in zip(parts.sizes, fresh.sizes))
    assert parts.count[content.ids[1, 0, 1]] == 1
    for got, want in zip(repair.fine_components(fine, content, parts=parts), repair.fine_components(fine, content)):
        np.testing.assert_array_equal(got, want)


def test_enclosed_cavities_are_filled_and_open_pockets_kept():
    from model.quilt import repair

    occ = np.ones((3, 2, 1), bool)
    fine = np.ones((48, 32, 16), np.float32)
    fine[5:9, 5:9, 5:9] = 0  # inside cell (0, 0, 0)
    fine[20:22, 20:23, 4:6] = 0  # inside cell (1, 1, 0)
    fine[15:18, 2:4, 2:4] = 0  # across the face between cells (0, 0, 0) and (1, 0, 0)
    fine[40:48, 0:3, 0:3] = 0  # reaches the grid's border: open to the outside
    assert repair.fill_cavities(fine, repair.cell_graph(occ)) == 3
    assert (fine[:40] == 1).all() and (fine[40:48, 0:3, 0:3] == 0).all()
