"""What the README's figure scripts (``hero-image.py``, ``renderer-screenshots.py``) share: the
shared-data stack they render, found or refused with one line, and the captions' font."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any


def shared_stack(data_folder: str, name: str) -> Path | None:
    """``data_folder/name``, or None after one ``vtkvol:`` line on stderr when it is missing."""
    stack = Path(data_folder) / name
    if not stack.is_file():
        print(f"vtkvol: {stack}: not found; pass the shared data folder (see its SOURCES.md)",
              file=sys.stderr)
        return None
    return stack


def caption_font(size: int) -> Any:
    """DejaVu Sans at ``size`` px where installed, else Pillow's own scalable font."""
    from PIL import ImageFont

    try:
        return ImageFont.truetype("DejaVuSans.ttf", size)
    except OSError:
        return ImageFont.load_default(size=size)
