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
