"""``decollage paint``'s page: paint parts and styles onto an asset's coarse grid, detailize, save the recipe.

Role: the painter's session and routes. The recipe file named on the command
line is the only recipe it reads or writes (read again on every request, so
the page follows edits made in an editor); ``--asset`` picks the first asset
shown. Routes (``studio/http.py`` adds the safety rules):

- ``GET /api/session``: the recipe, its assets (variant? script?), the detailizers of the registry;
- ``GET /api/asset?name=A``: the asset's coarse grid (``studio/paint_grid.py``);
- ``GET /api/detailizer?name=D&asset=A``: what detailizer D accepts (styles, parts; null = any);
- ``POST /api/palette``: ``{asset, target}`` (or ``{styles}``) → the colours the GLB will use;
- ``POST /api/detailize``: ``{asset, detailizer, target}`` → a job (``studio/paint_jobs.py``);
- ``GET /api/job?id=N[&unless=STATE]``: the job's state (waiting up to 5 s while it is STATE), preview
  and exact GLB URLs, sha256, manifest entry;
- ``POST /api/save``: ``{asset, detailizer, target, recipe_sha256}`` → the recipe file rewritten
  (``studio/recipe_edit.py``) when it did not change on disk meanwhile;
- ``/results/<job>/<file>``: the jobs' GLBs and previews (a scratch folder removed on exit).

An asset that comes from a variant matrix can be painted and detailized, but
not saved (its rules are shared by every variant).
"""

from __future__ import annotations

import difflib
import json
import os
import shutil
import tempfile
import threading
from http import HTTPStatus
from pathlib import Path

from core.detailizer import get_detailizer, known_detailizers
from core.errors import StudioError, UsageError
from core.files import write_bytes_atomic
from core.recipe import Asset, DetailizeSettings
from core.recipe_loader import LoadedRecipe, load_recipe, parse_recipe
from studio.http import App, HttpError, Request, Response
from studio.pages import base_app
from studio.paint_grid import AssetGrid, grid_json, load_asset_grid, palette, parse_target, relabel, script_of
from studio.paint_jobs import PIPELINE_LOCK, JobRunner
from studio.paint_rules import RuleEdits, compile_edits
from studio.recipe_edit import RecipeDocument, check_saved, comparable, detailize_changes, digest


class PaintSession:
    """The painter's state: the recipe path, the loaded grids, the job runner and its scratch folder."""

    def __init__(self, recipe: Path, asset: str | None = None, allow_scripts: bool = False) -> None:
        self.path = Path(recipe).resolve()
        self.allow_scripts = allow_scripts
        loaded = load_recipe(self.path)
        names = [a.name for a in loaded.recipe.assets]
        if asset is not None and asset not in names:
            raise UsageError(f"--asset {asset!r} is not in the recipe (assets: {', '.join(names[:20])})")
        self.initial = asset or names[0]
        self.scratch = Path(tempfile.mkdtemp(prefix="decollage-paint-"))
        self.runner = JobRunner(self.scratch)
        self._lock = threading.Lock()
        self._grids: dict[tuple[str, str], AssetGrid] = {}
        self._recipe: tuple[LoadedRecipe, str] | None = None
        self._source_grids: dict = {}  # paint_grid.source_key → (source-part grid, warnings); last 16 kept

    def close(self) -> None:
        """Stop the worker and remove the scratch folder."""
        self.runner.close()
        shutil.rmtree(self.scratch, ignore_errors=True)

    # ------------------------------------------------------------------ reading

    def loaded(self) -> tuple[LoadedRecipe, str]:
        """The recipe as it is on disk now, and its text's sha256 (parsed again only when the text changed)."""
        try:
            sha = digest(self.path.read_bytes().decode("utf-8", errors="replace"))
        except OSError:
            sha = None  # load_recipe says what is wrong
        with self._lock:
            cached = self._recipe
        if cached is not None and cached[1] == sha:
            return cached
        loaded = load_recipe(self.path)
        sha = digest(loaded.text)
        with self._lock:
            self._recipe = (loaded, sha)
        return loaded, sha

    def grid(self, name: str) -> tuple[AssetGrid, LoadedRecipe, str]:
        """Asset ``name`` loaded up to its labeled grid (kept while the recipe text is unchanged)."""
        loaded, sha = self.loaded()
        index = next((i for i, a in enumerate(loaded.recipe.assets) if a.name == name), None)
        if index is None:
            raise HttpError(HTTPStatus.NOT_FOUND, f"no asset {name!r} in {self.path.name}")
        with self._lock:
            grid = self._grids.get((name, sha))
        if grid is None:
            with PIPELINE_LOCK:  # sources and detailizers share one lock: the CAD kernel is not thread-safe
                grid = load_asset_grid(loaded, index, self.allow_scripts, self._source_grids)
                while len(self._source_grids) > 16:
                    self._source_grids.pop(next(iter(self._source_grids)))
            with self._lock:
                self._grids = {k: v for k, v in self._grids.items() if k[1] == sha}
                self._grids[(name, sha)] = grid
        return grid, loaded, sha

    def session_json(self) -> dict:
        loaded, sha = self.loaded()
        assets = []
        for i, a in enumerate(loaded.recipe.assets):
            field, variant = loaded.where(i)
            assets.append({"name": a.name, "field": field, "variant": variant, "script": script_of(a)})
        return {"recipe": str(self.path), "recipe_sha256": sha, "assets": assets, "initial": self.initial,
                "detailizers": known_detailizers(), "allow_scripts": self.allow_scripts}

    def asset_json(self, name: str) -> dict:
        grid, loaded, sha = self.grid(name)
        _, variant = loaded.where(grid.index)
        note = None if variant is None else (
            f"{name} is the variant {variant} of {grid.field}; saving would change every variant, "
            "so the painter only detailizes it (edit the YAML, or paint a plain asset)")
        return {**grid_json(grid), "recipe_sha256": sha, "savable": variant is None, "save_note": note}

    def detailizer_json(self, name: str, asset: str | None) -> dict:
        if name not in known_detailizers():
            raise HttpError(HTTPStatus.NOT_FOUND, f"unknown detailizer {name!r}")
        checkpoint, device = None, "auto"
        if asset is not None:
            grid, loaded, _ = self.grid(asset)
            own = grid.asset.detailize
            if own.detailizer == name:
                _, value = own.data_file(name)
                checkpoint = value and str(loaded.resolve(value))
                device = own.device
        with PIPELINE_LOCK:
            det = get_detailizer(name, checkpoint, device)
        return {"name": name, "learned": bool(det.learned),
                "style_names": None if det.style_names is None else list(det.style_names),
                "part_names": None if det.part_names is None else list(det.part_names)}

    # ------------------------------------------------------------------ edits

    def edited(self, body: object) -> tuple[AssetGrid, LoadedRecipe, str, RuleEdits, Asset]:
        """The asset with the page's edits: (grid, recipe, its sha, rule edits, edited asset)."""
        if not isinstance(body, dict) or not isinstance(body.get("asset"), str):
            raise StudioError("expected an object with 'asset', 'target' and optionally 'detailizer'")
        grid, loaded, sha = self.grid(body["asset"])
        want_part, want_style = parse_target(body.get("target"), grid).names()
        rules = list(grid.asset.regions)
        edits = compile_edits(grid.source_grid, rules, want_part, want_style)
        settings = grid.asset.detailize.model_dump(mode="json")
        chosen = body.get("detailizer") or settings["detailizer"]
        if chosen not in known_detailizers():
            raise StudioError(f"unknown detailizer {chosen!r} (known: {', '.join(known_detailizers())})")
        if chosen != settings["detailizer"]:
            settings.update(detailizer=chosen, checkpoint=None)
        asset = grid.asset.model_copy(update={"regions": edits.apply(rules),
                                              "detailize": DetailizeSettings.model_validate(settings)})
        return grid, loaded, sha, edits, asset

    def one_asset_recipe(self, asset: Asset) -> LoadedRecipe:
        """A recipe holding only ``asset`` (read from the real recipe's folder, so its paths resolve the same)."""
        text = json.dumps({"version": 1, "assets": [comparable(asset)]})
        recipe = parse_recipe(text, self.path)
        if comparable(recipe.assets[0]) != comparable(asset):
            raise StudioError("the edited asset does not survive a round trip through the schema (please report it)")
        return LoadedRecipe(recipe, self.path, text)

    def palette_json(self, body: object) -> dict:
        """Colours of the styles as the GLB will have them: in the order the edited rules give (slots depend on it).

        ``body``: ``{asset, target, extra}`` (the page's labels, plus names not used yet) or ``{styles}``.
        """
        if isinstance(body, dict) and "target" in body:
            grid, _, _, _, asset = self.edited(body)
            names = list(relabel(grid, list(asset.regions)).style_names)
            extra = body.get("extra") or []
        else:
            names, extra = [], body.get("styles") if isinstance(body, dict) else None
        if not isinstance(extra, list) or not all(isinstance(s, str) and 0 < len(s) <= 100 for s in extra):
            raise StudioError("styles: expected a list of names")
        return palette(names + [s for s in dict.fromkeys(extra[:4096]) if s not in names])

    def detailize(self, body: object) -> dict:
        grid, _, _, edits, asset = self.edited(body)
        job = self.runner.submit(self.one_asset_recipe(asset), relabel(grid, list(asset.regions)))
        return {"job": job.id, "edits": edits.describe(list(grid.asset.regions), f"{grid.field}.regions")}

    def save(self, body: object) -> dict:
        grid, loaded, sha, edits, asset = self.edited(body)
        if body.get("recipe_sha256") != sha:
            raise HttpError(HTTPStatus.CONFLICT, f"{self.path.name} changed on disk since the page read it; "
                                                 "reload the page (your unsaved paint is lost)")
        _, variant = loaded.where(grid.index)
        if variant is not None:
            raise StudioError(f"{asset.name} is the variant {variant} of {grid.field}: not saved",
                              hint="its rules are shared by every variant; edit the YAML by hand")
        doc = RecipeDocument(loaded.text, self.path)
        doc.apply(grid.field, edits, detailize_changes(grid.asset, asset.detailize.model_dump(mode="json")))
        text = doc.render()
        check_saved(text, self.path, asset)
        if text == loaded.text:
            return {"changed": False, "edits": [], "recipe_sha256": sha}
        mode = self.path.stat().st_mode & 0o7777
        write_bytes_atomic(self.path, text.encode("utf-8"))
        os.chmod(self.path, mode)
        diff = "".join(difflib.unified_diff(loaded.text.splitlines(True), text.splitlines(True),
                                            self.path.name, self.path.name + " (saved)"))
        return {"changed": True, "edits": edits.describe(list(grid.asset.regions), f"{grid.field}.regions"),
                "diff": diff, "recipe_sha256": digest(text), "layout_kept": doc.lossless}


def painter_app(session: PaintSession) -> App:
    """The painter's routes (module docstring) around ``session``."""
    app = base_app("paint.html")

    def job(request: Request) -> Response:
        try:
            job_id = int(request.arg("id", ""))
        except ValueError:
            raise HttpError(HTTPStatus.BAD_REQUEST, "id: expected a job number") from None
        # ?unless=STATE waits (up to 5 s) for the job to leave that state: the page long-polls.
        snapshot = session.runner.get(job_id, request.arg("unless"), 5.0)
        if snapshot is None:
            raise HttpError(HTTPStatus.NOT_FOUND, "no such job (finished jobs are kept for a while only)")
        return Response.json(snapshot)

    def need(request: Request, key: str) -> str:
        value = request.arg(key)
        if not value:
            raise HttpError(HTTPStatus.BAD_REQUEST, f"missing ?{key}=")
        return value

    app.routes.update({
        ("GET", "/api/session"): lambda r: Response.json(session.session_json()),
        ("GET", "/api/asset"): lambda r: Response.json(session.asset_json(need(r, "name"))),
        ("GET", "/api/detailizer"): lambda r: Response.json(session.detailizer_json(need(r, "name"), r.arg("asset"))),
        ("GET", "/api/job"): job,
        ("POST", "/api/palette"): lambda r: Response.json(session.palette_json(r.body)),
        ("POST", "/api/detailize"): lambda r: Response.json(session.detailize(r.body)),
        ("POST", "/api/save"): lambda r: Response.json(session.save(r.body)),
    })
    app.trees["/results/"] = session.scratch
    app.close = session.close
    return app
