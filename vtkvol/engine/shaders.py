"""GLSL files sectioned by the VTK template tag they touch, and their composition.

A shader file is plain GLSL in the ``shaders/`` folder of a package: the host's in
``vtkvol.resources``, each technique's in its plugin package. Fragment files carry marker lines::

    //@inject //VTK::ComputeLighting::Dec pre before
    float vv_light_visibility(int i, vec3 texPos, vec3 dirDS) { return 1.0; }

Marker fields: the tag; ``pre`` (applied before VTK's own substitutions, so the tag still
exists) or ``post`` (after them; needed for tags VTK creates itself, such as
``//VTK::ComputeLighting::Exit``); and where the code goes: ``before`` or ``after`` the tag
(the tag is kept) or ``replace``. ``//@include name.glsl`` inlines a helper file from the same
package's ``shaders/`` (or, failing that, the host's). Compute shaders use the same loader
(:func:`compute_source`): includes, and defines inserted after ``#version``.

VTK keeps one replacement per (tag, pre/post), so every snippet aimed at the same tag by the
host and the technique is merged into one replacement string by :func:`compose`.
"""

from __future__ import annotations

import functools
import re
from collections import defaultdict
from dataclasses import dataclass
from importlib import resources
from typing import Literal

import vtk

Phase = Literal["pre", "post"]
Where = Literal["before", "after", "replace"]

_MARKER = re.compile(r"^\s*//@inject\s+(//VTK::\S+)\s+(pre|post)\s+(before|after|replace)\s*$")
_INCLUDE = re.compile(r"^\s*//@include\s+(\S+)\s*$")


@dataclass(frozen=True)
class Section:
    tag: str
    phase: Phase
    where: Where
    code: str
    origin: str  # file name, for error messages and for the marker comment


class ShaderFileError(ValueError):
    """A shader resource is missing or malformed."""


HOST_PACKAGE = "vtkvol.resources"


def read_resource(name: str, package: str = HOST_PACKAGE) -> str:
    """Text of ``<package>/shaders/<name>``; for a technique's package, a name it does not
    have is looked up among the host's shaders (shared helpers)."""
    for pkg in dict.fromkeys((package, HOST_PACKAGE)):
        try:
            path = resources.files(pkg).joinpath("shaders", *name.split("/"))
        except ModuleNotFoundError:
            continue
        if path.is_file():
            return path.read_text(encoding="utf-8")
    raise ShaderFileError(f"shader {name!r} not found in {package}/shaders")


def _expand_includes(
    text: str, origin: str, package: str = HOST_PACKAGE, seen: tuple[str, ...] = ()
) -> str:
    out = []
    for line in text.splitlines():
        m = _INCLUDE.match(line)
        if m:
            name = m.group(1)
            if name in seen:
                raise ShaderFileError(f"{origin}: include cycle through {name}")
            out.append(f"// ---- vtkvol include {name}")
            out.append(
                _expand_includes(read_resource(name, package), name, package, (*seen, name))
            )
        else:
            out.append(line)
    return "\n".join(out)


def compute_source(
    name: str, defines: dict[str, str] | None = None, package: str = HOST_PACKAGE
) -> str:
    """A compute shader's full source: includes expanded and ``defines`` as ``#define`` lines
    right after the ``#version`` line (which GLSL requires to come first)."""
    text = _expand_includes(read_resource(name, package), name, package)
    lines = text.splitlines()
    at = next((i + 1 for i, line in enumerate(lines) if line.startswith("#version")), 0)
    extra = [f"#define {k} {v}" for k, v in sorted((defines or {}).items())]
    return "\n".join([*lines[:at], *extra, *lines[at:]]) + "\n"


def parse(text: str, origin: str, package: str = HOST_PACKAGE) -> list[Section]:
    """Split a sectioned GLSL text into :class:`Section` objects."""
    sections: list[Section] = []
    current: tuple[str, Phase, Where] | None = None
    body: list[str] = []

    def flush() -> None:
        if current is not None:
            code = _expand_includes("\n".join(body).strip("\n"), origin, package)
            sections.append(Section(*current, code=code, origin=origin))

    for line in text.splitlines():
        m = _MARKER.match(line)
        if m:
            flush()
            current = (m.group(1), m.group(2), m.group(3))  # type: ignore[assignment]
            body = []
        elif line.lstrip().startswith("//@"):
            if not _INCLUDE.match(line):
                raise ShaderFileError(f"{origin}: unknown marker line {line.strip()!r}")
            body.append(line)
        elif current is not None:
            body.append(line)
    flush()
    return sections


def load(
    name: str, defines: dict[str, str] | None = None, package: str = HOST_PACKAGE
) -> list[Section]:
    """Parse ``<package>/shaders/<name>``; ``defines`` become ``#define`` lines before the first
    section (compile-time variants: on llvmpipe, branches on uniforms cost as much as all
    branches).

    The host asks for its sections on every frame, so files are read and parsed once."""
    return list(_load_cached(name, tuple(sorted((defines or {}).items())), package))


@functools.cache
def _load_cached(
    name: str, defines: tuple[tuple[str, str], ...], package: str
) -> tuple[Section, ...]:
    sections = parse(read_resource(name, package), name, package)
    if defines:
        prefix = "\n".join(f"#define {k} {v}" for k, v in defines)
        sections = [
            Section(s.tag, s.phase, s.where, f"{prefix}\n{s.code}", s.origin) if i == 0 else s
            for i, s in enumerate(sections)
        ]
    return tuple(sections)


def marker(section: Section) -> str:
    """The comment :func:`compose` puts before a section's code; finding it in the shader VTK
    built proves the section's tag existed. (The tag is written without its ``//VTK::`` prefix
    so VTK's own substitutions can never match the comment.)"""
    return f"vtkvol<{section.origin}> at {section.tag.removeprefix('//VTK::')}"


def compose(sections: list[Section]) -> dict[tuple[str, Phase], str]:
    """Merge sections into one replacement string per (tag, phase), in list order."""
    grouped: dict[tuple[str, Phase], list[Section]] = defaultdict(list)
    for s in sections:
        grouped[(s.tag, s.phase)].append(s)
    result: dict[tuple[str, Phase], str] = {}
    for (tag, phase), group in grouped.items():
        replaced = [s for s in group if s.where == "replace"]
        if len(replaced) > 1:
            names = ", ".join(s.origin for s in replaced)
            raise ShaderFileError(f"{tag} ({phase}) is replaced by more than one file: {names}")
        before = [f"// {marker(s)}\n{s.code}" for s in group if s.where == "before"]
        after = [f"// {marker(s)}\n{s.code}" for s in group if s.where == "after"]
        middle = [f"// {marker(replaced[0])}\n{replaced[0].code}"] if replaced else [tag]
        result[(tag, phase)] = "\n".join([*before, *middle, *after])
    return result


class ShaderConflictError(ValueError):
    """The user's own replacement at a tag ours also needs cannot be composed with ours."""


Key = tuple[str, Phase]
#: A replacement as VTK stores it: (replacement text, replace every occurrence).
Value = tuple[str, bool]


def fragment_replacements(shader_property: vtk.vtkShaderProperty) -> dict[Key, Value]:
    """The fragment-shader replacements on ``shader_property``, by (tag, phase)."""
    out: dict[Key, Value] = {}
    sp = shader_property
    for i in range(sp.GetNumberOfShaderReplacements()):
        if sp.GetNthShaderReplacementTypeAsString(i) != "Fragment":
            continue
        name, first, text, every = (vtk.reference(""), vtk.reference(False),
                                    vtk.reference(""), vtk.reference(False))
        sp.GetNthShaderReplacement(i, name, first, text, every)
        out[(name.get(), "pre" if first.get() else "post")] = (text.get(), bool(every.get()))
    return out


def compose_with_user(key: Key, ours: str, user: Value | None) -> Value:
    """Our replacement text for ``key`` combined with the user's own one there, if any.

    VTK keeps one replacement per (tag, phase), so a second one would silently drop the
    first. Both are substitutions of the tag: where the user's text keeps the tag, ours takes
    its place inside the user's (their code stays around VTK's, ours right next to VTK's, as
    without them); where only ours keeps it (we add code before/after), the user's takes its
    place inside ours. Where neither keeps it, both replace VTK's code: refused.
    """
    if user is None:
        return ours, False
    tag, phase = key
    text, every = user
    if tag in text:
        return text.replace(tag, ours, 1), every
    if tag in ours:
        return ours.replace(tag, text, 1), every
    raise ShaderConflictError(
        f"vtkvol: the volume's shader property already replaces {tag} ({phase}) with code of "
        "its own (the tag is not kept), and vtkvol's illumination replaces that tag too; "
        "keep the tag in that replacement or remove it "
        "(vtkShaderProperty.ClearFragmentShaderReplacement) to illuminate this volume")


class ReplacementSet:
    """The replacements currently installed on one ``vtkShaderProperty``, composed with the
    user's own (:func:`compose_with_user`); :meth:`clear` puts the user's back exactly."""

    def __init__(self, shader_property: vtk.vtkShaderProperty) -> None:
        self.shader_property = shader_property
        #: Ours, as asked for (before composing with the user's).
        self.installed: dict[Key, str] = {}
        #: What we wrote to the property, per key.
        self._written: dict[Key, Value] = {}
        #: The user's replacements we composed with (and so overwrote), per key.
        self._users: dict[Key, Value] = {}
        self._mtime = -1

    def user_replacements(self) -> dict[Key, Value]:
        """The user's fragment replacements: those on the property we did not write, and
        those we composed ours with."""
        current = fragment_replacements(self.shader_property)
        users = {k: v for k, v in current.items() if self._written.get(k) != v}
        for key, value in self._users.items():
            if current.get(key) == self._written.get(key):  # still ours there: theirs inside
                users[key] = value
        return users

    def compose(self, replacements: dict[Key, str]) -> dict[Key, Value]:
        """``replacements`` composed with the user's (``ShaderConflictError`` if they
        cannot be)."""
        users = self.user_replacements()
        return {k: compose_with_user(k, text, users.get(k)) for k, text in replacements.items()}

    def install(self, replacements: dict[Key, str]) -> bool:
        """Install ``replacements``, removing ours that are no longer wanted.

        Returns True when anything changed (the program will be rebuilt).
        """
        sp = self.shader_property
        if replacements == self.installed and sp.GetMTime() == self._mtime:
            return False
        users = self.user_replacements()
        composed = {k: compose_with_user(k, text, users.get(k))
                    for k, text in replacements.items()}
        current = fragment_replacements(sp)
        changed = False
        for key in self._written:
            if key not in composed and current.get(key) == self._written[key]:
                self._put_back(key, users.get(key))
                changed = True
        for (tag, phase), (text, every) in composed.items():
            if current.get((tag, phase)) != (text, every):
                sp.AddFragmentShaderReplacement(tag, phase == "pre", text, every)
                changed = True
        self._users = {k: users[k] for k in composed if k in users}
        self._written = composed
        self.installed = dict(replacements)
        self._mtime = sp.GetMTime()
        return changed

    def _put_back(self, key: Key, user: Value | None) -> None:
        tag, phase = key
        self.shader_property.ClearFragmentShaderReplacement(tag, phase == "pre")
        if user is not None:
            self.shader_property.AddFragmentShaderReplacement(tag, phase == "pre", *user)

    def clear(self) -> None:
        """Remove ours; the user's replacements we composed with are put back as they were."""
        self.install({})
