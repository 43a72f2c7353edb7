"""The benchmark's charts (:mod:`vtkvol.bench.report`'s drawing half): time against error with
the Pareto front, and the stability sweeps. matplotlib is loaded only when a chart is drawn."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

#: Colour-blind-safe palette (Okabe–Ito, then Tableau), handed out in method order.
_PALETTE = ("#444444", "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9",
            "#8c564b", "#9467bd", "#bcbd22", "#17becf", "#7f7f7f")

def slug(text: str) -> str:
    """A file-name-safe lower-case slug (``"llvmpipe (LLVM 15.0.6, 256 bits)"`` → ``llvmpipe``
    for software renderers, the GPU's name otherwise)."""
    low = text.lower()
    if "llvmpipe" in low:
        return "llvmpipe"
    return re.sub(r"[^a-z0-9]+", "-", low).strip("-")[:40] or "unknown"


def method_colors(methods: Sequence[str]) -> dict[str, str]:
    """A colour per method, assigned in the order the methods first appear (the run's order:
    local first, then the techniques, VTK's scattering last), so a chart never depends on a
    table of known technique names; the palette repeats after 12 methods."""
    order = list(dict.fromkeys(methods))
    return {m: _PALETTE[k % len(_PALETTE)] for k, m in enumerate(order)}


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and math.isfinite(value)


def _lighting(record: Mapping[str, Any]) -> str:
    """The lighting model a record was measured under (older results: surface)."""
    return str(record.get("lighting") or "surface")



# ------------------------------------------------------------------------------------------
# Charts
# ------------------------------------------------------------------------------------------
def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")  # no display: charts are files only
    import matplotlib.pyplot as plt

    return plt


def chart_paths(run: Mapping[str, Any]) -> dict[str, str]:
    """Chart file names (relative to the output folder) of one run."""
    base = f"benchmarks/{run['mode']}-{slug(run['renderer'])}"
    return {"pareto": f"{base}-pareto.png", "stability": f"{base}-stability.png"}


def _label_points(ax: Any, xs: Sequence[float], ys: Sequence[float], labels: Sequence[str],
                  color: str) -> None:
    """Every point gets its setting label; offsets alternate so neighbours overlap less."""
    offsets = ((4, 3), (4, -8), (-4, 6), (-4, -9))
    for k, (x, y, text) in enumerate(zip(xs, ys, labels, strict=True)):
        dx, dy = offsets[k % len(offsets)]
        ax.annotate(text, (x, y), xytext=(dx, dy), textcoords="offset points", fontsize=6,
                    color=color, ha="left" if dx > 0 else "right")


def pareto_chart(path: Path, run: Mapping[str, Any], records: Sequence[Mapping[str, Any]]) -> None:
    """Error (RMSE against the scene's reference image) against frame time and against
    recompute time, one row per scene and lighting model (the methods measured against the
    same reference), every setting labelled, the Pareto front drawn and its points filled."""
    plt = _pyplot()
    from matplotlib.lines import Line2D

    rows = list(dict.fromkeys((r["scene"], _lighting(r)) for r in records))
    methods = list(dict.fromkeys(r["method"] for r in records))
    colors = method_colors(methods)
    fig, axes = plt.subplots(len(rows), 2, figsize=(14, 3.9 * max(1, len(rows))),
                             squeeze=False)
    floor = 0.1  # recompute 0 (no precomputation) is drawn here so a log axis can show it
    for row, (scene, lighting) in enumerate(rows):
        group = [r for r in records
                 if r["scene"] == scene and _lighting(r) == lighting and r.get("ok")]
        for col, (key, flag, title) in enumerate((
            ("frame_ms", "pareto_frame", "frame time (ms, median)"),
            ("recompute_ms", "pareto_recompute", "recompute time (ms, median)"),
        )):
            ax = axes[row][col]
            for method in methods:
                pts = [r for r in group if r["method"] == method and _finite(r.get(key))
                       and _finite(r.get("rmse"))]
                if not pts:
                    continue
                xs = [max(float(r[key]), floor) for r in pts]
                ys = [float(r["rmse"]) for r in pts]
                color = colors[method]
                for x, y, r in zip(xs, ys, pts, strict=True):
                    on = bool(r.get(flag))
                    ax.scatter([x], [y], s=36, zorder=3, color=color if on else "none",
                               edgecolors=color)
                _label_points(ax, xs, ys, [str(r.get("short") or r["setting"]) for r in pts],
                              color)
            front_pts = sorted((max(float(r[key]), floor), float(r["rmse"])) for r in group
                               if r.get(flag) and _finite(r.get(key)) and _finite(r.get("rmse")))
            if front_pts:
                fx, fy = zip(*front_pts, strict=True)
                ax.step(fx, fy, where="post", color="#999999", lw=1, ls="--", zorder=1)
            ax.set_xscale("log")
            errs = [float(r["rmse"]) for r in group if _finite(r.get("rmse")) and r["rmse"] > 0]
            if errs and max(errs) / min(errs) > 8:  # spread the accurate cluster near 0
                from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

                ax.set_yscale("log")
                ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
                ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
                ax.yaxis.set_minor_formatter(NullFormatter())
            if key == "recompute_ms":
                ax.axvline(floor, color="#cccccc", lw=0.8, zorder=0)
                ax.annotate("no precomputation", (floor, 1.0), xycoords=("data", "axes fraction"),
                            xytext=(3, -10), textcoords="offset points", fontsize=6,
                            color="#777777")
            ax.set_xlabel(title)
            ax.set_ylabel("RMSE vs reference (8-bit levels)")
            reference = next((str(r.get("reference")) for r in group if r.get("reference")),
                             "")
            ax.set_title(f"{scene} — {lighting} lighting, reference {reference}", fontsize=10,
                         loc="left")
            ax.grid(True, which="both", alpha=0.25)
    handles = [Line2D([], [], marker="o", ls="", color=colors[m], label=m) for m in methods]
    handles += [
        Line2D([], [], marker="o", ls="", color="#555555", label="on the Pareto front"),
        Line2D([], [], marker="o", ls="", color="#555555", markerfacecolor="none",
               label="dominated"),
        Line2D([], [], ls="--", color="#999999", label="Pareto front"),
    ]
    height = 3.9 * max(1, len(rows))
    fig.suptitle(f"vtkvol bench ({run['mode']}): error against time on {run['renderer']}, "
                 f"{run['date'][:10]}", fontsize=11, y=1.0 - 0.12 / height)
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), fontsize=8,
               bbox_to_anchor=(0.5, 1.0 - 0.42 / height), frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 1.0 - 0.75 / height))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def stability_chart(path: Path, run: Mapping[str, Any],
                    cases: Sequence[Mapping[str, Any]]) -> None:
    """Error (RMSE against the reference) against each swept variable, one line per
    method/setting; failed cases (shader or bounds) are marked with a red cross."""
    plt = _pyplot()
    sweeps = list(dict.fromkeys(c["sweep"] for c in cases))
    colors = method_colors([c["method"] for c in cases])
    cols = 3
    rows = max(1, math.ceil(len(sweeps) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(15, 3.8 * rows), squeeze=False)
    for k, sweep in enumerate(sweeps):
        ax = axes[k // cols][k % cols]
        group = [c for c in cases if c["sweep"] == sweep]
        unit = group[0].get("unit", "")
        per_method: dict[str, int] = {}
        for key in dict.fromkeys((c["method"], c["setting"]) for c in group):
            pts = sorted((c for c in group if (c["method"], c["setting"]) == key),
                         key=lambda c: c["value"])
            xs = [c["value"] for c in pts]
            ys = [c["rmse"] if _finite(c.get("rmse")) else math.nan for c in pts]
            label = key[0] if key[1] in ("default", "") else f"{key[0]} {key[1]}"
            k = per_method[key[0]] = per_method.get(key[0], -1) + 1  # settings of one method
            ax.plot(xs, ys, marker="osD^v"[k % 5], ms=4, color=colors[key[0]],
                    label=label, alpha=0.9, ls=("-", "--", ":", "-.")[k % 4])
            bad = [(x, y if _finite(y) else 0.0) for x, y, c in zip(xs, ys, pts, strict=True)
                   if not c.get("ok")]
            if bad:
                ax.scatter(*zip(*bad, strict=True), marker="x", color="red", s=60, zorder=4)
        values = [c["value"] for c in group]
        positive = [v for v in values if v > 0]
        if sweep == "opacity_scale" or (min(values) > 0 and max(values) / min(values) > 20):
            ax.set_xscale("log")
        elif positive and min(values) == 0 and max(positive) / min(positive) > 20:
            ax.set_xscale("symlog", linthresh=min(positive))  # 0 and decades of small values
        labels = {c["value"]: c["value_label"] for c in group}
        ax.set_xticks(sorted(labels))
        ax.set_xticklabels([labels[v] for v in sorted(labels)], fontsize=7, rotation=30)
        ax.minorticks_off()
        ax.set_xlabel(f"{sweep} ({unit})" if unit else sweep)
        ax.set_ylabel("RMSE vs reference (8-bit)")
        ax.grid(True, alpha=0.25)
        ax.legend(fontsize=6)
    for k in range(len(sweeps), rows * cols):
        axes[k // cols][k % cols].axis("off")
    fig.suptitle(f"vtkvol bench ({run['mode']}): stability sweeps on {run['renderer']}, "
                 f"{run['date'][:10]}; red × = failed check", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
