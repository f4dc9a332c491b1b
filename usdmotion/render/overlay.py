"""Text overlay (file, frame, time) drawn with Pillow's built-in font: no font files, no network."""

from __future__ import annotations

from functools import lru_cache

import numpy as np


@lru_cache(maxsize=4)
def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)  # Pillow's embedded scalable font (FreeType)
    except (TypeError, OSError):
        return ImageFont.load_default()


def warm_up_text(height: int = 720) -> None:
    """Load the font (and Pillow) ahead of the first frame: about 0.1 s, spent on another thread."""
    _font(max(12, height // 32))


def draw_text(image: np.ndarray, lines: list[str], corner: str = "top-left") -> None:
    """Draw ``lines`` in a translucent dark box into ``image (H, W, 3) uint8`` in place."""
    from PIL import Image, ImageDraw

    height, width = image.shape[:2]
    size = max(12, height // 32)
    font = _font(size)
    pad = size // 2
    text = "\n".join(lines)
    probe = ImageDraw.Draw(Image.new("L", (1, 1)))
    left, top, right, bottom = probe.multiline_textbbox((0, 0), text, font=font, spacing=size // 4)
    box_w, box_h = min(right + 2 * pad, width), min(bottom + 2 * pad, height)
    patch = Image.new("L", (box_w, box_h), 0)
    ImageDraw.Draw(patch).multiline_text((pad, pad - top // 2), text, fill=255, font=font, spacing=size // 4)
    alpha = np.asarray(patch, np.float32)[..., None] / 255.0
    x0 = pad if corner.endswith("left") else width - box_w - pad
    y0 = pad if corner.startswith("top") else height - box_h - pad
    x0, y0 = max(x0, 0), max(y0, 0)
    region = image[y0:y0 + box_h, x0:x0 + box_w].astype(np.float32)
    h, w = region.shape[:2]
    region = region * 0.45 + 0.55 * 20.0  # darkened backing box
    region = region * (1 - alpha[:h, :w]) + 255.0 * alpha[:h, :w]
    image[y0:y0 + h, x0:x0 + w] = region.astype(np.uint8)
