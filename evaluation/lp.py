"""The paper's local-patch metrics, LP-IOU and LP-F-score (``reference/method.md`` §5).

LP-IOU / LP-F: the fraction of ``n`` sampled surface patches (12³) of an output
whose best match among all surface patches of the style shapes has IOU (resp.
F-score with a 1-voxel tolerance) strictly above 0.95. Patches are defined in
``evaluation/patches.py``; the dictionary and its exact pruned search in
``evaluation/patch_index.py``. Strict/Loose-IOU is ``core/structure.py``.
"""

from __future__ import annotations

from evaluation.patch_index import StyleDictionary, f_similar, iou_similar
from evaluation.patches import N_PATCHES, as_bool_tensor, patch_set, sample_surface_patches


def lp_scores(output, style_dict: StyleDictionary, n: int = N_PATCHES, seed: int = 0) -> tuple[float, float]:
    """LP-IOU and LP-F-score of one output against a style dictionary.

    Args:
        output: (X, Y, Z) bool fine output (floats binarised at ISO_LEVEL).
        style_dict: from ``style_patch_dictionary``; move it to the output's
            device once with ``.to()`` (otherwise it is copied on every call).
        n: patches sampled from the output (paper: 1000).
        seed: sampling seed.
    Returns:
        (lp_iou, lp_f), fractions in [0, 1] of sampled patches that are
        similar. An output without any surface patch scores (0.0, 0.0).
    """
    occ = as_bool_tensor(output, "output")
    pos = sample_surface_patches(occ, n=n, seed=seed)
    if len(pos) == 0:
        return 0.0, 0.0
    patches = patch_set(occ, pos)
    d = style_dict.to(occ.device) if style_dict.device != occ.device else style_dict
    lp_iou = float(iou_similar(patches.occ, d).mean())
    lp_f = float(f_similar(patches.surf, patches.dil, d).mean())
    return lp_iou, lp_f
