"""Generate ``docs/techniques.md`` from the techniques' declared ``PARAMETERS``.

The declaration is the single source of defaults, ranges and units; this page is a view of it.
Regenerate with ``python -m vtkvol.engine.technique_docs docs/techniques.md`` (a test checks the
committed page is current).
"""

from __future__ import annotations

import sys
from pathlib import Path

from vtkvol.engine.technique import installed_techniques
from vtkvol.model.params import Invalidates, Param

HEADER = """# Illumination techniques and their parameters

Generated from each technique's `PARAMETERS` declaration by
`python -m vtkvol.engine.technique_docs docs/techniques.md`; do not edit by hand.
"Recomputes" says what a change costs: *frame* (uniform upload), *shader* (program rebuild),
*illumination* (the precomputed volume is recomputed), *data* (re-upload).
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


def render_markdown() -> str:
    parts = [HEADER]
    for name, cls in sorted(installed_techniques().items()):
        parts.append(f"\n## {cls.LABEL} (`{name}`)\n")
        if cls.DESCRIPTION:
            parts.append(f"\n{cls.DESCRIPTION}\n")
        parts.append(f"\nShader: `resources/shaders/{cls.SHADER}`.\n")
        if not cls.PARAMETERS:
            parts.append("\nNo parameters.\n")
            continue
        parts.append(
            "\n| parameter | default | range | unit | recomputes | meaning |\n"
            "|---|---|---|---|---|---|\n"
        )
        for p in cls.PARAMETERS:
            doc = " ".join(p.doc.split()).replace("|", "\\|")
            parts.append(
                f"| `{p.name}` | {p.default} | {_range(p)} | {p.unit} | "
                f"{_invalidates(p.invalidates)} | {doc} |\n"
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
