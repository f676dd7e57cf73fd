"""Side-by-side previews of the example assets, one column per detailizer (upsample | quilt | decollage).

Run from the repository root (writes ``docs/previews/<asset>.png`` and prints a
markdown table with each asset's Strict/Loose-IOU against its coarse grid)::

    .venv/bin/python scripts/make_docs_previews.py [recipes/showcase.yaml ...] [--detailizers upsample,quilt,decollage]
                                                   [--checkpoint FILE]

Each recipe is built once per detailizer through the real pipeline
(``build_recipe`` with the detailizer overridden) into temporary folders; an
asset's preview PNGs are put side by side (``TILE_PX`` each, captioned with the
detailizer, whether it is learned, and its Strict-IOU) and saved as one PNG.
``--checkpoint`` stands in for the shipped model's weights (a candidate before
it is committed).
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


def build(recipe: Path, out: Path, detailizer: str) -> dict[str, dict]:
    """Build ``recipe`` into ``out`` with ``detailizer``; manifest entries by asset name."""
    from core.recipe_loader import load_recipe
    from pipeline.batch import build_recipe

    reports = build_recipe(load_recipe(recipe), out, detailizer_override=detailizer)
    failed = [r for r in reports if r.status == "failed"]
    if failed:
        raise SystemExit(f"{failed[0].name}: {failed[0].error}")
    manifest = json.loads((out / "manifest.json").read_text())
    return {a["name"]: a for a in manifest["assets"]}


def side_by_side(pictures: list[Path], captions: list[str]) -> "Image.Image":  # noqa: F821
    """One row of ``TILE_PX`` tiles with a caption line under each."""
    from PIL import Image, ImageDraw

    sheet = Image.new("RGB", (len(pictures) * TILE_PX, TILE_PX + 22), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (path, caption) in enumerate(zip(pictures, captions)):
        tile = Image.open(path).convert("RGB").resize((TILE_PX, TILE_PX), Image.LANCZOS)
        sheet.paste(tile, (i * TILE_PX, 0))
        draw.text((i * TILE_PX + 6, TILE_PX + 5), caption, fill=(0, 0, 0))
    return sheet


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipes", nargs="*", type=Path, default=[REPO / "recipes" / "showcase.yaml"])
    ap.add_argument("--detailizers", default="upsample,quilt,decollage")
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "previews")
    args = ap.parse_args(argv)
    from core.detailizer import get_detailizer

    if args.checkpoint:
        import model.infer

        model.infer.DEFAULT_CHECKPOINT = Path(args.checkpoint).resolve()
    names = args.detailizers.split(",")
    learned = {n: bool(get_detailizer(n, None, "cpu").learned) for n in names}
    args.out.mkdir(parents=True, exist_ok=True)
    print("| asset | " + " | ".join(f"{n} strict / loose IOU" for n in names) + " | picture |")
    print("|---" * (len(names) + 2) + "|")
    with tempfile.TemporaryDirectory() as tmp:
        for recipe in args.recipes:
            built = {n: build(recipe, Path(tmp) / n / recipe.stem, n) for n in names}
            for asset in built[names[0]]:
                entries = [built[n][asset] for n in names]
                pictures = [Path(tmp) / n / recipe.stem / e["outputs"]["preview"]["path"] for n, e in zip(names, entries)]
                captions = [f"{n} ({'learned' if learned[n] else 'non-learned'})  strict IOU "
                            f"{e['structure']['strict_iou']:.3f}" for n, e in zip(names, entries)]
                png = args.out / f"{asset}.png"
                side_by_side(pictures, captions).save(png, optimize=True)
                cells = " | ".join(f"{e['structure']['strict_iou']:.3f} / {e['structure']['loose_iou']:.3f}"
                                   for e in entries)
                print(f"| {asset} | {cells} | ![{asset}]({png.name}) |")


if __name__ == "__main__":
    main(sys.argv[1:])
