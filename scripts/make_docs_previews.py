"""Side-by-side previews of the example assets: the upsample baseline next to the shipped model.

Run from the repository root (writes ``docs/previews/<asset>.png`` and prints a
markdown table with each asset's Strict/Loose-IOU against its coarse grid)::

    .venv/bin/python scripts/make_docs_previews.py [recipes/showcase.yaml] [--checkpoint FILE]

Each recipe is built twice through the real pipeline (``build_recipe``), once
with ``--detailizer upsample`` and once with ``decollage`` (the shipped model, or
``--checkpoint``), into temporary folders; the two preview PNGs of an asset are
put side by side (``TILE_PX`` each, captioned) and saved as a small PNG.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

TILE_PX = 320


def build(recipe: Path, out: Path, detailizer: str, checkpoint: str | None) -> dict[str, dict]:
    from pipeline.batch import build_recipe
    from core.recipe_loader import load_recipe

    if checkpoint:  # stands in for the shipped model (e.g. a candidate before it is committed)
        import model.infer

        model.infer.DEFAULT_CHECKPOINT = Path(checkpoint).resolve()
    loaded = load_recipe(recipe)
    reports = build_recipe(loaded, out, detailizer_override=detailizer)
    failed = [r for r in reports if r.status == "failed"]
    if failed:
        raise SystemExit(f"{failed[0].name}: {failed[0].error}")
    manifest = json.loads((out / "manifest.json").read_text())
    return {a["name"]: a for a in manifest["assets"]}


def side_by_side(left: Path, right: Path, captions: tuple[str, str]) -> "Image.Image":  # noqa: F821
    from PIL import Image, ImageDraw

    sheet = Image.new("RGB", (2 * TILE_PX, TILE_PX + 22), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (path, caption) in enumerate(zip((left, right), captions)):
        tile = Image.open(path).convert("RGB").resize((TILE_PX, TILE_PX), Image.LANCZOS)
        sheet.paste(tile, (i * TILE_PX, 0))
        draw.text((i * TILE_PX + 6, TILE_PX + 5), caption, fill=(0, 0, 0))
    return sheet


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipes", nargs="*", type=Path, default=[REPO / "recipes" / "showcase.yaml"])
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "previews")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    print("| asset | upsample strict / loose IOU | decollage strict / loose IOU | picture |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for recipe in args.recipes:
            base = build(recipe, Path(tmp) / "upsample" / recipe.stem, "upsample", None)
            learned = build(recipe, Path(tmp) / "decollage" / recipe.stem, "decollage", args.checkpoint)
            for name, entry in learned.items():
                b, s = base[name]["structure"], entry["structure"]
                png = args.out / f"{name}.png"
                side_by_side(Path(tmp) / "upsample" / recipe.stem / base[name]["outputs"]["preview"]["path"],
                             Path(tmp) / "decollage" / recipe.stem / entry["outputs"]["preview"]["path"],
                             (f"upsample (baseline)  strict IOU {b['strict_iou']:.3f}",
                              f"decollage (shipped model)  strict IOU {s['strict_iou']:.3f}")
                             ).save(png, optimize=True)
                print(f"| {name} | {b['strict_iou']:.3f} / {b['loose_iou']:.3f} | "
                      f"{s['strict_iou']:.3f} / {s['loose_iou']:.3f} | ![{name}](previews/{png.name}) |")


if __name__ == "__main__":
    main(sys.argv[1:])
