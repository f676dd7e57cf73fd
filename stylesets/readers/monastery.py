"""Real buildings for the ``monastery`` style set: the temples of pybullet's ``samurai_monastry.obj``.

Role: finds the model in the installed ``pybullet_data`` package (PyPI
``pybullet``; nothing is downloaded or copied into the repository), splits it
into buildings and labels each building's faces ``body`` or ``roof``
(vocabulary ``THINGS``, category ``building``). ``monastery_specs`` gives one
``ExemplarSpec`` per building; the OBJ is each spec's input file, so the set's
cache key changes when the file does.

The model (Blender 2.66 export of a Maya scene; one ``o`` object, 124,789
triangles after fan-splitting, 81 materials, +Y up, about 125 × 30 × 121
units): a walled courtyard with a central platform, a gate, a main temple, two
side temples, three long halls, four small shrines, two small roofed
gateways, four pagodas, a torii-like gateway, and stone and paper lanterns.
The material names carry the Maya reference the faces came from
(``Out_Temple1:Out_Temple:lambert2SG`` = material ``lambert2SG`` of the second
copy of ``Out_Temple``).

Splitting (``split_buildings``), in the file's own frame:

1. A building's *family* is a set of material-name prefixes (the text before
   the first ``:``; ``""`` = names without one), from the hand-written
   ``BUILDINGS`` table. Only the family's faces are considered.
2. Those faces are split into vertex-connected components (positions merged).
   Components whose X/Z bounding rectangles come within ``GAP`` units of each
   other are joined (single linkage): each group is one standing copy.
3. The copy whose X/Z rectangle contains the building's ``anchor`` point is
   the exemplar; a table entry whose anchor lies in no copy is an error (the
   file is not the one this table was written for).

Labels (``roof_mask``): ``ROOF_MATERIALS`` (hand-written: the roof-tile
materials, found by looking at every material of every building) are ``roof``,
every other face of the building is ``body``. Materials that mix roof and
body pieces (eave edges, ridge trims drawn with wall materials) stay ``body``.
A building whose roofs share one material with its body (the pagoda) uses the
``tiers`` rule instead: a connected component is roof when its faces'
area-weighted mean ``|normal·Y|`` is at least ``TIER_MIN_UP`` (the eave tiers
are flat, wide shells; walls, posts and brackets are mostly vertical), and so
is every component lying wholly above the lowest point of the topmost tier (the
spire).

Voxels (``building_parts``): the meshes are open almost everywhere (roof
shells without undersides, posts without caps, single-sided panels), so each
connected component is filled on its own, the voxels its faces pass through
are added (thin panels and trims survive), and the result is handed to
``make_exemplar`` as closed voxel-cube surfaces on exactly the grid it uses.

Kept: one copy of each distinct design (7 buildings, see ``BUILDINGS``).
Left out: the courtyard walls and ground (``Arena_02``, ``Floor_04``: a ring
of covered walkways, no building), the central platform (``blinn7SG`` posts,
``Arena_02`` floor), lanterns, the torii-like gateway (``MainEntrance``
posts and beams 10 units in front of the gate, no roof), the mirrored second
side temple (``SideTemple03``), the second and third long hall
(``Out_Temple1`` and the unprefixed ``blinn2SG``..``blinn6SG``: the same
design, face counts within 2 %), and the second copy of each shrine and the
three other pagodas: copies add no detail of their own. Also left out: the
small roofed gateways (``MediumTemple``/``SmallTemple`` at x ≈ 18, z ≈ ±12.6):
low-poly, 2.5 units across, their single-sided roof sheet fills wrongly at
256³ (a flat slab where a slope should be, stray trim wires), though the
detail ratio passes (1.64).

Licence: pybullet is zlib-licensed (the wheel's ``LICENSE.txt``); neither the
wheel nor the bullet3 repository's ``data/`` folder has a licence file, author
or origin note for this model (``data/LICENSE.txt`` there only says that the
URDF files were made by Erwin Coumans and to check the subdirectories). So the
model's own licence is recorded as unclear (``LICENCE``) rather than guessed;
see NOTICE.
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from geometry.voxelize import solid_occupancy
from stylesets.format import RESOLUTION, ExemplarError, ExemplarSpec, fit_voxels
from stylesets.readers.file_cache import cached_per_file
from stylesets.readers.obj_text import GroupedObj, parse_obj

if TYPE_CHECKING:
    import trimesh

PACKAGE = "pybullet_data"
PIP_REQUIREMENT = "pybullet==3.2.7"
REINSTALL_HINT = f"reinstall it: pip install --force-reinstall {PIP_REQUIREMENT}"
OBJ_NAME = "samurai_monastry.obj"
SOURCE = "pybullet_data samurai_monastry.obj"
LICENCE = ("unclear: no licence stated for this model; distributed in pybullet 3.2.7's pybullet_data, "
           "whose package licence is zlib")
ATTRIBUTION = ("samurai_monastry.obj from pybullet_data (pybullet 3.2.7, Bullet Physics SDK, "
               "https://github.com/bulletphysics/bullet3); model author not recorded")
INSTALL_HINT = f"pip install {PIP_REQUIREMENT} (or: bash scripts/install.sh exemplars)"

#: Copies (connected components) closer than this (file units) in X/Z belong to one building.
GAP = 0.5
#: ``tiers`` rule: a component whose area-weighted mean |normal·Y| reaches this is a roof tier.
TIER_MIN_UP = 0.6


@dataclass(frozen=True)
class Building:
    """One building of the model.

    families: material-name prefixes whose faces make it ("" = names without a prefix).
    anchor: (x, z) in the file's frame, inside the wanted copy's footprint.
    roof: "materials" (``ROOF_MATERIALS``) or "tiers" (the geometric rule, module docstring).
    note: what it is.
    """

    families: tuple[str, ...]
    anchor: tuple[float, float]
    roof: str = "materials"
    note: str = ""


#: name → building (one copy of each distinct design).
BUILDINGS: dict[str, Building] = {
    "main_gate": Building(("MainEntrance",), (47.0, 0.0),
                          note="two-storey gate, hipped roofs with flared eaves, bracket sets"),
    "main_temple": Building(("MainTemple", "MainTemple1"), (-24.0, 0.0),
                            note="main hall, stepped hip-and-gable roof over a wide veranda"),
    "side_temple": Building(("SideTemple", "SideTemple04"), (0.0, -26.0),
                            note="long side hall, gabled roof with end finials, posts and railings"),
    "long_hall": Building(("Out_Temple",), (34.0, -52.0),
                          note="long outer hall, two-tier hipped roof, colonnade"),
    "shrine_porch": Building(("MediumTemple", "SmallTemple"), (-23.5, -25.0),
                             note="small shrine with curved gable roof, arched windows, deck and steps"),
    "shrine": Building(("MediumTemple", "SmallTemple"), (21.0, -24.5),
                       note="small shrine with curved gable roof and arched windows"),
    "pagoda": Building(("pagodas",), (-48.5, 29.4), roof="tiers",
                       note="five-tier pagoda with spire, on a raised base"),
}

#: Hand-written label map: the materials that are roofs (all other faces of a building are body).
ROOF_MATERIALS: frozenset[str] = frozenset({
    "MainEntrance:MainEntrance:blinn2SG",      # gate: both roofs' tiles
    "MainTemple:MainTemple:blinn2SG",          # main temple: all three roof tiers
    "SideTemple:SideTemple:Material9SG",       # side temple roof
    "SideTemple03:SideTemple1:Material9SG",    # (mirrored copy, not built)
    "Out_Temple:Out_Temple:lambert2SG",        # long hall: both roof tiers
    "Out_Temple1:Out_Temple:lambert2SG",       # (copy, not built)
    "blinn6SG",                                # (unprefixed copy of the long hall, not built)
    "MediumTemple:MediumTemple:blinn1SG",      # shrines and shrine gates: curved roof sheet
    "SmallTemple:SmallTemple:lambert2SG",      # shrine: roof
})


# --------------------------------------------------------------------------- finding and reading


def find_obj() -> Path:
    """Path of ``samurai_monastry.obj`` in the installed ``pybullet_data``; ExemplarError if missing."""
    try:
        spec = importlib.util.find_spec(PACKAGE)
    except (ImportError, ValueError):
        spec = None
    folders = [Path(p) for p in (spec.submodule_search_locations or [])] if spec is not None else []
    for folder in folders:
        if (folder / OBJ_NAME).is_file():
            return folder / OBJ_NAME
    if spec is None:
        raise ExemplarError(f"the 'monastery' set needs the Python package {PACKAGE} (from PyPI pybullet), "
                            "which is not installed", field="set", hint=INSTALL_HINT)
    raise ExemplarError(f"{PACKAGE} is installed but has no {OBJ_NAME}", field="set", hint=REINSTALL_HINT)


def read_obj(path: Path) -> GroupedObj:
    """Positions, triangles (polygons fan-split) and per-face materials (``usemtl``) of an OBJ file.

    Cached per process by path, size and modification time (every exemplar reads the same file).
    """
    try:
        return _read_obj(path)
    except OSError as exc:
        raise ExemplarError(f"cannot read {path}: {exc.strerror}", file=path, hint=REINSTALL_HINT) from None


@cached_per_file(maxsize=2)
def _read_obj(path: Path) -> GroupedObj:
    with open(path, "r", encoding="utf-8", errors="replace") as handle:
        return parse_obj(handle, str(path), REINSTALL_HINT, file=path)


# --------------------------------------------------------------------------- splitting and labelling


def family_of(material: str) -> str:
    """A material's family: the text before its first ':' ("" when it has none)."""
    return material.split(":", 1)[0] if ":" in material else ""


def face_components(obj: GroupedObj, faces: np.ndarray) -> np.ndarray:
    """(len(faces),) component id of each of ``faces`` (connected through shared vertex positions)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    tri = obj.faces[faces]
    used, local = np.unique(tri.reshape(-1), return_inverse=True)
    _, merged = np.unique(obj.vertices[used], axis=0, return_inverse=True)
    corners = merged.reshape(-1)[local].reshape(-1, 3)
    n = int(corners.max()) + 1 if corners.size else 0
    rows = np.concatenate([corners[:, 0], corners[:, 1]])
    cols = np.concatenate([corners[:, 1], corners[:, 2]])
    graph = coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return labels[corners[:, 0]]


def _copies(obj: GroupedObj, faces: np.ndarray, gap: float) -> list[np.ndarray]:
    """``faces`` grouped into standing copies: components joined when their X/Z rectangles are ≤ gap apart."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    comp = face_components(obj, faces)
    order = np.argsort(comp, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(comp[order]) != 0])
    groups = np.split(order, starts[1:])
    xz = obj.vertices[:, [0, 2]]
    lo = np.array([xz[obj.faces[faces[g]].reshape(-1)].min(axis=0) for g in groups])
    hi = np.array([xz[obj.faces[faces[g]].reshape(-1)].max(axis=0) for g in groups])
    near = ((lo[:, None] - gap <= hi[None]) & (lo[None] - gap <= hi[:, None])).all(axis=-1)
    _, copy = connected_components(coo_matrix(near), directed=False)
    return [np.sort(np.concatenate([g for g, c in zip(groups, copy) if c == k])) for k in range(copy.max() + 1)]


def split_buildings(obj: GroupedObj, buildings: Mapping[str, Building] = BUILDINGS,
                    gap: float = GAP) -> dict[str, np.ndarray]:
    """name → sorted face indices of that building (module docstring, "Splitting")."""
    family = np.array([family_of(m) for m in obj.materials] + [""], dtype=object)  # index -1 → ""
    face_family = family[obj.material]
    out: dict[str, np.ndarray] = {}
    for name, building in buildings.items():
        faces = np.flatnonzero(np.isin(face_family, list(building.families)))
        if len(faces) == 0:
            raise ExemplarError(f"building '{name}': no faces with materials "
                                + ", ".join(f"'{f}:*'" for f in building.families), field=name,
                                hint=f"the label map was written for {OBJ_NAME} of {PIP_REQUIREMENT}")
        x, z = building.anchor
        found = None
        for copy in _copies(obj, faces, gap):
            pts = obj.vertices[obj.faces[faces[copy]].reshape(-1)][:, [0, 2]]
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            if lo[0] <= x <= hi[0] and lo[1] <= z <= hi[1]:
                found = faces[copy]
                break
        if found is None:
            raise ExemplarError(f"building '{name}': no copy stands at x={x}, z={z}", field=name,
                                hint=f"the label map was written for {OBJ_NAME} of {PIP_REQUIREMENT}")
        out[name] = found
    return out


def roof_mask(obj: GroupedObj, faces: np.ndarray, rule: str = "materials",
              roof_materials: frozenset[str] | set[str] = ROOF_MATERIALS,
              min_up: float = TIER_MIN_UP) -> np.ndarray:
    """(len(faces),) bool: which of a building's faces are roof (module docstring, "Labels")."""
    if rule == "materials":
        return np.array([m in roof_materials for m in obj.material_names(faces)], dtype=bool)
    if rule != "tiers":
        raise ValueError(f"unknown roof rule {rule!r}")
    tri = obj.vertices[obj.faces[faces]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(normal, axis=1)
    up = np.abs(normal[:, 1])  # |n·Y| × 2·area
    comp = face_components(obj, faces)
    n = comp.max() + 1
    tier = np.bincount(comp, up, n) >= min_up * np.maximum(np.bincount(comp, area, n), 1e-30)
    tier &= np.bincount(comp, area, n) > 0
    if tier.any():
        low = np.full(n, np.inf)
        np.minimum.at(low, comp, tri[:, :, 1].min(axis=1))
        tier |= low >= low[tier].max() - 1e-9  # wholly above the lowest point of the topmost tier
    return tier[comp]


def lattice(lo: np.ndarray, hi: np.ndarray, resolution: int = RESOLUTION) -> tuple[np.ndarray, float, tuple]:
    """(origin, voxel, dims) of the grid ``geometry.voxelize`` puts a shape of bounds ``lo``..``hi`` in.

    Longest side = ``fit_voxels(resolution)`` voxels, every side rounded up, centred (as
    ``make_exemplar`` asks the voxelizer for: fit longest).
    """
    extent = np.asarray(hi, float) - np.asarray(lo, float)
    voxel = float(extent.max()) / fit_voxels(resolution)
    dims = tuple(max(1, math.ceil(float(e) / voxel - 1e-9)) for e in extent)
    origin = (np.asarray(lo, float) + np.asarray(hi, float)) / 2 - np.asarray(dims) * voxel / 2
    return origin, voxel, dims


def surface_voxels(tri: np.ndarray, labels: np.ndarray, origin: np.ndarray, voxel: float,
                   shape: tuple) -> np.ndarray:
    """``shape`` uint8 grid (voxel 0 at ``origin``): the largest ``labels`` value of the triangles through each voxel.

    Each triangle is sampled on a barycentric grid at most half a voxel apart,
    so every voxel it passes through by more than a sliver is hit (thin panels,
    ropes and trims that no voxel centre lies inside stay in the grid). 0 = no
    triangle; labels must be 1..255. Points outside the grid count in its nearest voxel
    (callers pass grids that hold the triangles; this catches faces on the far boundary).
    """
    tri = np.asarray(tri, dtype=np.float64)
    labels = np.asarray(labels, dtype=np.uint8)
    out = np.zeros(shape, dtype=np.uint8)
    if len(tri) == 0:
        return out
    edge = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    steps = np.ceil(edge / (0.5 * voxel)).astype(np.int64) + 1
    size = np.asarray(shape)
    for label in np.unique(labels):  # ascending: a larger label overwrites a smaller one
        for n in np.unique(steps[labels == label]):
            members = np.flatnonzero((steps == n) & (labels == label))
            u, v = np.meshgrid(np.linspace(0.0, 1.0, n), np.linspace(0.0, 1.0, n), indexing="ij")
            keep = u + v <= 1.0 + 1e-9
            u, v = u[keep], v[keep]
            for chunk in np.array_split(members, len(members) * len(u) // 1_000_000 + 1):
                t = tri[chunk]
                pts = t[:, None, 0] + u[None, :, None] * (t[:, None, 1] - t[:, None, 0]) \
                    + v[None, :, None] * (t[:, None, 2] - t[:, None, 0])
                ijk = np.floor((pts.reshape(-1, 3) - origin) / voxel).astype(np.int64)
                ijk = np.clip(ijk, 0, size - 1)  # a face on the grid's far side lies in its last voxel
                out[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = label
    return out


def labelled_fill(obj: GroupedObj, faces: np.ndarray, roof: np.ndarray, origin: np.ndarray, voxel: float,
                  dims: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(body, roof): (X, Y, Z) bool occupancy of a building's body and roof faces on the given grid.

    Each connected component (over all of the building's faces, whatever
    their material: a roof sheet and the ridge trim drawn with a body
    material close each other) is filled on its own by
    ``geometry.voxelize.solid_occupancy`` in its own box (exact when closed,
    3-axis parity vote when open), so a ray escaping through one open shell
    cannot pair up with another component's surface. The voxels its faces
    pass through (``surface_voxels``) are added. Surface voxels take their
    faces' part (roof where both), filled voxels the part of the nearest
    surface voxel of their component; roof wins where components overlap.
    """
    import trimesh
    from scipy import ndimage


    body_occ = np.zeros(dims, dtype=bool)
    roof_occ = np.zeros(dims, dtype=bool)
    if len(faces) == 0:
        return body_occ, roof_occ
    comp = face_components(obj, faces)
    order = np.argsort(comp, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(comp[order]) != 0])
    for members in np.split(order, starts[1:]):
        tri_index = obj.faces[faces[members]]
        used, local = np.unique(tri_index.reshape(-1), return_inverse=True)
        vertices = obj.vertices[used]
        lo = np.floor((vertices.min(axis=0) - origin) / voxel).astype(np.int64) - 1
        hi = np.ceil((vertices.max(axis=0) - origin) / voxel).astype(np.int64) + 1
        lo, hi = np.maximum(lo, 0), np.minimum(hi, dims)
        if np.any(hi <= lo):
            continue
        shape = tuple(int(n) for n in hi - lo)
        local_origin = origin + lo * voxel
        mesh = trimesh.Trimesh(vertices=vertices, faces=local.reshape(-1, 3), process=False)
        inside = solid_occupancy(mesh, shape, local_origin, voxel) > 0.5
        on_roof = roof[members]
        surface = surface_voxels(vertices[local.reshape(-1, 3)], np.where(on_roof, 2, 1),  # 1 body, 2 roof
                                 local_origin, voxel, shape)
        if on_roof.all() or not on_roof.any() or not surface.any():
            is_roof = np.full(shape, bool(on_roof.all()))
        else:
            nearest = ndimage.distance_transform_edt(surface == 0, return_distances=False, return_indices=True)
            is_roof = surface[tuple(nearest)] == 2
        solid = inside | (surface > 0)
        window = tuple(slice(a, b) for a, b in zip(lo, hi))
        roof_occ[window] |= solid & is_roof
        body_occ[window] |= solid & ~is_roof
    return body_occ & ~roof_occ, roof_occ


def box_mesh(occ: np.ndarray, origin: np.ndarray, voxel: float) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of the boundary of the occupied voxels' cubes, outward-facing.

    Neighbouring coplanar cube faces along one axis are merged into strips (fewer
    triangles; the surface stays closed, with T-junctions).
    """
    quads = []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        for step in (-1, 1):
            neighbour = np.zeros_like(occ)
            src = [slice(None)] * 3
            dst = [slice(None)] * 3
            src[a], dst[a] = (slice(1, None), slice(None, -1)) if step > 0 else (slice(None, -1), slice(1, None))
            neighbour[tuple(dst)] = occ[tuple(src)]
            face = np.moveaxis(occ & ~neighbour, (a, b, c), (0, 1, 2))
            edges = np.diff(np.pad(face, ((0, 0), (0, 0), (1, 1))).view(np.int8), axis=2)
            ia, ib, c0 = np.nonzero(edges == 1)
            c1 = np.nonzero(edges == -1)[2]
            plane = ia + (step > 0)
            # Counter-clockwise seen from outside: (b, c) → (b+1, c) → (b+1, c1) → (b, c1) faces +a.
            ring = [(ib, c0), (ib + 1, c0), (ib + 1, c1), (ib, c1)]
            if step < 0:
                ring = ring[::-1]
            corners = np.zeros((len(ia), 4, 3), dtype=np.float64)
            for k, (ub, uc) in enumerate(ring):
                corners[:, k, a], corners[:, k, b], corners[:, k, c] = plane, ub, uc
            quads.append(corners)
    corners = np.concatenate(quads) if quads else np.zeros((0, 4, 3))
    vertices = origin + corners.reshape(-1, 3) * voxel
    base = 4 * np.arange(len(corners))[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    return vertices, faces.astype(np.int64)


def cube_part_meshes(occupancies: Mapping[str, np.ndarray], origin: np.ndarray, voxel: float,
                     dims: tuple) -> dict[str, "trimesh.Trimesh"]:
    """{part: surface of its voxel cubes} for the parts that occupy a voxel (``lattice``'s grid).

    The first part's mesh also carries the pins: two degenerate triangles at
    the grid's corners, so that the handed-over bounding box equals the grid
    (they cover no voxel-centre sample).
    """
    import trimesh

    parts: dict[str, "trimesh.Trimesh"] = {}
    for part, occ in occupancies.items():
        if not occ.any():
            continue
        vertices, tris = box_mesh(occ, origin, voxel)
        if not parts:
            pins = np.array([origin] * 3 + [origin + np.asarray(dims) * voxel] * 3)
            tris = np.concatenate([tris, len(vertices) + np.arange(6).reshape(2, 3)])
            vertices = np.concatenate([vertices, pins])
        parts[part] = trimesh.Trimesh(vertices=vertices, faces=tris, process=False)
    return parts


def building_parts(name: str, path: Path | None = None, resolution: int = RESOLUTION,
                   buildings: Mapping[str, Building] = BUILDINGS,
                   roof_materials: frozenset[str] | set[str] = ROOF_MATERIALS) -> dict[str, "trimesh.Trimesh"]:
    """{"body": mesh, "roof": mesh} of one building, as closed voxel-cube surfaces (a part with none is left out).

    The model is open everywhere (shells without undersides, posts without
    caps), and filling all of a part's open components together lets rays
    escape through one and pair up with another (slabs, lost roof corners).
    So each component is filled on its own (``labelled_fill``) on exactly the
    grid ``make_exemplar`` will use at ``resolution`` (``lattice``), roof
    winning where roof and body overlap, and each part is handed over as the
    surface of its voxel cubes: the voxelizer's samples are those cubes'
    centres, so it gets back this occupancy unchanged. Two degenerate
    triangles at the grid's corners keep the handed-over bounding box equal to
    the grid (they cover no sample; ``cube_part_meshes``).
    """
    obj = read_obj(path or find_obj())
    building = buildings[name]
    faces = split_buildings(obj, {name: building})[name]
    roof = roof_mask(obj, faces, building.roof, roof_materials)
    corners = obj.vertices[obj.faces[faces]].reshape(-1, 3)
    origin, voxel, dims = lattice(corners.min(axis=0), corners.max(axis=0), resolution)
    body_occ, roof_occ = labelled_fill(obj, faces, roof, origin, voxel, dims)
    parts = cube_part_meshes({"body": body_occ, "roof": roof_occ}, origin, voxel, dims)
    if not parts:
        raise ExemplarError(f"building '{name}' fills no voxel at {resolution}³", field=name,
                            hint="its faces are thinner than a voxel; raise the resolution")
    return parts


def monastery_specs() -> list[ExemplarSpec]:
    """One building spec per ``BUILDINGS`` entry; ExemplarError when pybullet_data is not installed."""
    path = find_obj()
    return [ExemplarSpec(name, "building", partial(building_parts, name, path, RESOLUTION),
                         key=f"{b.families}|{b.anchor}|{b.roof}|{sorted(ROOF_MATERIALS)}|{GAP}|{TIER_MIN_UP}",
                         source=SOURCE, licence=LICENCE, attribution=ATTRIBUTION, input_files=(path,))
            for name, b in BUILDINGS.items()]
