"""The Cls-score (method.md §5): can a small 2-D CNN tell real exemplar renders from generated ones?

Renders come from ``evaluation.render_eval`` (depth-shaded, 256², seeded random
views: azimuth ~ U[0, 2π), elevation ~ U[−45°, 45°]). A small ResNet with
InstanceNorm (the reference's layout: 7×7 stride-2 conv, 6 residual blocks of
which two have stride 2, a 4×4 stride-2 conv and a 4×4 conv to one logit) is
trained on random 64² crops of the renders to say "real" (style exemplars,
label 1) or "fake" (detailizer outputs, label 0); its input is 1 − image/255
after a Gaussian blur (σ = 1 for 256² images). Cls = mean of the real accuracy
(logit > 0) and the fake accuracy (logit < 0); 0.5 is ideal (the classifier is
guessing), 1.0 means every crop gives the outputs away.

**Held-out views.** Unlike the reference, which tests on the training images,
every shape's views are split: the last ``test_views`` of its ``n_views``
seeded views are never trained on, and Cls is measured on those only
(``split_views``). Every shape (real and fake) has views on both sides, so the
score says whether *new views* of the same shapes give the outputs away.

Differences from the reference, all for a CPU budget (2 cores, 320 outputs in
a few minutes), and all recorded in ``ClsResult``:

* crops are centred uniformly inside the shape's bounding box in the image
  (clamped to the image), so a crop sees the shape, not only background;
* balanced batches of ``batch`` crops (half real, half fake), one crop
  position per image, and a fixed number of ``steps`` (the reference: batches of
  1024 + 1024, 200 epochs);
* base width 8 instead of 16.

Variants (``CLS_VARIANTS``): ``full`` = 24 views a shape (16 train, 8 test),
1000 steps of 32 + 32 crops; ``quick`` = 8 views (6 train, 2 test), 150
steps, for checks during development. A figure must say which one it used
(``ClsResult.variant``). Measured (full, 20 exemplars + 320 outputs, one
thread, 2 cores shared with a training job): 84 s training + 6 s testing;
rendering the 8160 views ~20 ms each.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Iterable

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import torch


@dataclass(frozen=True)
class ClsConfig:
    """How the Cls-score is measured.

    Attributes:
        variant: the name reported with every figure ("full", "quick", or custom).
        n_views: seeded random views rendered per shape.
        test_views: views per shape held out for testing (the last ones); the rest train.
        steps: optimiser steps.
        batch: crops per step, half real and half fake.
        width: base channel width of the classifier.
        crop: crop edge in pixels.
        lr: Adam learning rate.
        test_crops: crops per held-out image.
        blur_sigma: Gaussian blur of the images, pixels (reference: 1 at 256²).
        seed: seeds crops, batches and the classifier's initial weights.
    """

    variant: str = "full"
    n_views: int = 24
    test_views: int = 8
    steps: int = 1000
    batch: int = 64
    width: int = 8
    crop: int = 64
    lr: float = 1e-3
    test_crops: int = 4
    blur_sigma: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0 < self.test_views < self.n_views:
            raise ValueError(f"test_views must be in [1, n_views), got {self.test_views} of {self.n_views}")
        if self.batch < 2 or self.batch % 2:
            raise ValueError(f"batch must be an even number >= 2, got {self.batch}")
        if self.crop < 16 or self.crop % 16:
            raise ValueError(f"crop must be a multiple of 16 pixels, got {self.crop}")


CLS_FULL = ClsConfig("full")
CLS_QUICK = ClsConfig("quick", n_views=8, test_views=2, steps=150)
CLS_VARIANTS: dict[str, ClsConfig] = {"full": CLS_FULL, "quick": CLS_QUICK}


def split_views(n_views: int, test_views: int) -> tuple[np.ndarray, np.ndarray]:
    """(train, test) view indices of every shape: the last ``test_views`` are held out.

    The views themselves are seeded random angles, so the last ones are as
    random as any; the split is the same for real and fake shapes.
    """
    if not 0 < test_views < n_views:
        raise ValueError(f"test_views must be in [1, n_views), got {test_views} of {n_views}")
    idx = np.arange(n_views)
    return idx[: n_views - test_views], idx[n_views - test_views :]


# --------------------------------------------------------------------------- image banks


@dataclass
class ViewBank:
    """Renders of one class (real or fake), split into train and test views as they arrive.

    ``add(images)`` takes the (n_views, H, W) uint8 renders of one shape. Only
    uint8 images and their shape bounding boxes are kept (64 KiB a 256² view).
    """

    n_views: int
    test_views: int
    train: list[np.ndarray] = field(default_factory=list)
    test: list[np.ndarray] = field(default_factory=list)
    train_shape: list[int] = field(default_factory=list)
    test_shape: list[int] = field(default_factory=list)
    n_shapes: int = 0

    def add(self, images: np.ndarray) -> None:
        if images.ndim != 3 or images.shape[0] != self.n_views or images.dtype != np.uint8:
            raise ValueError(f"expected ({self.n_views}, H, W) uint8 renders of one shape, got "
                             f"{images.dtype} {images.shape}")
        tr, te = split_views(self.n_views, self.test_views)
        self.train += [images[v] for v in tr]
        self.test += [images[v] for v in te]
        self.train_shape += [self.n_shapes] * len(tr)
        self.test_shape += [self.n_shapes] * len(te)
        self.n_shapes += 1


def _boxes(images: list[np.ndarray]) -> np.ndarray:
    """(n, 4) int64 (row_lo, row_hi, col_lo, col_hi) of the non-background pixels (whole image if none)."""
    out = np.zeros((len(images), 4), np.int64)
    for i, im in enumerate(images):
        fg = im < 255
        rows, cols = np.flatnonzero(fg.any(axis=1)), np.flatnonzero(fg.any(axis=0))
        if len(rows):
            out[i] = rows[0], rows[-1], cols[0], cols[-1]
        else:
            out[i] = 0, im.shape[0] - 1, 0, im.shape[1] - 1
    return out


class _Crops:
    """Random crops of a list of same-size uint8 images, centred inside each image's shape box."""

    def __init__(self, images: list[np.ndarray], crop: int, margin: int) -> None:
        if not images:
            raise ValueError("no images")
        self.images = np.stack(images)
        self.boxes = _boxes(images)
        self.crop, self.margin = crop, margin
        h, w = self.images.shape[1:]
        if min(h, w) < crop:
            raise ValueError(f"images of {h}×{w} are smaller than the {crop}² crop")

    def __len__(self) -> int:
        return len(self.images)

    def take(self, which: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(len(which), crop + 2·margin, same) uint8: the crop plus a margin for the blur."""
        n, (h, w) = len(which), self.images.shape[1:]
        box = self.boxes[which]
        cy = rng.integers(box[:, 0], box[:, 1] + 1)
        cx = rng.integers(box[:, 2], box[:, 3] + 1)
        half = self.crop // 2
        y0 = np.clip(cy - half, 0, h - self.crop)
        x0 = np.clip(cx - half, 0, w - self.crop)
        padded = np.pad(self.images[which], ((0, 0), (self.margin,) * 2, (self.margin,) * 2), constant_values=255)
        size = self.crop + 2 * self.margin
        r = np.arange(size)
        return padded[np.arange(n)[:, None, None], (y0[:, None] + r)[:, :, None], (x0[:, None] + r)[:, None, :]]


def _blur_kernel(sigma: float) -> tuple[np.ndarray, int]:
    radius = max(1, int(np.ceil(3 * sigma)))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    return (k / k.sum()).astype(np.float32), radius


def _prepare(crops: np.ndarray, kernel: "torch.Tensor", margin: int, device) -> "torch.Tensor":
    """uint8 crops with a margin → (n, 1, crop, crop) float32 1 − blurred/255 on ``device``."""
    import torch
    import torch.nn.functional as F

    x = 1.0 - torch.from_numpy(crops).to(device=device, dtype=torch.float32)[:, None] / 255.0
    if margin:
        k = kernel.to(device)
        x = F.conv2d(x, k.reshape(1, 1, 1, -1))
        x = F.conv2d(x, k.reshape(1, 1, -1, 1))
    return x.contiguous()


# --------------------------------------------------------------------------- classifier


def make_classifier(width: int = 8, crop: int = 64) -> "torch.nn.Module":
    """The reference's small 2-D ResNet (InstanceNorm), base width ``width``; a crop² image → one logit.

    Four stride-2 stages bring a crop to crop/16 (4 for the reference's 64²);
    the last conv's kernel is that size.
    """
    import torch.nn as nn

    class Block(nn.Module):
        def __init__(self, cin: int, cout: int, stride: int) -> None:
            super().__init__()
            self.body = nn.Sequential(
                nn.Conv2d(cin, cout, 3, stride, 1, bias=False), nn.InstanceNorm2d(cout, affine=True),
                nn.LeakyReLU(0.2),
                nn.Conv2d(cout, cout, 3, 1, 1, bias=False), nn.InstanceNorm2d(cout, affine=True))
            self.skip = (nn.Identity() if stride == 1 and cin == cout
                         else nn.Sequential(nn.Conv2d(cin, cout, 1, stride, bias=False),
                                            nn.InstanceNorm2d(cout, affine=True)))
            self.act = nn.LeakyReLU(0.2)

        def forward(self, x):
            return self.act(self.body(x) + self.skip(x))

    w = width
    return nn.Sequential(
        nn.Conv2d(1, w, 7, 2, 3), nn.InstanceNorm2d(w, affine=True), nn.LeakyReLU(0.2),  # 64 → 32
        Block(w, w, 1), Block(w, 2 * w, 2),  # → 16
        Block(2 * w, 2 * w, 1), Block(2 * w, 4 * w, 2),  # → 8
        Block(4 * w, 4 * w, 1), Block(4 * w, 4 * w, 1),
        nn.Conv2d(4 * w, 8 * w, 4, 2, 1), nn.LeakyReLU(0.2),  # → 4
        nn.Conv2d(8 * w, 1, crop // 16, 1, 0),  # → 1
        nn.Flatten(),
    )


@dataclass(frozen=True)
class ClsResult:
    """A Cls-score and how it was measured.

    Attributes:
        cls: (real_acc + fake_acc) / 2 on held-out views; 0.5 ideal.
        real_acc, fake_acc: crop accuracies on the held-out real / fake views.
        variant: the ClsConfig's name ("full", "quick"...).
        split: what is held out ("views": the last test_views views of every shape).
        real_shapes, fake_shapes: shapes per class.
        train_images, test_images: (real, fake) image counts.
        train_s, test_s: seconds spent training / testing the classifier.
        config: the ClsConfig as a dict.
        real_acc_per_shape, fake_acc_per_shape: accuracy on each shape's held-out
            crops, in bank order (which outputs give themselves away).
    """

    cls: float
    real_acc: float
    fake_acc: float
    variant: str
    split: str
    real_shapes: int
    fake_shapes: int
    train_images: tuple[int, int]
    test_images: tuple[int, int]
    train_s: float
    test_s: float
    config: dict
    real_acc_per_shape: list[float] = field(default_factory=list)
    fake_acc_per_shape: list[float] = field(default_factory=list)

    def to_json(self) -> dict:
        d = asdict(self)
        d["train_images"], d["test_images"] = list(self.train_images), list(self.test_images)
        return d


def cls_score(real: ViewBank, fake: ViewBank, cfg: ClsConfig = CLS_FULL, device: str = "cpu",
              progress=None) -> ClsResult:
    """Train the real-vs-fake classifier on the train views and score it on the held-out views.

    Args:
        real, fake: banks filled with ``cfg.n_views`` renders per shape (split by ``cfg.test_views``).
        device: torch device of the classifier.
        progress: optional callable(step, steps) called every 50 steps.
    Raises:
        ValueError: a bank is empty or was split differently from ``cfg``.
    """
    import torch
    import torch.nn.functional as F

    for name, bank in (("real", real), ("fake", fake)):
        if bank.n_shapes == 0:
            raise ValueError(f"no {name} shapes to score")
        if (bank.n_views, bank.test_views) != (cfg.n_views, cfg.test_views):
            raise ValueError(f"the {name} bank has {bank.n_views} views ({bank.test_views} held out); "
                             f"the config wants {cfg.n_views} ({cfg.test_views})")
    kernel_np, margin = _blur_kernel(cfg.blur_sigma)
    kernel = torch.from_numpy(kernel_np)
    train = [_Crops(real.train, cfg.crop, margin), _Crops(fake.train, cfg.crop, margin)]
    rng = np.random.default_rng(cfg.seed)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(cfg.seed)
        net = make_classifier(cfg.width, cfg.crop).to(device)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    half = cfg.batch // 2
    target = torch.cat([torch.ones(half, 1), torch.zeros(half, 1)]).to(device)
    started = time.perf_counter()
    net.train()
    for step in range(cfg.steps):
        crops = np.concatenate([c.take(rng.integers(0, len(c), size=half), rng) for c in train])
        logits = net(_prepare(crops, kernel, margin, device))
        loss = F.binary_cross_entropy_with_logits(logits, target)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if progress is not None and (step + 1) % 50 == 0:
            progress(step + 1, cfg.steps)
    train_s = time.perf_counter() - started

    started = time.perf_counter()
    net.eval()
    acc, per_shape = [], []
    with torch.inference_mode():
        for sign, bank in ((1.0, real), (-1.0, fake)):
            test_rng = np.random.default_rng(cfg.seed + 1)  # the same crop draws for both classes
            crops = _Crops(bank.test, cfg.crop, margin)
            order = np.repeat(np.arange(len(crops)), cfg.test_crops)
            right = np.zeros(len(order), dtype=bool)
            for s in range(0, len(order), 256):
                logits = net(_prepare(crops.take(order[s : s + 256], test_rng), kernel, margin, device))
                right[s : s + 256] = (sign * logits[:, 0] > 0).cpu().numpy()
            acc.append(float(right.mean()))
            shape_of = np.asarray(bank.test_shape)[order]
            per_shape.append([float(right[shape_of == k].mean()) for k in range(bank.n_shapes)])
    test_s = time.perf_counter() - started
    return ClsResult(cls=(acc[0] + acc[1]) / 2, real_acc=acc[0], fake_acc=acc[1], variant=cfg.variant,
                     split="views", real_shapes=real.n_shapes, fake_shapes=fake.n_shapes,
                     train_images=(len(real.train), len(fake.train)), test_images=(len(real.test), len(fake.test)),
                     train_s=train_s, test_s=test_s, config=asdict(cfg), real_acc_per_shape=per_shape[0],
                     fake_acc_per_shape=per_shape[1])


def render_bank(shapes: Iterable, cfg: ClsConfig, seeds: Iterable[int] | None = None) -> ViewBank:
    """A ViewBank of the given shapes' renders (shape i uses view seed ``seeds[i]``, default i)."""
    from evaluation.render_eval import render_views

    bank = ViewBank(cfg.n_views, cfg.test_views)
    seeds = list(seeds) if seeds is not None else None
    for i, shape in enumerate(shapes):
        bank.add(render_views(shape, cfg.n_views, seed=seeds[i] if seeds is not None else i))
    return bank
