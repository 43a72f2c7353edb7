"""Write docs/images/hero.png, the README's first picture: one real stack of the shared data
under local shading, shadows, ambient occlusion and scattering, side by side.

The stack is the Platynereis nucleus label image (``platynereis_nuclei_labels_256x256x103.tif``
of the data folder, see its SOURCES.md; CC BY 4.0, BioImageAnalysisNotebooks, Robert Haase and
contributors, after Ozpolat et al.) shown as labels (categorical colours), the way
``vtkvol render --labels`` shows it. Each panel is rendered offscreen at PANEL² pixels,
cropped to the specimen (framed tight) and the four are composed into a 2 × 2 grid
WIDTH (1600) px wide, with each method's name under its panel. Headless (EGL), from the checkout:

    .venv/bin/python scripts/hero-image.py [DATA_FOLDER] [-o docs/images/hero.png]

DATA_FOLDER defaults to ``../shared/data`` beside the checkout. The PNG is reduced to 256
colours when that keeps it under 600 KB.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from figure_common import caption_font, shared_stack

ROOT = Path(__file__).resolve().parents[1]
STACK = "platynereis_nuclei_labels_256x256x103.tif"
#: (method, parameters, caption) of each panel, left to right.
PANELS: tuple[tuple[str, dict, str], ...] = (
    ("local", {}, "local shading"),
    ("shadow_volume", {}, "shadows"),
    ("cone_traced", {"shadows": False}, "ambient occlusion"),
    # Translucency: light scattered through the material (directional diffusion), coloured
    # by the labels; hybrid_diffusion's multiple scattering did not converge within 25 min on
    # two cores without a GPU.
    ("translucency", {}, "scattering (translucency)"),
)
#: Offscreen size of one panel before cropping (px).
PANEL = 720
#: Width of the composed image (px).
WIDTH = 1600
#: Largest PNG committed (bytes).
MAX_BYTES = 600_000


def _crop_to_specimen(image: np.ndarray, background: np.ndarray, margin: int = 6) -> np.ndarray:
    """``image`` cut to the box of pixels that differ from ``background`` (RGB 0…255), plus
    ``margin`` px on each side."""
    differs = np.abs(image.astype(np.int16) - background.astype(np.int16)).max(axis=-1) > 8
    rows, cols = np.flatnonzero(differs.any(axis=1)), np.flatnonzero(differs.any(axis=0))
    if not len(rows):
        return image
    top, bottom = max(0, rows[0] - margin), min(image.shape[0], rows[-1] + margin + 1)
    left, right = max(0, cols[0] - margin), min(image.shape[1], cols[-1] + margin + 1)
    return image[top:bottom, left:right]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", default=str(ROOT.parent / "shared" / "data"),
                        help="folder holding the shared stacks (default ../shared/data)")
    parser.add_argument("-o", "--output", default=str(ROOT / "docs" / "images" / "hero.png"))
    parser.add_argument("--max-seconds", type=float, default=240.0,
                        help="time budget of a progressive method's refinement (s)")
    args = parser.parse_args(argv)
    stack = shared_stack(args.data, STACK)
    if stack is None:
        return 2

    from PIL import Image, ImageDraw

    from vtkvol.engine.api import render_image
    from vtkvol.io import read_volume
    from vtkvol.model.defaults import scene_for
    from vtkvol.model.labels import apply_labels

    data = read_volume(stack)
    ids = [int(v) for v in np.unique(data.array[0]) if v != 0]
    panels = []
    for method, parameters, caption in PANELS:
        model = scene_for(data)
        apply_labels(model, ids)
        model.render.background = (1.0, 1.0, 1.0)
        start = time.perf_counter()
        image = render_image(data, model=model, size=(PANEL, PANEL), method=method,
                             parameters=parameters, azimuth=35.0, elevation=30.0,
                             max_seconds=args.max_seconds,
                             on_error=lambda m: print(f"vtkvol: {m}", file=sys.stderr))
        print(f"{caption}: {time.perf_counter() - start:.1f} s", file=sys.stderr)
        panels.append((_crop_to_specimen(image, np.array([255, 255, 255])), caption))

    # A 2 × 2 grid: one height for all panels, scaled so that a row of two fills WIDTH.
    height = max(p.shape[0] for p, _ in panels)
    scaled = [Image.fromarray(p).resize((round(p.shape[1] * height / p.shape[0]), height),
                                        Image.Resampling.LANCZOS) for p, _ in panels]
    gap, caption_h = 16, 48
    column = max(im.width for im in scaled)
    factor = (WIDTH - 3 * gap) / (2 * column)
    scaled = [im.resize((round(im.width * factor), round(im.height * factor)),
                        Image.Resampling.LANCZOS) for im in scaled]
    cell_w, cell_h = round(column * factor), scaled[0].height + caption_h
    canvas = Image.new("RGB", (WIDTH, 2 * cell_h + 3 * gap), "white")
    draw = ImageDraw.Draw(canvas)
    font = caption_font(30)
    for i, (im, (_, caption)) in enumerate(zip(scaled, panels, strict=True)):
        x = gap + (i % 2) * (cell_w + gap)
        y = gap + (i // 2) * (cell_h + gap)
        canvas.paste(im, (x + (cell_w - im.width) // 2, y))
        width = draw.textlength(caption, font=font)
        draw.text((x + (cell_w - width) / 2, y + im.height + 8), caption, fill=(40, 40, 40),
                  font=font)
    out = Path(args.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(out, optimize=True)
    if out.stat().st_size > MAX_BYTES:
        canvas.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, optimize=True)
    print(f"wrote {out} ({canvas.width}×{canvas.height}, {out.stat().st_size // 1024} KB)",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
