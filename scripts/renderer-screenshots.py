"""Write docs/screenshots/renderers-bead.png, the README's picture of the four ways the volume
can be drawn: VTK's ray caster, view-aligned slicing, half-angle slicing and the camera path
tracer, on one real stack of the shared data, side by side in one row.

The stack is ``Bead_Image1_crop.tif`` of the data folder (see its SOURCES.md), with the default
scene the app opens it with. The ray caster and slicing panels use local shading; half-angle
slicing and the path tracer light the medium material (albedo, phase) with the scene's one
light, so their pictures show scattered light where the others show surface shading. Each panel
is rendered offscreen at PANEL² pixels with the same camera (its time is printed), and all
four are cut to the one box that holds the specimen in every panel. Headless
(EGL), from the checkout:

    .venv/bin/python scripts/renderer-screenshots.py [DATA_FOLDER] [-o OUTPUT_PNG]

DATA_FOLDER defaults to ``../shared/data`` beside the checkout.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from figure_common import caption_font, shared_stack

ROOT = Path(__file__).resolve().parents[1]
STACK = "Bead_Image1_crop.tif"
#: (volume renderer, illumination method, caption) of each panel, left to right.
PANELS: tuple[tuple[str, str, str], ...] = (
    ("raycast", "local", "ray caster"),
    ("slicing", "local", "view-aligned slicing"),
    ("half_angle", "local", "half-angle slicing"),
    ("path_tracer", "local", "camera path tracer"),
)
#: Offscreen size of one panel before cropping (px).
PANEL = 560


def specimen_box(images: list[np.ndarray], margin: int = 12) -> tuple[int, int, int, int]:
    """(top, bottom, left, right) px of the box holding every pixel that differs from the
    background (the corner pixel) in any of ``images``, plus ``margin`` px on each side."""
    differs = np.zeros(images[0].shape[:2], bool)
    for image in images:
        background = image[0, 0].astype(np.int16)
        differs |= np.abs(image.astype(np.int16) - background).max(axis=-1) > 6
    rows, cols = np.flatnonzero(differs.any(axis=1)), np.flatnonzero(differs.any(axis=0))
    if not len(rows):
        return 0, differs.shape[0], 0, differs.shape[1]
    return (max(0, rows[0] - margin), min(differs.shape[0], rows[-1] + margin + 1),
            max(0, cols[0] - margin), min(differs.shape[1], cols[-1] + margin + 1))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", default=str(ROOT.parent / "shared" / "data"),
                        help="folder holding the shared stacks (default ../shared/data)")
    parser.add_argument("-o", "--output",
                        default=str(ROOT / "docs" / "screenshots" / "renderers-bead.png"))
    parser.add_argument("--max-seconds", type=float, default=300.0,
                        help="time budget of the path tracer's refinement (s)")
    args = parser.parse_args(argv)
    stack = shared_stack(args.data, STACK)
    if stack is None:
        return 2

    from PIL import Image, ImageDraw

    from vtkvol.engine.api import render_image
    from vtkvol.io import read_volume

    data = read_volume(stack)
    panels = []
    for renderer, method, caption in PANELS:
        start = time.perf_counter()
        image = render_image(data, size=(PANEL, PANEL), method=method, azimuth=35.0,
                             elevation=25.0, max_seconds=args.max_seconds,
                             volume_renderer=renderer,
                             on_error=lambda m: print(f"vtkvol: {m}", file=sys.stderr))
        seconds = time.perf_counter() - start
        print(f"{caption}: {seconds:.1f} s", file=sys.stderr)
        panels.append((image, caption))

    top, bottom, left, right = specimen_box([image for image, _ in panels])
    panels = [(image[top:bottom, left:right], caption) for image, caption in panels]
    width, height = right - left, bottom - top
    gap, caption_h = 8, 28
    canvas = Image.new("RGB", (len(panels) * (width + gap) + gap, height + caption_h + 2 * gap),
                       "white")
    draw = ImageDraw.Draw(canvas)
    font = caption_font(17)
    for i, (image, caption) in enumerate(panels):
        x = gap + i * (width + gap)
        canvas.paste(Image.fromarray(np.ascontiguousarray(image)), (x, gap))
        text_width = draw.textlength(caption, font=font)
        draw.text((x + (width - text_width) / 2, gap + height + 4), caption, fill=(40, 40, 40),
                  font=font)
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(out, optimize=True)
    print(f"wrote {out} ({canvas.width}×{canvas.height}, {out.stat().st_size // 1024} KB)",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
