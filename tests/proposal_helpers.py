"""Small builders shared by the proposal tests (not a test module: pytest does not collect it)."""

from __future__ import annotations

import numpy as np

from npsim_core.proposals import ProposalParams

SKY = 23
#: No camera pitch: the test canvases are drawn as seen level.
FLAT = ProposalParams(camera_pitch_rad=0.0)


def canvas(H: int = 120, W: int = 200, label: int = SKY, color=(150, 170, 200)) -> tuple[np.ndarray, np.ndarray]:
    """(image, labels): an H x W uint8 RGB image of one ``color`` and its labels, all ``label``."""
    img = np.zeros((H, W, 3), np.uint8)
    img[:] = color
    return img, np.full((H, W), label, np.uint8)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (0 when both are empty)."""
    return float((a & b).sum() / max(1, (a | b).sum()))


def first_call_of(module, name: str, W: int, H: int, seed: int, variant: str, depth: bool,
                  texture: bool = True, copy_args: bool = False) -> tuple:
    """The arguments of the first call of ``module.name`` while the windows proposer runs on a fixture
    street (``street_scene(W, H, seed, variant)``; its walls textured twice as tests/test_proposals_fuzz.py
    does, rng ``seed``, when ``texture``; with the scene's depth or none). ``copy_args`` deep-copies them
    (for a stage that changes its inputs in place). Used to replay one stage both ways on real inputs."""
    import copy

    from test_proposals_fuzz import _expose

    from npsim_core.proposals import propose_lights
    from npsim_core.synthetic import street_scene

    s = street_scene(W, H, seed, variant)
    img = s.image
    if texture:
        rng = np.random.default_rng(seed)
        img = _expose(_expose(img, s.labels, "texture", rng), s.labels, "texture", rng)
    seen = []
    real = getattr(module, name)

    def spy(*args, **kw):
        got = args + tuple(kw.values())          # keyword arguments after the positional ones
        seen.append(copy.deepcopy(got) if copy_args else got)
        return real(*args, **kw)

    setattr(module, name, spy)
    try:
        propose_lights(img, s.labels, s.depth if depth else None, s.intrinsics, None,
                       ProposalParams(categories=("windows",)))
    finally:
        setattr(module, name, real)
    return seen[0]
