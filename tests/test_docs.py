"""Generated documentation stays in step with the declarations it is generated from."""

from __future__ import annotations

from pathlib import Path

from vtkvol.engine.technique_docs import render_markdown

ROOT = Path(__file__).resolve().parents[1]


def test_techniques_page_is_current():
    page = (ROOT / "docs" / "techniques.md").read_text(encoding="utf-8")
    assert page == render_markdown(), (
        "docs/techniques.md is stale: run python -m vtkvol.engine.technique_docs docs/techniques.md"
    )
