"""Generate ``docs/techniques.md`` from the techniques' declarations (``TechniqueSpec``).

The declaration is the single source of defaults, ranges and units; this page is a view of it.
Regenerate with ``python -m vtkvol.engine.technique_docs docs/techniques.md`` (a test checks the
committed page is current).
"""

from __future__ import annotations

import sys
from pathlib import Path

from vtkvol.model.params import Invalidates, Param
from vtkvol.model.techniques import technique_specs

HEADER = """# Illumination techniques and their parameters

Generated from each technique's declaration (`TECHNIQUE` in its plugin package) by
`python -m vtkvol.engine.technique_docs docs/techniques.md`; do not edit by hand.
"Recomputes" says what a change costs: *frame* (uniform upload), *shader* (program rebuild),
*illumination* (the precomputed volume is recomputed), *accumulation* (progressive refinement
restarts). "Applies when" names the other settings under which a parameter has an effect (the
lights dock hides it otherwise).
"""


def _range(p: Param) -> str:
    if p.kind == "choice":
        return " / ".join(p.choices)
    if p.kind == "bool":
        return "on / off"
    if p.range is None:
        return ""
    lo, hi = p.range
    return f"{lo:g} … {hi:g}" + (" (log)" if p.scale == "log" else "")


def _invalidates(flag: Invalidates) -> str:
    names = [f.name.lower() for f in Invalidates if f & flag]  # type: ignore[union-attr]
    return ", ".join(names) or "frame"


def _applies(p: Param) -> str:
    return "; ".join(
        f"`{other}` is " + " or ".join(str(v) for v in allowed) for other, allowed in p.applies_when
    ) or "always"


def render_markdown() -> str:
    parts = [HEADER]
    for name, spec in sorted(technique_specs().items()):
        parts.append(f"\n## {spec.label} (`{name}`)\n")
        if spec.description:
            parts.append(f"\n{spec.description}\n")
        package = spec.engine.partition(":")[0].rpartition(".")[0]
        capabilities = ", ".join(sorted(spec.capabilities)) or "none"
        parts.append(
            f"\nLighting model: `{spec.lighting}`. Capabilities: {capabilities}. "
            f"Package: `{package}`.\n"
        )
        if not spec.parameters:
            parts.append("\nNo parameters.\n")
            continue
        parts.append(
            "\n| parameter | default | range | unit | recomputes | applies when | meaning |\n"
            "|---|---|---|---|---|---|---|\n"
        )
        for p in spec.parameters:
            doc = " ".join(p.doc.split()).replace("|", "\\|")
            parts.append(
                f"| `{p.name}` | {p.default} | {_range(p)} | {p.unit} | "
                f"{_invalidates(p.invalidates)} | {_applies(p)} | {doc} |\n"
            )
    return "".join(parts)


def main(argv: list[str]) -> int:
    text = render_markdown()
    if len(argv) > 1:
        Path(argv[1]).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
