"""The shader builder: which GLSL sections and literal-line replacements make up a build.

One service of the technique host. From the technique's sections and the volume's state (slice
weights, corrected interpolation, multi-channel sampling and lighting, empty-space skipping,
the lighting model) it composes the replacements VTK's ray caster takes, and says what the
shader VTK then builds must contain: every section's marker, the result of every literal-line
replacement (VTK's multi-channel loop lines, the sampler retyping of bound textures) and every
technique uniform. :func:`verify` checks a built source against that, so a VTK whose shader
lacks a tag or spells a replaced line differently fails loudly instead of silently dropping the
feature. VTK's counterpart is ``vtkVolumeShaderComposer.h``.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import vtk

from vtkvol.engine import shaders
from vtkvol.engine.adaptive_sampling import STEP_FACTOR
from vtkvol.engine.bindings import technique_uniform_values
from vtkvol.engine.precompute import no_collection
from vtkvol.engine.preintegration import TABLE_SIZE

if TYPE_CHECKING:
    from vtkvol.engine.technique import Technique

#: GLSL hooks a technique may define; the host supplies defaults for the others
#: (resources/shaders/host_hooks.glsl).
HOOKS: dict[str, str] = {
    "vv_light_visibility": "VV_HAS_LIGHT_VISIBILITY",
    "vv_light_transmittance_rgb": "VV_HAS_LIGHT_TRANSMITTANCE_RGB",
    "vv_ambient_visibility": "VV_HAS_AMBIENT_VISIBILITY",
    "vv_irradiance": "VV_HAS_IRRADIANCE",
}


_HOOK_DEFINITION = re.compile(r"\b(?:float|vec3)\s+(vv_\w+)\s*\(")


#: Lines of VTK 9.7's independent-component composite loop (post replacements, see
#: host_multichannel.glsl): the classification loop's body becomes one vv_mcClassify call.
_MULTICHANNEL_LINES = {
    "float totalAlpha = 0.0;":
        "float totalAlpha = 0.0;\n      vv_mcClassify(scalar, color, totalAlpha);",
    "color[i][3] = computeOpacity(scalar, i);": "",
    "color[i] = computeColor(scalar, color[i][3], i);": "",
    "totalAlpha += color[i][3] * in_componentWeight[i];": "",
}


#: VTK 9.7's colour-table fetch of one component (computeColor) and what pre-integrated
#: classification puts there (host_preintegration.glsl).
_COLOR_FETCH = "texture2D(in_colorTransferFunc_0[0],"
_PI_COLOR_FETCH = "vv_piColorTex(in_colorTransferFunc_0[0],"
#: The same for component ``c`` of independent components (VTK 9.7 spells the fetch over two
#: lines, the first ending in twelve spaces): the component's index goes in front.
_COLOR_FETCH_COMPONENT = "texture2D(            \n      in_colorTransferFunc_0[{c}],"
_PI_COLOR_FETCH_COMPONENT = "vv_piColorTex({c},            \n      in_colorTransferFunc_0[{c}],"


@functools.lru_cache(maxsize=64)
def _defined_functions(codes: tuple[str, ...]) -> frozenset[str]:
    """The ``vv_`` functions a technique's GLSL defines (asked every frame; parsed once)."""
    return frozenset(m for code in codes for m in _HOOK_DEFINITION.findall(code))


@dataclass(frozen=True)
class ShaderBuild:
    """One build: what to install and what the built fragment shader must then hold."""

    #: ``{(VTK tag or literal line, phase): text}`` for :class:`shaders.ReplacementSet`.
    replacements: dict[tuple[str, shaders.Phase], str]
    #: One marker comment per section (``shaders.marker``): a missing one = a missing VTK tag.
    expected_markers: frozenset[str]
    #: Results of literal-line replacements that must appear in the built source.
    expected_lines: frozenset[str]
    #: Literal VTK lines that a replacement removes: still present = the replacement missed.
    absent_lines: frozenset[str]
    #: Technique uniforms the source must read (declared and used: two mentions at least).
    expected_uniforms: frozenset[str]


def source_observer(on_source: Callable[[str], None]) -> Callable[..., None]:
    """Observer for the mapper's UpdateShaderEvent, whose call data is the bound
    vtkShaderProgram: ``on_source`` gets its fragment source. The event does not fire on the
    frame a program is (re)built (docs/architecture.md, "Engine"), only on the frames after:
    the first of those checks the build."""

    @vtk.calldata_type(vtk.VTK_OBJECT)
    def capture(_mapper: Any, _event: str, program: Any = None) -> None:
        if program is not None:
            with no_collection():
                on_source(program.GetFragmentShader().GetSource())

    return capture


def verify(build: ShaderBuild, source: str) -> str | None:
    """Why ``source`` (the fragment shader VTK built) does not carry ``build`` (a sentence for
    the host's failure message), or None when it does."""
    missing = sorted(m for m in build.expected_markers if m not in source)
    if missing:
        return f"targets a VTK shader tag this VTK does not have ({', '.join(missing)})"
    lines = sorted(line for line in build.expected_lines if line not in source)
    lines += sorted(line for line in build.absent_lines if line in source)
    if lines:
        return ("replaces a VTK shader line this VTK spells differently "
                f"({'; '.join(lines)})")
    unused = sorted(u for u in build.expected_uniforms
                    if len(re.findall(rf"\b{u}\b", source)) < 2)
    if unused:
        return f"sets uniforms its shader never reads ({', '.join(unused)})"
    return None


class ShaderBuilder:
    """Composes the host's and the technique's GLSL for one illuminated volume.

    ``host`` supplies the volume, its image and the state the build depends on (slice weights,
    interpolation, multi-channel settings, bound textures, empty-space statistics). The builder
    also installs its builds on the volume's shader property, checks them on the source VTK
    then builds, and sets the property's shading flags for the lighting model (restored on
    :meth:`restore_shade`)."""

    def __init__(self, host: Any) -> None:
        self._host = host
        #: What the last build did with multi-channel lighting (multichannel_lighting_state).
        self.mc_lighting_state = "per_channel"
        #: Our replacements, composed with the user's on the volume's shader property.
        self.replacements = shaders.ReplacementSet(host.volume.GetShaderProperty())
        #: The last fragment shader VTK built with our replacements (tests, diagnostics).
        self.fragment_source = ""
        self._expected: ShaderBuild | None = None  # installed, not yet seen built
        prop = host.volume.GetProperty()
        self._user_shade = [prop.GetShade(c) for c in range(4)]

    # -- installation ----------------------------------------------------------------------------
    def install(self, tech: Technique, values: Mapping[str, Any]) -> None:
        """:meth:`build` and install; a build that changed the replacements is checked on the
        next source VTK builds (:meth:`built`)."""
        build = self.build(tech, values)
        if self.replacements.install(build.replacements):
            self._expected = build

    def built(self, source: str) -> str | None:
        """The fragment ``source`` VTK built: remembered, and checked against the last
        installed build (:func:`verify`). Returns why it lacks part of that build, else None."""
        self.fragment_source = source
        pending, self._expected = self._expected, None
        return None if pending is None else verify(pending, source)

    def clear(self) -> None:
        """Remove our replacements (VTK builds its own shader again; nothing is checked)."""
        self.replacements.clear()
        self._expected = None

    def apply_shade(self, *, keep_user: bool) -> None:
        """Shading flags for the method's lighting model (``keep_user``: the user's)."""
        # surface: VTK's shaded variant computes the gradient we shade with; medium: the
        # unshaded variant skips it (the medium model uses no gradient).
        prop = self._host.volume.GetProperty()
        shade = 1 if self._host.spec.lighting == "surface" else 0
        for c in range(4):
            prop.SetShade(c, self._user_shade[c] if keep_user else shade)

    def restore_shade(self) -> None:
        """The user's shading flags as they were before the host changed them."""
        self.apply_shade(keep_user=True)

    def build(self, tech: Technique, values: Mapping[str, Any]) -> ShaderBuild:
        """The replacements that install ``tech`` (with ``values``) and the host's sections for
        the volume's current state, and what the built shader must then contain."""
        sections = shaders.load("host_prelude.glsl")
        preintegrated = self._host.preintegration.active
        pi_channels = self._host.preintegration.channels() if preintegrated else 1
        if preintegrated:
            # Innermost computeOpacity: before the slice weights and the corrected filter.
            pi_defines = {"VV_PI_SIZE": f"{float(TABLE_SIZE):.1f}",
                          "VV_PI_CHANNELS": str(pi_channels)}
            if pi_channels > 1:
                pi_defines["VV_INDEPENDENT"] = "1"
            sections += shaders.load("host_preintegration.glsl", pi_defines)
        if self._host._weights is not None:
            img = self._host.image
            ncomp = img.GetPointData().GetScalars().GetNumberOfComponents()
            prop = self._host.volume.GetProperty()
            independent = ncomp > 1 and bool(prop.GetIndependentComponents())
            sections += shaders.load(
                "host_slice_weights.glsl", {"VV_INDEPENDENT": "1"} if independent else None
            )
        interpolation = self.interpolation_sections()
        sections += interpolation
        multichannel, shared_lighting = self._multichannel_sections(
            shares_gradient=any("#define VV_IP_SHARE_GRADIENT" in s.code for s in interpolation),
            lighting=tech.SPEC.lighting)
        sections += multichannel
        if self._host.empty_space.stats.get("active"):
            bz, by, bx = self._host.empty_space.stats["brick_voxels_zyx"]
            sections += shaders.load("host_empty_space.glsl", {
                "VV_ESS_BRICK": f"vec3({float(bx):.1f}, {float(by):.1f}, {float(bz):.1f})"})
        if self._host.adaptive_sampling.active:
            bz, by, bx = self._host.adaptive_sampling.stats["brick_voxels_zyx"]
            sections += shaders.load("host_adaptive.glsl", {
                "VV_AS_BRICK": f"vec3({float(bx):.1f}, {float(by):.1f}, {float(bz):.1f})",
                "VV_AS_FACTOR": f"{float(STEP_FACTOR):.1f}"})
        own = tech.sections(values)
        defined = _defined_functions(tuple(s.code for s in own))
        hooks = {define: "1" for hook, define in HOOKS.items() if hook in defined}
        if tech.SPEC.has("rgb") != ("vv_light_transmittance_rgb" in defined):
            # The capability is what the dock and the benchmark read; it must not lie.
            raise ValueError(
                f"technique {tech.NAME!r}: declaring the 'rgb' capability and defining "
                "vv_light_transmittance_rgb go together"
            )
        sections += own
        lighting = {"surface": "host_lighting.glsl", "medium": "host_medium.glsl"}[
            tech.SPEC.lighting
        ]
        if self.shaded() or (tech.SPEC.lighting == "medium" and self.compositing()):
            sections += shaders.load("host_hooks.glsl", hooks)
            # Multi-channel, shaded surface lighting per channel: one transmittance per light
            # and sample (shared lighting evaluates the lights once anyway).
            share_light = (bool(multichannel) and not shared_lighting and self.shaded()
                           and tech.SPEC.lighting == "surface")
            sections += shaders.load(lighting, {"VV_MC_SHARE_LIGHT": "1"} if share_light
                                     else None)
        replacements = shaders.compose(sections)
        if multichannel:
            # VTK's classification loop: its body moves to vv_mcClassify (constant component
            # indices), called where the loop starts; the emptied loop compiles away.
            for line, text in _MULTICHANNEL_LINES.items():
                replacements[(line, "post")] = text
        expected_lines: set[str] = set()
        absent_lines: set[str] = set()
        if multichannel:
            for line, text in _MULTICHANNEL_LINES.items():
                if text:
                    expected_lines.add(text.splitlines()[-1].strip())
                else:
                    absent_lines.add(line)
        if preintegrated:
            # VTK's colour-table fetch in computeColor reads the segment's colour instead.
            fetches = ([(_COLOR_FETCH, _PI_COLOR_FETCH)] if pi_channels == 1 else
                       [(_COLOR_FETCH_COMPONENT.format(c=c), _PI_COLOR_FETCH_COMPONENT.format(c=c))
                        for c in range(pi_channels)])
            for fetch, replaced in fetches:
                replacements[(fetch, "post")] = replaced
                expected_lines.add(replaced)
                absent_lines.add(fetch)
        for name, (_texture, sampler) in self._host._textures.items():
            replacements[(f"uniform int {name};", "post")] = f"uniform {sampler} {name};"
            expected_lines.add(f"uniform {sampler} {name};")
        return ShaderBuild(
            replacements=replacements,
            expected_markers=frozenset(shaders.marker(s) for s in sections),
            expected_lines=frozenset(expected_lines),
            absent_lines=frozenset(absent_lines),
            expected_uniforms=frozenset(technique_uniform_values(tech, values)),
        )

    def _multichannel_sections(self, *, shares_gradient: bool, lighting: str
                               ) -> tuple[list[shaders.Section], bool]:
        """The multi-channel sample's sections (``host_multichannel.glsl``: VTK's per-component
        work with constant indices, one set of gradient fetches; with shared lighting also
        ``host_multichannel_lighting.glsl``), or none; and whether the lighting is shared.
        For two to four independent components on a composite blend; ``shares_gradient``: the
        corrected trilinear filter already shares its fetches with the gradient; ``lighting``:
        the technique's lighting model."""
        self.mc_lighting_state = "per_channel"
        scalars = self._host.image.GetPointData().GetScalars()
        ncomp = scalars.GetNumberOfComponents() if scalars is not None else 1
        prop = self._host.volume.GetProperty()
        mapper = self._host.volume.GetMapper()
        if not (self._host.multichannel_sample and 2 <= ncomp <= 4
                and prop.GetIndependentComponents()
                and mapper.GetBlendMode() == vtk.vtkVolumeMapper.COMPOSITE_BLEND):
            return [], False
        defines = {"VV_MC_COMPONENTS": str(ncomp)}
        share_gradient = (self.shaded() and not shares_gradient
                          and not any(prop.HasGradientOpacity(c) for c in range(ncomp))
                          and mapper.GetVolumetricScatteringBlending() == 0)
        if share_gradient:
            # As for the corrected filter: VTK's gradient-opacity variant returns a magnitude
            # and its volumetric shadows take gradients away from the sample.
            defines["VV_MC_SHARE_GRADIENT"] = "1"
        why_not = self._why_not_shared_lighting(
            lighting, gradient_shared=share_gradient or shares_gradient)
        if why_not is not None:
            if self._host._multichannel_lighting == "shared":
                self.mc_lighting_state = f"per_channel ({why_not})"
            return shaders.load("host_multichannel.glsl", defines), False
        defines["VV_MC_SHARED_LIGHTING"] = "1"
        self.mc_lighting_state = "shared"
        light_defines = None
        if lighting == "surface":
            light_defines = {"VV_MC_SHARED_NORMAL": "1", "VV_MC_CHANNEL_GRADIENT":
                             "vv_ipGradient" if shares_gradient else "vv_mcGradient"}
        return (shaders.load("host_multichannel.glsl", defines)
                + shaders.load("host_multichannel_lighting.glsl", light_defines), True)

    def _why_not_shared_lighting(self, lighting: str, *, gradient_shared: bool) -> str | None:
        """None when the multi-channel sample lights its channels once (shared lighting asked
        for, and a lit sample whose normal can come from the shared fetches); else why not."""
        if self._host._multichannel_lighting != "shared":
            return "per channel asked for"
        prop = self._host.volume.GetProperty()
        if prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D:
            return "2-D transfer functions colour from the gradient per channel"
        if lighting == "medium":
            return None  # lit on every composited sample, no normal
        if not self.shaded():
            return "unshaded: nothing is lit"
        if not gradient_shared:
            return "gradient opacity or volumetric scattering take gradients per channel"
        return None

    def interpolation_sections(self) -> list[shaders.Section]:
        """The corrected-trilinear filter's sections (after the slice weights: both wrap
        ``computeOpacity``), or none. Only composite blending samples the scalar where the
        wrappers can correct it (MIP and the other blends classify a reduced value)."""
        if self._host._interpolation != "corrected":
            return []
        if self._host.volume.GetMapper().GetBlendMode() != vtk.vtkVolumeMapper.COMPOSITE_BLEND:
            return []
        prop = self._host.volume.GetProperty()
        if prop.GetInterpolationType() == vtk.VTK_NEAREST_INTERPOLATION:
            return []  # the correction assumes trilinear fetches (label data use nearest)
        if prop.GetTransferFunctionMode() == vtk.vtkVolumeProperty.TF_2D:
            # VTK's 2-D colour lookup reads the uncorrected scalar and its own gradient; a
            # corrected opacity beside it would classify one sample two ways.
            return []
        ncomp = self._host.image.GetPointData().GetScalars().GetNumberOfComponents()
        independent = ncomp > 1 and bool(prop.GetIndependentComponents())
        if ncomp > 1 and not independent:
            return []  # dependent components (RGBA data): colour is not a filtered scalar
        defines = {"VV_INDEPENDENT": "1"} if independent else {}
        used = range(ncomp) if independent else range(1)
        mapper = self._host.volume.GetMapper()
        if (self.shaded() and not any(prop.HasGradientOpacity(c) for c in used)
                and mapper.GetVolumetricScatteringBlending() == 0):
            # The shading gradient reuses the correction's six fetches. Not with gradient
            # opacity (VTK's variant returns a magnitude) or VTK's volumetric shadows (they
            # take gradients away from the sample).
            defines["VV_IP_SHARE_GRADIENT"] = "1"
        return shaders.load("host_interpolation.glsl", defines)

    def shaded(self) -> bool:
        """True when VTK generates its shaded ``computeLighting()`` (where the ``surface``
        lighting hooks in): shading on for a used component and a composite or isosurface
        blend. MIP, MinIP, average and additive blends, and unshaded composite, show no
        surface illumination."""
        prop = self._host.volume.GetProperty()
        scalars = self._host.image.GetPointData().GetScalars()
        ncomp = scalars.GetNumberOfComponents() if scalars is not None else 1
        # VTK generates the shaded code when any *used* component is shaded (component 0 for
        # dependent components).
        used = range(ncomp) if prop.GetIndependentComponents() else range(1)
        return self.compositing() and any(prop.GetShade(c) for c in used)

    def compositing(self) -> bool:
        """Composite or isosurface blending (the blends that light samples)."""
        blend = self._host.volume.GetMapper().GetBlendMode()
        return blend in (vtk.vtkVolumeMapper.COMPOSITE_BLEND, vtk.vtkVolumeMapper.ISOSURFACE_BLEND)
