"""Real chairs and tables for the ``sweethome`` style set, read from the Debian package ``sweethome3d-furniture``.

Role: finds the chosen models in the installed package's zip catalogues
(``/usr/share/sweethome3d/furniture/<catalogue>.sh3f``; nothing is downloaded
or copied into the repository), labels each model's faces with the parts of
vocabulary ``FURNITURE`` (``back, seat, leg, armrest, stretcher``; a table's
top is ``seat``) and voxelizes them. ``sweethome_specs`` gives one
``ExemplarSpec`` per ``MODELS`` entry; its catalogue file is the spec's input
file, so the set's cache key changes when the ``.sh3f`` bytes do.

A catalogue is a zip with ``PluginFurnitureCatalog.properties`` (Java
properties: ``name#N``, ``category#N``, ``creator#N``, ``model#N`` = the OBJ's
path in the zip, ``width#N``/``depth#N``/``height#N`` in cm) and the OBJ/MTL
files. The OBJs are +Y up, front +Z (as this project's exemplars), in
arbitrary units; each model is scaled per axis to its catalogue size
(width = X, height = Y, depth = Z), as Sweet Home 3D shows it. Models with a
``modelRotation`` are not supported (none is chosen).

Label map (``MODELS``, written by hand after looking at every group of every
chosen model, as the paper labelled its exemplars by hand): the OBJ's groups
(``g``/``o`` names; faces before any are group ``""``) are material/object
groups, not semantic parts, and one group often holds several parts (the
legs and the seat frame of one chair are one object). So a model's label map
is an ordered tuple of ``Rule(group, part, where)``, applied to each
*component* (vertex-connected faces, positions merged) of each group:

- ``group``: a group name, ``"*"`` (any group) or ``"mtl:NAME"`` (faces of
  material ``NAME``);
- ``where``: optional conditions, all of which must hold, on the component's
  bounding box in the model's normalised frame (0..1 on each axis of the
  model's bounding box; z = 1 is the front): ``x``, ``y``, ``z`` = the box's
  centre, ``w``, ``h``, ``d`` = its extent along X, Y, Z; e.g.
  ``"y>0.8 w>0.5"`` = a wide component at the top (a tabletop slab);
- ``part``: a ``FURNITURE`` part (or ``tabletop``), or ``""`` = leave out
  (cushion ties, floor shadows, glass).

The first matching rule labels the component. A rule naming a group the
model does not have, and a component no rule matches, are errors (the map was
written for another version of the package).

Voxels (``model_parts``): only about one model in nine is watertight (open
cushions, single-sided panels, legs without caps), so each part is filled
with ``stylesets.readers.monastery.labelled_fill`` (each connected component
filled on its own by the project voxelizer, plus the voxels its faces pass
through) on exactly the grid ``make_exemplar`` uses, and handed over as
voxel-cube surfaces (``monastery.cube_part_meshes``). Where parts overlap, the
earlier part of ``PRIORITY`` wins.

Choice: chairs and tables with ≥ 3k triangles first (slatted, turned, tubular,
carved), CC0 (catalogue ``BlendSwap-CC-0``) first, CC-BY catalogues where
needed; models whose parts are fused into one surface (one-piece plastic
chairs, upholstered armchairs whose seat and back are one shell), pool and
football tables, tables under a tablecloth and desks with drawers are left
out. Tried and dropped for a low detail ratio at 256³ (< 1.3): Scopia's
kitchen stool (1.28: a thick solid seat) and round table ``table3`` (1.16: its
drum-shaped cloth fills solid). Licences:
``BlendSwap-CC-0`` = CC0-1.0; ``BlendSwap-CC-BY`` and ``Scopia`` = CC-BY-3.0;
``KatorLegaz`` = CC-BY-3.0-US. CC-BY models need attribution: every
exemplar records its title, author and catalogue, and NOTICE lists them.
"""

from __future__ import annotations

import re
import zipfile
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from stylesets.format import FURNITURE, RESOLUTION, ExemplarError, ExemplarSpec
from stylesets.readers.file_cache import cached_per_file
from stylesets.readers.monastery import cube_part_meshes, face_components, labelled_fill, lattice
from stylesets.readers.obj_text import GroupedObj, parse_obj

if TYPE_CHECKING:
    import trimesh

PACKAGE = "sweethome3d-furniture"
PACKAGE_VERSION = "1.8-1"
#: Where the Debian package installs its catalogues.
FURNITURE_DIR = Path("/usr/share/sweethome3d/furniture")
PROPERTIES = "PluginFurnitureCatalog.properties"
INSTALL_HINT = f"run: bash scripts/install.sh exemplars (or: sudo apt-get install -y {PACKAGE})"
STALE_HINT = f"the label map was written for {PACKAGE} {PACKAGE_VERSION}"
REINSTALL_HINT = f"reinstall it: sudo apt-get install --reinstall {PACKAGE}"
#: Catalogue → licence of its models.
LICENCES = {"BlendSwap-CC-0": "CC0-1.0", "BlendSwap-CC-BY": "CC-BY-3.0", "Scopia": "CC-BY-3.0",
            "KatorLegaz": "CC-BY-3.0-US", "Reallusion": "CC-BY-3.0-US"}
#: Where parts overlap, the first of these wins.
PRIORITY = ("seat", "back", "armrest", "stretcher", "leg")


@dataclass(frozen=True)
class Rule:
    """Labels the components of ``group`` that satisfy ``where`` with ``part`` (module docstring)."""

    group: str
    part: str
    where: str = ""


@dataclass(frozen=True)
class Model:
    """One chosen model: its catalogue (file stem), OBJ path in the zip, category and label map."""

    catalogue: str
    model: str
    category: str
    rules: tuple[Rule, ...]
    note: str = ""


@dataclass(frozen=True)
class CatalogueEntry:
    """A catalogue's record of one model (sizes in cm)."""

    name: str
    category: str
    creator: str
    model: str
    width: float
    depth: float
    height: float
    rotated: bool


L, S, B, A, T = "leg", "seat", "back", "armrest", "stretcher"
CC0, CCBY, KL, SC = "BlendSwap-CC-0", "BlendSwap-CC-BY", "KatorLegaz", "Scopia"
#: The table heuristic: the wide slabs at the top are the tabletop (``seat``), everything else is ``leg``.
TOP = Rule("*", S, "y>0.85 w>0.5 d>0.5")
TABLE = (TOP, Rule("*", L))

#: name → model and its hand-written label map (module docstring).
MODELS: dict[str, Model] = {
    # ---- chairs
    "oak_chair": Model(CC0, "blendswap-cc-0/oakChair/oakChair.obj", "chair", (
        Rule("Cube.001_Cube.003", B),                      # five back spindles
        Rule("Circle.011_Circle.016", L),                  # four turned legs
        Rule("Plane.002", S, "y<0.5 h<0.1"),               # seat board
        Rule("Plane.002", B),                              # top rail and back posts
        Rule("*", T, "y<0.3")), "turned legs, spindle back, four turned stretchers"),
    "antique_chair": Model(CC0, "blendswap-cc-0/antiqueChair/antiqueChair.obj", "chair", (
        Rule("Zitting_Plane.082", S), Rule("Achterpoten_Cube.355", L), Rule("Voorpoten_Cylinder.066", L),
        Rule("Leuning_Torus.004", B)), "carved cherry chair, cane seat and oval back"),
    "thonet_chair": Model(CC0, "blendswap-cc-0/thonet/thonet.obj", "chair", (
        Rule("Circle_Circle.003", S), Rule("BezierCircle.001", T),   # ring under the seat
        Rule("BezierCurve.001", B, "y>0.6"), Rule("BezierCurve.001", L)), "bentwood bistro chair"),
    "design_chair": Model(CC0, "blendswap-cc-0/designChair/designChair.obj", "chair", (
        Rule("zidle.design.polstare_Cube.001", S), Rule("zidle.desig.noh_Circle.003", S, "h<0.05"),
        Rule("zidle.desig.noh_Circle.003", L), Rule("zidle.desig.sedak_Circle.002", B)),
        "shell chair with cushion on a wire base"),
    "shell_chair": Model(CC0, "blendswap-cc-0/sillaBlanca/sillaBlanca.obj", "chair", (
        Rule("Plane.001", L), Rule("Plane", B), Rule("Cube", S)), "shell chair with pedestal base"),
    "cushion_chair": Model(CC0, "blendswap-cc-0/chairWithCushion/chairWithCushion.obj", "chair", (
        Rule("Chair3_Untitled.007", ""),                   # glides and screws
        Rule("Cushion_Untitled.028", S),
        Rule("*", L, "h>0.4"),                             # legs and back posts
        Rule("*", T, "y<0.35"), Rule("*", S, "y<0.5"),     # side stretchers; seat board and rails
        Rule("*", B)), "slatted wooden chair with cushion"),
    "bar_chair_orange": Model(CC0, "blendswap-cc-0/silla2/silla2.obj", "chair", (
        Rule("silla_Mesh.003", B), Rule("silla.001_Mesh.004", S), Rule("BezierCurve", T),
        Rule("*", L)), "tubular bar chair with footrest ring"),
    "ella_chair": Model(CCBY, "blendswap-cc-by/ella_chair_f/ella_chair_f.obj", "chair", (
        Rule("ChairBack.001_Cube.014", B), Rule("SeatBackSupports.003_Cube.018", B),
        Rule("BackLegs.001_Cube.003", L), Rule("FrontLegs.001_Cube.006", L),
        Rule("SideSupports.001_Cube.009", T), Rule("CenterSupport.001_Cube.011", T),
        Rule("BackSupport.001_Cube.012", T), Rule("*", S)), "spindle-back chair with stretchers"),
    "child_chair": Model(CCBY, "blendswap-cc-by/childChair/childChair.obj", "chair", (
        Rule("Child_chair_plane_Plane.026", S), Rule("Child_chair_lag_Cone.004", L), Rule("*", B)),
        "child's chair, splayed legs, spindle back"),
    "kitchen_chair": Model(CCBY, "blendswap-cc-by/kitchenChair/kitchenChair.obj", "chair", (
        Rule("Cube.001_Cube.007", S), Rule("Plane_Plane.003", L, "h>0.4"),
        Rule("Plane_Plane.003", B, "y>0.6"), Rule("Plane_Plane.003", T)), "kitchen chair"),
    "slat_chair": Model(CCBY, "blendswap-cc-by/chair4/chair4.obj", "chair", (
        Rule("chair_Cube.005", S), Rule("chair.001_Cube.001", T, "y<0.4"), Rule("chair.001_Cube.001", B),
        Rule("feet_Cube.002", L), Rule("chair.002_Cube.003", B)), "chair with slatted back"),
    "cafe_chair": Model(KL, "katorlegaz/cafe-chair/cafe-chair.obj", "chair", (
        Rule("Cafe_chair_Cafe_chair_Green_chair", B, "y>0.6"), Rule("Cafe_chair_Cafe_chair_Green_chair", S),
        Rule("Cafe_chair_Cafe_chair_Aluminum", L, "h>0.3"),
        Rule("Cafe_chair_Cafe_chair_Aluminum", S, "y>0.4 y<0.55"),
        Rule("Cafe_chair_Cafe_chair_Aluminum", B, "y>0.55"), Rule("*", T)), "aluminium cafe chair, slats"),
    "swivel_bar_stool": Model(KL, "katorlegaz/bar-stool/bar-stool.obj", "chair", (
        Rule("swivel_chair_posts_swivel_chair_posts_Chair_vinyl", B, "y>0.75"),
        Rule("swivel_chair_posts_swivel_chair_posts_Chair_vinyl", S),
        Rule("swivel_chair_posts_swivel_chair_posts_Aluminum", S, "y>0.5"), Rule("*", L)),
        "swivel bar stool with low back"),
    "wooden_bar_chair": Model(SC, "scopia/bar_chair/bar_chair.obj", "chair", (
        Rule("stool_support_Cube.005", B), Rule("stool_link_Cube.002", T),
        Rule("wood_stool_Cube.001", S, "y>0.6 h<0.1 w>0.5"), Rule("*", L)), "wooden bar chair, low back"),
    "cushion_chair_ties": Model(CCBY, "blendswap-cc-by/chairWithCushion/chairWithCushion.obj", "chair", (
        Rule("Cushion-tie1_Plane.056", ""), Rule("Cushion-tie2_Plane.057", ""),
        Rule("Chair-Back-Top_Plane.031", B), Rule("Cube.052_Cube.031", B),
        Rule("Chair-Back-Uprights-legs_Cube.085", L), Rule("Chair-leg-front-L_Cube.083", L),
        Rule("Chair-leg-front-R_Cube.083", L), Rule("*", T, "y<0.35"), Rule("*", S)),
        "carved-back chair with cushion"),
    # ---- tables
    "oak_table": Model(CC0, "blendswap-cc-0/oakTable/oakTable.obj", "table", (Rule("*", S, "y>0.85"), Rule("*", L)), "round pedestal table, claw feet"),
    "trestle_table": Model(CC0, "blendswap-cc-0/table/table.obj", "table", (
        Rule("*", S, "y>0.9 h<0.1"), Rule("*", T, "y>0.4 y<0.8 h<0.5"), Rule("*", L)),
        "long trestle table with braces"),
    "metal_desk": Model(CC0, "blendswap-cc-0/lbDesk/lbDesk.obj", "table", (
        Rule("*", S, "y>0.97"), Rule("BackDesk_Plane.004", T), Rule("Frame1_Plane.005", T),
        Rule("Frame2_Plane.005", T), Rule("*", L)), "desk on tubular trestle legs"),
    "cafe_table": Model(KL, "katorlegaz/cafe-table/cafe-table.obj", "table", (
        Rule("*", S, "y>0.85"), Rule("*", T, "h<0.3 y>0.1"), Rule("*", L)), "aluminium cafe table"),
    "folding_table": Model(KL, "katorlegaz/folding-table/folding-table.obj", "table", (
        TOP, Rule("table_legs_table_legs_table_legs", T, "h<0.3"), Rule("*", L)), "folding table"),
    "glass_table": Model(SC, "scopia/metal_glass_table/metal_glass_table.obj", "table", (
        Rule("toptable_Cube.001", S), Rule("*", L)), "glass table on a metal frame"),
    "iron_coffee_table": Model(SC, "scopia/table_wood_and_iron/table_wood_and_iron.obj", "table", (
        Rule("glass_Cube", S), Rule("woodenframe_Plane.001", S), Rule("*", T, "h<0.3 y<0.85"), Rule("*", L)),
        "coffee table, wood and iron"),
    "alder_table": Model(SC, "scopia/wooden_office_alder_table/wooden_office_alder_table.obj", "table", TABLE,
                         "office table on turned legs"),
    "pedestal_table": Model(CCBY, "blendswap-cc-by/cafe_set_mota_table/cafe_set_mota_table.obj", "table", TABLE,
                            "round cafe table on a pedestal"),
    "tonon_table": Model(CCBY, "blendswap-cc-by/cafe_set_tonon_table/cafe_set_tonon_table.obj", "table", TABLE,
                         "cafe table, curved base"),
}


# --------------------------------------------------------------------------- catalogues


def catalogue_path(catalogue: str, folder: Path | None = None) -> Path:
    """``<folder>/<catalogue>.sh3f``; ExemplarError with the install hint when the package is missing."""
    folder = Path(folder or FURNITURE_DIR)
    path = folder / f"{catalogue}.sh3f"
    if path.is_file():
        return path
    if not folder.is_dir():
        raise ExemplarError(f"the 'sweethome' set needs the Debian package {PACKAGE}, which is not installed "
                            f"({folder} does not exist)", field="set", hint=INSTALL_HINT)
    raise ExemplarError(f"{PACKAGE} has no catalogue {path.name}", file=folder, field="set",
                        hint=REINSTALL_HINT)


def _unescape(value: str) -> str:
    return re.sub(r"\\(u[0-9a-fA-F]{4}|.)",
                  lambda m: chr(int(m.group(1)[1:], 16)) if len(m.group(1)) == 5 else m.group(1), value)


def parse_properties(text: str) -> dict[int, dict[str, str]]:
    """Item number → {key: value} of a ``PluginFurnitureCatalog.properties`` text (``key#N=value`` lines)."""
    items: dict[int, dict[str, str]] = {}
    for line in text.splitlines():
        m = re.match(r"\s*([A-Za-z]+)#(\d+)\s*[=:]\s?(.*)$", line)
        if m:
            items.setdefault(int(m.group(2)), {})[m.group(1)] = _unescape(m.group(3).strip())
    return items


@cached_per_file(maxsize=8)
def read_catalogue(path: Path) -> dict[str, CatalogueEntry]:
    """OBJ path in the zip → its catalogue entry. Cached per path, size and modification time."""
    try:
        with zipfile.ZipFile(path) as z:
            text = z.read(PROPERTIES).decode("iso-8859-1")
    except (OSError, zipfile.BadZipFile, KeyError) as exc:
        raise ExemplarError(f"cannot read the catalogue {path}: {exc}", file=path,
                            hint=REINSTALL_HINT) from None
    out: dict[str, CatalogueEntry] = {}
    for item in parse_properties(text).values():
        if "model" not in item:
            continue
        model = item["model"].lstrip("/")
        try:
            size_cm = [float(item.get(k, "nan")) for k in ("width", "depth", "height")]
        except ValueError:
            size_cm = [float("nan")] * 3
        out[model] = CatalogueEntry(item.get("name", ""), item.get("category", ""), item.get("creator", ""),
                                    model, *size_cm, rotated="modelRotation" in item)
    return out


def catalogue_entry(path: Path, model: str) -> CatalogueEntry:
    """The entry of ``model`` (OBJ path in the zip); ExemplarError when the catalogue has none."""
    entry = read_catalogue(path).get(model)
    if entry is None:
        raise ExemplarError(f"catalogue {Path(path).name} has no model {model}", file=path, hint=STALE_HINT)
    return entry


# --------------------------------------------------------------------------- OBJ


@cached_per_file(maxsize=4)
def read_model(path: Path, model: str) -> GroupedObj:
    """A model of a catalogue, scaled per axis to its catalogue size (metres, min corner at the origin)."""
    try:
        with zipfile.ZipFile(path) as z:
            text = z.read(model).decode("utf-8", errors="replace")
    except KeyError:
        raise ExemplarError(f"catalogue {path.name} has no file {model}", file=path, hint=STALE_HINT) from None
    except (OSError, zipfile.BadZipFile) as exc:
        raise ExemplarError(f"cannot read the catalogue {path}: {exc}", file=path,
                            hint=REINSTALL_HINT) from None
    entry = catalogue_entry(path, model)
    obj = parse_obj(text.splitlines(), f"{path.name}:{model}", STALE_HINT, file=path)
    if entry.rotated:
        raise ExemplarError(f"{model} has a modelRotation, which the 'sweethome' set does not support",
                            file=path, hint="choose another model")
    used = obj.vertices[np.unique(obj.faces)]
    lo, hi = used.min(axis=0), used.max(axis=0)
    target = np.array([entry.width, entry.height, entry.depth]) / 100.0  # cm → m
    extent = hi - lo
    if not np.all(np.isfinite(target)) or np.any(target <= 0) or np.any(extent <= 0):
        raise ExemplarError(f"{model}: flat model or no catalogue size", file=path, hint="choose another model")
    scaled = (obj.vertices - lo) * (target / extent)
    return GroupedObj(scaled, obj.faces, obj.group, obj.groups, obj.material, obj.materials)


# --------------------------------------------------------------------------- labels


_CONDITION = re.compile(r"^([xyzwhd])([<>])(-?[0-9.]+)$")


def _conditions(where: str) -> list[tuple[int, bool, str, float]]:
    out = []
    for token in where.split():
        m = _CONDITION.match(token)
        if m is None:
            raise ValueError(f"bad label-map condition {token!r} (use e.g. 'y>0.8 w>0.5')")
        key = m.group(1)
        out.append(("xyzwhd".index(key) % 3, key in "whd", m.group(2), float(m.group(3))))
    return out


def face_parts(obj: GroupedObj, rules: tuple[Rule, ...], name: str = "") -> np.ndarray:
    """(F,) object array: the part of every face ("" = left out), by the label map (module docstring)."""

    accepted = set(FURNITURE.accepted())
    for rule in rules:
        if rule.part and rule.part not in accepted:
            raise ExemplarError(f"model '{name}': label map names unknown part '{rule.part}'", field=name,
                                hint="parts: " + ", ".join(sorted(accepted)))
        if rule.group.startswith("mtl:"):
            if rule.group[4:] not in obj.materials:
                raise ExemplarError(f"model '{name}': label map names material '{rule.group[4:]}', "
                                    "which the model does not have", field=name, hint=STALE_HINT)
        elif rule.group != "*" and rule.group not in obj.groups:
            raise ExemplarError(f"model '{name}': label map names group '{rule.group}', which the model "
                                "does not have (groups: " + ", ".join(repr(g) for g in obj.groups if g) + ")",
                                field=name, hint=STALE_HINT)
    parsed = [_conditions(r.where) for r in rules]
    used = obj.vertices[np.unique(obj.faces)]
    lo, extent = used.min(axis=0), np.maximum(np.ptp(used, axis=0), 1e-12)
    out = np.full(len(obj.faces), None, dtype=object)
    for g, group in enumerate(obj.groups):
        members = np.flatnonzero(obj.group == g)
        if len(members) == 0:
            continue
        comp = face_components(obj, members)
        for c in np.unique(comp):
            faces = members[comp == c]
            pts = (obj.vertices[obj.faces[faces].reshape(-1)] - lo) / extent
            box = np.r_[(pts.min(axis=0) + pts.max(axis=0)) / 2, np.ptp(pts, axis=0)]
            materials = {obj.materials[m] for m in np.unique(obj.material[faces]) if m >= 0}
            for rule, conditions in zip(rules, parsed):
                if rule.group.startswith("mtl:"):
                    if rule.group[4:] not in materials:
                        continue
                elif rule.group not in ("*", group):
                    continue
                if all((box[3 * size + axis] > value) == (op == ">") for axis, size, op, value in conditions):
                    out[faces] = rule.part
                    break
            else:
                raise ExemplarError(f"model '{name}': no label-map rule matches a component of group "
                                    f"'{group}' (centre {np.round(box[:3], 2).tolist()}, "
                                    f"size {np.round(box[3:], 2).tolist()})", field=name, hint=STALE_HINT)
    return out


# --------------------------------------------------------------------------- voxels


def model_parts(name: str, folder: Path | None = None, resolution: int = RESOLUTION,
                models: Mapping[str, Model] | None = None) -> dict[str, "trimesh.Trimesh"]:
    """{part: closed voxel-cube mesh} of one model on ``make_exemplar``'s grid at ``resolution``."""

    model = (MODELS if models is None else models)[name]
    obj = read_model(catalogue_path(model.catalogue, folder), model.model)
    part_of = face_parts(obj, model.rules, name)
    canonical = np.array([FURNITURE.parts[FURNITURE.index(p, model.category)] if p else "" for p in part_of],
                         dtype=object)
    kept = np.flatnonzero(canonical != "")
    if len(kept) == 0:
        raise ExemplarError(f"model '{name}': the label map leaves every face out", field=name, hint=STALE_HINT)
    corners = obj.vertices[obj.faces[kept]].reshape(-1, 3)
    origin, voxel, dims = lattice(corners.min(axis=0), corners.max(axis=0), resolution)
    taken = np.zeros(dims, dtype=bool)
    occupancies: dict[str, np.ndarray] = {}
    for part in PRIORITY:
        faces = kept[canonical[kept] == part]
        if len(faces) == 0:
            continue
        occ, _ = labelled_fill(obj, faces, np.zeros(len(faces), bool), origin, voxel, dims)
        occupancies[part] = occ & ~taken
        taken |= occ
    parts = cube_part_meshes(occupancies, origin, voxel, dims)
    if not parts:
        raise ExemplarError(f"model '{name}' fills no voxel at {resolution}³", field=name,
                            hint="its faces are thinner than a voxel; raise the resolution")
    return parts


def model_record(model: Model, folder: Path | None = None) -> tuple[str, str, str]:
    """(source, licence, attribution) of a model, from its catalogue entry."""
    path = catalogue_path(model.catalogue, folder)
    entry = catalogue_entry(path, model.model)
    licence = LICENCES.get(model.catalogue, "see the catalogue's LICENSE.TXT")
    source = f"{PACKAGE}: {model.catalogue}/{entry.name} by {entry.creator}"
    attribution = (f"\"{entry.name}\" ({model.model}) by {entry.creator}, Sweet Home 3D catalogue "
                   f"{model.catalogue} (Debian {PACKAGE}), {licence}")
    if licence.startswith("CC-BY"):
        licence = f"{licence}, by {entry.creator}"
    return source, licence, attribution


def sweethome_specs(folder: Path | None = None, models: Mapping[str, Model] | None = None) -> list[ExemplarSpec]:
    """One spec per ``MODELS`` entry; ExemplarError when the package is not installed."""
    models = MODELS if models is None else models
    specs = []
    for name, model in models.items():
        path = catalogue_path(model.catalogue, folder)
        source, licence, attribution = model_record(model, folder)
        specs.append(ExemplarSpec(name, model.category, partial(model_parts, name, folder, RESOLUTION, models),
                                  key=f"{model.catalogue}|{model.model}|{model.rules}|{PRIORITY}",
                                  source=source, licence=licence, attribution=attribution, input_files=(path,)))
    return specs
