"""Detailize jobs of the painter: a quick preview first, then the exact GLB that ``decollage build`` writes.

Role: run one painted asset through the detailizer and the build, one job at a
time in a worker thread, newest first. A job has two results:

1. **preview**: the detailizer's fine grid (``core/detailizer.py``), meshed at
   half its resolution (a quarter or less for grids over 128³: ``preview_glb``)
   with the same iso level and style colours, without decimation, as a GLB; for
   the fast detailizers this is on screen about a second after the edit;
2. **exact**: ``pipeline/build.py``'s ``build_asset`` on a one-asset recipe that
   holds the edited asset (same source, rules, detailizer, export settings), so
   its GLB is byte for byte what ``decollage build`` writes for the saved
   recipe; the page shows it when it is ready, with its sha256 and the
   manifest figures.

A job submitted while another waits replaces the waiting one; a running job
skips its exact stage when a newer job is waiting. Results live in a scratch
folder (``<scratch>/<job id>/``) that keeps the last ``KEEP_JOBS`` jobs.
"""

from __future__ import annotations

import shutil
import threading
import time
import traceback
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

import numpy as np

from core.detailizer import get_detailizer
from core.errors import DecollageError
from core.grid import ISO_LEVEL, FineGrid, LabeledGrid
from core.recipe_loader import LoadedRecipe
from pipeline.build import Progress, build_asset, check_recipe
from pipeline.mesh import crop_padded, marching_cubes
from pipeline.palette import palette_rgba
from pipeline.report import AssetStatus

#: Finished jobs whose files stay in the scratch folder.
KEEP_JOBS = 6

#: Largest preview grid (voxels): 128³, the fine grid of a 16³ asset at half resolution.
PREVIEW_VOXELS = 128**3

#: Held while sources, voxelization, detailizers and builds run: the detailizer registry's cache and the
#: CAD kernel are not thread-safe, so the job worker and the page's requests take turns.
PIPELINE_LOCK = threading.RLock()


class JobState(StrEnum):
    """Where a detailize job stands (the page polls it)."""

    QUEUED = "queued"
    DETAILIZING = "detailizing"
    PREVIEW = "preview"  # the preview GLB is ready; the exact build runs
    DONE = "done"  # the exact GLB is ready
    FAILED = "failed"
    SUPERSEDED = "superseded"  # a newer job replaced it before it finished


@dataclass
class Job:
    """One painted asset to detailize: the edited one-asset recipe and the grid it gives."""

    id: int
    recipe: LoadedRecipe  # one asset: the edited one
    grid: LabeledGrid
    state: JobState = JobState.QUEUED
    submitted: float = field(default_factory=time.perf_counter)
    result: dict = field(default_factory=dict)

    def snapshot(self) -> dict:
        return {"id": self.id, "state": self.state.value, **self.result}


def preview_factor(shape: tuple[int, int, int]) -> int:
    """How much coarser than the fine grid the preview is: 2, or more for grids over ``PREVIEW_VOXELS``."""
    factor = 2
    while int(np.prod([-(-s // factor) for s in shape])) > PREVIEW_VOXELS and factor < 16:
        factor *= 2
    return factor


def preview_glb(fine: FineGrid) -> tuple[bytes, int, int]:
    """(GLB bytes, triangles, factor) of the preview mesh: the fine field at 1/factor resolution.

    The occupancy is averaged over factor³ blocks, meshed by marching cubes at
    ``ISO_LEVEL`` (``pipeline/mesh.py``'s crop and mesher), not decimated, and
    each vertex takes the palette colour (``pipeline/palette.py``) of the style
    in its block. Vertices in metres, same frame as the fine grid (no pivot).
    """
    import trimesh

    f = preview_factor(fine.shape)
    x, y, z = (s // f for s in fine.shape)
    occ = fine.occupancy[: f * x, : f * y, : f * z].reshape(x, f, y, f, z, f).mean(axis=(1, 3, 5), dtype=np.float32)
    crop, start = crop_padded(occ, ISO_LEVEL)
    verts, faces = marching_cubes(crop, ISO_LEVEL)
    verts += start - 1
    style = fine.style[::f, ::f, ::f][:x, :y, :z]
    idx = np.clip(np.floor(verts + 0.5).astype(np.int64), 0, np.asarray(style.shape) - 1)
    styles = style[idx[:, 0], idx[:, 1], idx[:, 2]].astype(np.int64)
    neutral = len(fine.style_names)
    colors = palette_rgba(fine.style_names)[np.where((styles >= 0) & (styles < neutral), styles, neutral)]
    positions = np.asarray(fine.origin_m) + (verts + 0.5) * (fine.voxel_size_m * f)
    mesh = trimesh.Trimesh(positions, faces, vertex_colors=colors, process=False)
    return mesh.export(file_type="glb", include_normals=False), len(faces), f


class JobRunner:
    """One worker thread running the newest job; ``submit`` replaces a waiting job."""

    def __init__(self, scratch: Path) -> None:
        self.scratch = scratch
        self._lock = threading.Condition()
        self._jobs: dict[int, Job] = {}
        self._waiting: Job | None = None
        self._next_id = 1
        self._stop = False
        self._thread = threading.Thread(target=self._loop, name="paint-jobs", daemon=True)
        self._thread.start()

    def submit(self, recipe: LoadedRecipe, grid: LabeledGrid) -> Job:
        with self._lock:
            job = Job(self._next_id, recipe, grid)
            self._next_id += 1
            if self._waiting is not None:
                self._waiting.state = JobState.SUPERSEDED
            self._waiting = job
            self._jobs[job.id] = job
            self._lock.notify_all()
            return job

    def get(self, job_id: int, unless: str | None = None, wait_s: float = 0.0) -> dict | None:
        """The job's snapshot; with ``unless``, first wait up to ``wait_s`` while its state is still ``unless``."""
        deadline = time.monotonic() + wait_s
        with self._lock:
            job = self._jobs.get(job_id)
            while job is not None and job.state.value == unless and not self._stop:
                left = deadline - time.monotonic()
                if left <= 0 or not self._lock.wait(left):
                    break
            return None if job is None else job.snapshot()

    def close(self) -> None:
        with self._lock:
            self._stop = True
            self._lock.notify_all()
        self._thread.join(timeout=2.0)

    def _newer_waiting(self) -> bool:
        with self._lock:
            return self._waiting is not None or self._stop

    def _set(self, job: Job, state: JobState, **result) -> None:
        with self._lock:
            job.state = state
            job.result.update(result)
            self._lock.notify_all()

    def _loop(self) -> None:
        while True:
            with self._lock:
                while self._waiting is None and not self._stop:
                    self._lock.wait()
                if self._stop:
                    return
                job, self._waiting = self._waiting, None
            try:
                with PIPELINE_LOCK:
                    self._run(job)
            except DecollageError as exc:
                self._set(job, JobState.FAILED, error=exc.one_line())
            except Exception as exc:  # a bug must not stop the worker; the page shows it
                self._set(job, JobState.FAILED, error=f"internal error {type(exc).__name__}: {exc}",
                          traceback=traceback.format_exc())
            self._forget_old()

    def _run(self, job: Job) -> None:
        asset = job.recipe.recipe.assets[0]
        folder = self.scratch / str(job.id)
        folder.mkdir(parents=True, exist_ok=True)
        url = f"/results/{job.id}/"
        self._set(job, JobState.DETAILIZING)
        check_recipe(job.recipe)  # unknown styles or parts for this detailizer: the build's own message
        settings = asset.detailize
        _, value = settings.data_file(settings.detailizer)
        checkpoint = value and str(job.recipe.resolve(value))
        detailizer = get_detailizer(settings.detailizer, checkpoint, settings.device)
        t0 = time.perf_counter()
        fine = detailizer.detailize(job.grid, seed=settings.seed)
        t1 = time.perf_counter()
        glb, triangles, factor = preview_glb(fine)
        (folder / "preview.glb").write_bytes(glb)
        t2 = time.perf_counter()
        self._set(job, JobState.PREVIEW, preview_url=url + "preview.glb", preview_triangles=triangles, preview_factor=factor,
                  detailizer=detailizer.describe(), learned=bool(detailizer.learned),
                  preview_timings_s={"detailize": round(t1 - t0, 3), "preview_mesh": round(t2 - t1, 3),
                                     "since_submit": round(t2 - job.submitted, 3)})
        if self._newer_waiting():
            self._set(job, JobState.SUPERSEDED)
            return
        report = build_asset(job.recipe, 0, folder, Progress())
        if report.status != AssetStatus.BUILT:
            self._set(job, JobState.FAILED, error=report.error)
            return
        entry = report.entry()
        outputs = {kind: url + out["path"] for kind, out in report.outputs.items()}
        self._set(job, JobState.DONE, glb_url=outputs.get("glb"), png_url=outputs.get("preview"),
                  glb_sha256=report.outputs.get("glb", {}).get("sha256"), outputs=outputs, entry=entry,
                  build_s=round(time.perf_counter() - t2, 3), total_s=round(time.perf_counter() - job.submitted, 3))

    def _forget_old(self) -> None:
        with self._lock:
            finished = sorted(i for i, j in self._jobs.items()
                              if j.state in (JobState.DONE, JobState.FAILED, JobState.SUPERSEDED))
            for job_id in finished[:-KEEP_JOBS]:
                del self._jobs[job_id]
                shutil.rmtree(self.scratch / str(job_id), ignore_errors=True)

