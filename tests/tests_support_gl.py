"""Test support: record the GL objects vtkvol's wrappers create (``Texture3D`` and its
subclasses, ``ComputeProgram``), so a leak test checks exactly those handles instead of
scanning the GL name space."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pytest
import vtk

from vtkvol.engine import gl as vgl


@dataclass
class Created:
    obj: Any
    kind: str  # "texture" or "program"
    handle: int  # the GL name, recorded at creation (the wrapper forgets it on release)

    @property
    def released(self) -> bool:
        return (self.obj.tex if self.kind == "texture" else self.obj.prog) is None


class GlObjects:
    """Every texture and compute program created while installed (through ``monkeypatch``)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.created: list[Created] = []
        texture_init = vgl.Texture3D.__init__
        program_init = vgl.ComputeProgram.__init__

        def record_texture(obj: vgl.Texture3D, *args: Any, **kwargs: Any) -> None:
            texture_init(obj, *args, **kwargs)
            self.created.append(Created(obj, "texture", obj.handle))

        def record_program(obj: vgl.ComputeProgram, *args: Any, **kwargs: Any) -> None:
            program_init(obj, *args, **kwargs)
            self.created.append(Created(obj, "program", int(obj.prog.GetHandle())))

        monkeypatch.setattr(vgl.Texture3D, "__init__", record_texture)
        monkeypatch.setattr(vgl.ComputeProgram, "__init__", record_program)

    def held(self) -> list[Created]:
        """Objects not released yet."""
        return [c for c in self.created if not c.released]

    def alive_in_gl(self, rw: vtk.vtkRenderWindow, objects: list[Created]) -> list[Created]:
        """Those of ``objects`` whose GL name still exists. Only meaningful right after they
        were released, before anything else could be given the same name."""
        GL = vgl.gl(rw)
        rw.MakeCurrent()
        check = {"texture": GL.glIsTexture, "program": GL.glIsProgram}
        return [c for c in objects if check[c.kind](c.handle)]
