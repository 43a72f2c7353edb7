"""The mechanism every renderer beside VTK's ray caster shares.

A :class:`BesideRenderer` draws the volume itself, in the ``vtkRenderer``'s ``EndEvent``: VTK has
drawn the opaque and translucent geometry by then, its render framebuffer is bound, the viewport
is the renderer's own and the depth buffer holds the opaque depth (measured in
``../shared/reference/seed-audit/renderers.md`` §1.1; a Python ``vtkRenderPass`` is never called
by VTK). Per frame it

1. copies VTK's depth into a texture of its own (a depth blit: it also resolves multisampled
   framebuffers, and needs no GL 4.3 copy);
2. reads the host's classified opacity texture (:meth:`Illuminator.opacity_texture`: 1-D/2-D TF,
   gradient opacity, crop, clipping planes, slice and channel weights) and a colour texture of
   its own, built from the property's colour tables;
3. runs its passes (:meth:`draw`) and composites premultiplied colour over the scene
   (``ONE, ONE_MINUS_SRC_ALPHA``: what VTK's ray caster does), all inside
   ``vtkOpenGLState.Push()``/``Pop()`` with state set only through ``vtkOpenGLState``.

VTK's own volume is hidden (``VisibilityOff``) while a beside-renderer is attached, and a
*bounds proxy* (a box over the volume whose fragment shader discards) keeps the volume in VTK's
visible-prop bounds, so camera resets and the automatic clipping range still see it.

Coordinates: rays are set up in **dataset space** (the image's µm coordinates: the inverse of
the volume's matrix times the inverse composite projection maps NDC to it); voxel centres are at
``origin + i·spacing``; the opacity texture holds opacity per ``unit_distance`` µm.
"""

from __future__ import annotations

import logging
import time
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import vtk

from vtkvol.engine.gl import ComputeProgram, Texture2D, Texture3D, gl
from vtkvol.engine.opacity_source import gradient_opacity_on
from vtkvol.engine.precompute import no_collection as _no_collection
from vtkvol.model.renderers import unsupported_reason

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Illuminator

logger = logging.getLogger(__name__)

#: Observer priority of the pass: below VTK's default (0.0) so other EndEvent observers that
#: read the frame (screenshots, timing) see the volume drawn.
END_PRIORITY = 1.0

#: Entries of the post-classification tables (VTK samples a TF into at least this many).
TABLE_SIZE = 1024
#: Defines that switch the shared GLSL to post-classification (inserted after the version).
POST_DEFINES = f"#define VV_POST\n#define TABLE_SIZE {TABLE_SIZE}.0\n"

#: GLSL shared by every beside-renderer: dataset-space rays, the box, the classified medium.
COMMON_GLSL = """
uniform mat4 ndcToData;        // NDC -> dataset µm (column-major)
uniform vec3 dOrigin;          // µm, first voxel centre
uniform vec3 dSpacing;         // µm per voxel
uniform vec3 dims;             // voxels (nx, ny, nz)
uniform float unitDistance;    // µm the opacity texture's alpha refers to
uniform vec4 viewport;         // renderer's viewport in window pixels (x, y, w, h)
uniform sampler2D depthTex;    // VTK's opaque depth, whole window
vec3 toTex(vec3 p) { return ((p - dOrigin) / dSpacing + 0.5) / dims; }
#ifdef VV_POST
// Post-classified, as VTK's ray caster: the scalar is interpolated, then looked up.
uniform sampler3D opacityTex;  // r32f scalar, 0..1 over the transfer-function table's range
uniform sampler2D tableTex;    // 4 rows of TABLE_SIZE: opacity per unit distance, r, g, b
float tableAt(float s, float row) {
  return texture(tableTex, vec2((clamp(s, 0.0, 1.0) * (TABLE_SIZE - 1.0) + 0.5) / TABLE_SIZE,
                                (row + 0.5) / 4.0)).r;
}
float alphaAt(vec3 p) { return tableAt(texture(opacityTex, toTex(p)).r, 0.0); }
vec3 colourAt(vec3 p) {
  float s = texture(opacityTex, toTex(p)).r;
  return vec3(tableAt(s, 1.0), tableAt(s, 2.0), tableAt(s, 3.0));
}
#else
// Pre-classified: the host's classified opacity and our colour per voxel, interpolated.
uniform sampler3D opacityTex;  // host's r32f opacity per unit distance
uniform sampler3D colourTex;   // rgba32f TF colour per voxel (opacity-weighted channel mix)
float alphaAt(vec3 p) { return texture(opacityTex, toTex(p)).r; }
vec3 colourAt(vec3 p) { return texture(colourTex, toTex(p)).rgb; }
#endif
// Extinction per µm.
float sigmaAt(vec3 p) { return -log(max(1.0 - alphaAt(p), 1e-6)) / unitDistance; }
vec3 unproject(vec3 ndc) { vec4 q = ndcToData * vec4(ndc, 1.0); return q.xyz / q.w; }
// Ray parameters where o + t d is inside the voxel-centre box [origin, origin + (dims-1) spacing].
bool boxHit(vec3 o, vec3 d, out float t0, out float t1) {
  vec3 inv = 1.0 / d;
  vec3 lo = dOrigin, hi = dOrigin + (dims - 1.0) * dSpacing;
  vec3 ta = (lo - o) * inv, tb = (hi - o) * inv;
  t0 = max(max(min(ta.x, tb.x), min(ta.y, tb.y)), min(ta.z, tb.z));
  t1 = min(min(max(ta.x, tb.x), max(ta.y, tb.y)), max(ta.z, tb.z));
  t0 = max(t0, 0.0);
  return t1 > t0;
}
// The camera ray through window pixel position `frag` (window pixels), clipped to the box and
// to VTK's opaque depth. Returns false when it misses the volume.
bool cameraRay(vec2 frag, ivec2 depthPixel, out vec3 o, out vec3 d, out float t0, out float t1) {
  vec2 ndc = 2.0 * (frag - viewport.xy) / viewport.zw - 1.0;
  o = unproject(vec3(ndc, -1.0));
  d = normalize(unproject(vec3(ndc, 1.0)) - o);
  if (!boxHit(o, d, t0, t1)) return false;
  float z = texelFetch(depthTex, depthPixel, 0).r;
  if (z < 1.0) t1 = min(t1, dot(unproject(vec3(ndc, 2.0 * z - 1.0)) - o, d));
  return t1 > t0;
}
"""

COMPOSITE_FS = """//VTK::System::Dec
in vec2 texCoord;
uniform sampler2D resultTex;  // premultiplied RGBA (sum over frames)
uniform vec4 viewport;
uniform float scale;          // 1 / frames
//VTK::Output::Dec
void main() {
  if (texCoord.x < -1.0) discard;  // keeps the quad helper's texCoordIn attribute alive
  gl_FragData[0] = texelFetch(resultTex, ivec2(gl_FragCoord.xy - viewport.xy), 0) * scale;
}
"""


def quad_program(render_window: vtk.vtkRenderWindow, fragment: str
                 ) -> tuple[vtk.vtkOpenGLQuadHelper, vtk.vtkShaderProgram]:
    """A full-screen quad with ``fragment`` as its fragment shader, and its program.

    VTK 9.7 wraps the helper's constructor and ``Render()`` but not its ``Program`` member; the
    helper binds its program while it is built, so the shader cache's last bound program is it
    (checked: compiled and carrying our source)."""
    quad = vtk.vtkOpenGLQuadHelper(render_window, None, fragment, "")
    prog = render_window.GetShaderCache().GetLastShaderBound()
    if prog is None or not prog.GetCompiled():
        error = prog.GetError() if prog is not None else "no program bound"
        raise RuntimeError(f"vtkvol: a renderer's quad shader failed to build: {error}")
    if fragment.split("\n", 2)[1] not in prog.GetFragmentShader().GetSource():
        raise RuntimeError("vtkvol: VTK's quad helper did not leave its program bound")
    return quad, prog


def colour_volume(volume: vtk.vtkVolume, image: vtk.vtkImageData) -> np.ndarray:
    """TF colour per voxel, ``[z, y, x, 4]`` float32 (alpha channel 1).

    One channel: the colour function at the voxel's value. Independent channels: the channels'
    colours weighted by their opacity × component weight (how VTK mixes independent components
    before compositing); where no channel is opaque, their plain mean."""
    from vtk.util.numpy_support import vtk_to_numpy

    prop = volume.GetProperty()
    nx, ny, nz = image.GetDimensions()
    scalars = image.GetPointData().GetScalars()
    values = vtk_to_numpy(scalars).reshape(nz, ny, nx, -1).astype(np.float32)
    ncomp = values.shape[-1]
    rgb = np.zeros((nz, ny, nx, 3), np.float32)
    weight = np.zeros((nz, ny, nx), np.float32)
    plain = np.zeros_like(rgb)
    for c in range(ncomp):
        lo, hi = scalars.GetRange(c)
        col = _table(prop.GetRGBTransferFunction(c), lo, hi, values[..., c], rgb=True)
        plain += col
        if ncomp == 1:
            rgb[:] = col
            weight[:] = 1.0
            break
        a = _table(prop.GetScalarOpacity(c), lo, hi, values[..., c], rgb=False)
        w = np.clip(a, 0, 1) * prop.GetComponentWeight(c)
        rgb += col * w[..., None]
        weight += w
    out = np.ones((nz, ny, nx, 4), np.float32)
    nonzero = weight > 1e-12
    out[..., :3] = plain / ncomp
    out[nonzero, :3] = rgb[nonzero] / weight[nonzero, None]
    return out


def _table(function: Any, lo: float, hi: float, values: np.ndarray, *, rgb: bool) -> np.ndarray:
    """``function`` at ``values`` through a 1024-entry table over [lo, hi] (VTK's own sampling
    of the TF for the ray caster)."""
    n = 1024
    hi = hi if hi > lo else lo + 1.0
    xs = np.linspace(lo, hi, n)
    table = np.array([function.GetColor(v) for v in xs] if rgb
                     else [[function.GetValue(v)] for v in xs], np.float32)
    pos = np.clip((values - lo) / (hi - lo) * (n - 1), 0, n - 1)
    i0 = np.floor(pos).astype(np.int64)
    i1 = np.minimum(i0 + 1, n - 1)
    f = (pos - i0)[..., None]
    out = table[i0] * (1 - f) + table[i1] * f
    return out if rgb else out[..., 0]


class BesideRenderer:
    """Base of the renderers that draw the volume themselves after VTK's opaque geometry.

    Subclasses implement :meth:`draw` (their passes, writing the premultiplied image into
    :attr:`result`, an RGBA32F texture of the renderer's size, and returning the divisor the
    composite applies) and may override :meth:`reset`.

    Attributes ``iteration`` (frames accumulated since the last reset) and ``converged`` follow
    the host's progressive-technique contract: :meth:`Illuminator.converge`,
    :attr:`Illuminator.wants_frame` and ``on_progress`` see them.
    """

    NAME: ClassVar[str] = ""
    #: Whether a camera move restarts the accumulation (every renderer here is view-dependent).
    PROGRESSIVE: ClassVar[bool] = False

    def __init__(self, host: Illuminator) -> None:
        self.host = host
        self.renderer: vtk.vtkRenderer = host.renderer
        self.volume: vtk.vtkVolume = host.volume
        self.iteration = 0
        self.target_iterations = 1
        self.last_pass_ms = 0.0
        self.last_error: str | None = None
        self._window: vtk.vtkRenderWindow | None = None
        self._quad: Any = None
        self._composite: Any = None
        self._depth: Any = None  # vtkTextureObject, DEPTH_COMPONENT32, window-sized
        self._depth_fbo: Any = None
        self.result: Any = None  # vtkTextureObject RGBA32F, renderer-sized
        self._colour: Texture3D | None = None
        self._colour_key: tuple | None = None
        #: The compute renderers' frame program (:meth:`medium_program`) and whether it was
        #: built for post-classification.
        self._program: ComputeProgram | None = None
        self._program_post = False
        self._post: tuple[Texture3D, Texture2D] | None = None
        self._post_key_value: tuple | None = None
        self.post_table: np.ndarray | None = None
        self.post_scalars: np.ndarray | None = None
        #: Why the last frame classified before interpolation (None: after, as VTK does).
        self.classification_reason: str | None = None
        self._view_key: tuple | None = None
        self._content_key: tuple | None = None
        self._was_visible = bool(self.volume.GetVisibility())
        self.volume.VisibilityOff()
        self._proxy = self._bounds_proxy()
        self.renderer.AddActor(self._proxy)
        self._tag = self.renderer.AddObserver(vtk.vtkCommand.EndEvent, self._on_end,
                                              END_PRIORITY)

    # -- progressive contract -------------------------------------------------------------------
    @property
    def converged(self) -> bool:
        """Enough frames accumulated (or failed: nothing more to refine)."""
        return self.iteration >= self.target_iterations or self.last_error is not None

    def reset(self) -> None:
        """Restart the accumulation (next frame overwrites)."""
        self.iteration = 0

    # -- subclass API ---------------------------------------------------------------------------
    def draw(self, opacity: Texture3D, uniforms: dict[str, Any]) -> float | None:
        """Run the passes into :attr:`result` and return the composite's scale (1 / frames),
        or composite over the scene directly and return None."""
        raise NotImplementedError

    # -- frame ----------------------------------------------------------------------------------
    def _bounds_proxy(self) -> vtk.vtkActor:
        """A box over the volume's bounds that draws nothing (discarded fragments): VTK's
        bounds, camera reset and automatic clipping range go on seeing the hidden volume."""
        self._cube = vtk.vtkCubeSource()
        mapper = vtk.vtkPolyDataMapper()
        mapper.SetInputConnection(self._cube.GetOutputPort())
        actor = vtk.vtkActor()
        actor.SetMapper(mapper)
        actor.PickableOff()
        actor.GetShaderProperty().AddFragmentShaderReplacement(
            "//VTK::UniformFlow::Impl", True, "discard;", False)
        self._update_proxy(actor)
        return actor

    def _update_proxy(self, actor: vtk.vtkActor | None = None) -> None:
        actor = actor or self._proxy
        b = self.volume.GetBounds()  # world bounds (hidden volumes still report them)
        self._cube.SetBounds(b)
        actor.SetVisibility(bool(self._was_visible))

    def _uniform_base(self, window: vtk.vtkRenderWindow) -> dict[str, Any]:
        img = self.host.image
        cam = self.renderer.GetActiveCamera()
        m = cam.GetCompositeProjectionTransformMatrix(self.renderer.GetTiledAspectRatio(), -1, 1)
        comp = np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)])
        vm = self.volume.GetMatrix()
        vol = np.array([[vm.GetElement(i, j) for j in range(4)] for i in range(4)])
        ndc_to_data = np.linalg.inv(vol) @ np.linalg.inv(comp)
        x0, y0, _x1, _y1 = self.renderer.GetViewport()
        w, h = window.GetSize()
        vp = [float(round(x0 * w)), float(round(y0 * h)), *(float(s) for s in
                                                             self.renderer.GetSize())]
        return {
            "ndcToData": ndc_to_data,
            "dOrigin": tuple(float(v) for v in img.GetOrigin()),
            "dSpacing": tuple(float(v) for v in img.GetSpacing()),
            "dims": tuple(float(v) for v in img.GetDimensions()),
            "unitDistance": float(self.host.unit_distance),
            "viewport": vp,
        }

    def view_signature(self) -> tuple:
        """Camera and renderer size: a change restarts a progressive renderer."""
        cam = self.renderer.GetActiveCamera()
        return (tuple(cam.GetPosition()), tuple(cam.GetFocalPoint()), tuple(cam.GetViewUp()),
                cam.GetViewAngle(), cam.GetParallelProjection(), cam.GetParallelScale(),
                tuple(self.renderer.GetSize()), tuple(self.renderer.GetViewport()))

    def content_signature(self) -> tuple:
        """Data, TF (opacity and colour), crop, clipping, weights, lights, material, exposure,
        fill and the renderer's own settings: a change restarts every renderer."""
        prop = self.volume.GetProperty()
        return (self.host.opacity_signature(), self._colour_signature(),
                tuple(self.host.light_specs()), self.host.albedo, self.host.phase_g,
                self.host.exposure, self.host.fill, prop.GetMTime(), self.settings_signature())

    def settings_signature(self) -> tuple:
        return ()

    def _colour_signature(self) -> tuple:
        prop = self.volume.GetProperty()
        img = self.host.image
        n = img.GetPointData().GetScalars().GetNumberOfComponents()
        return (img.GetMTime(), tuple(prop.GetRGBTransferFunction(c).GetMTime()
                                      for c in range(n)))

    def _colour_texture(self, window: vtk.vtkRenderWindow) -> Texture3D:
        key = (*self._colour_signature(), self.host.opacity_signature())
        if self._colour is None or key != self._colour_key:
            data = colour_volume(self.volume, self.host.image)
            if self._colour is not None and self._colour.shape == data.shape[:3]:
                self._colour.upload(data)
            else:
                if self._colour is not None:
                    self._colour.release()
                self._colour = Texture3D(window, data.shape[:3], data=data, channels=4)
            self._colour.tex.Deactivate()
            self._colour_key = key
        return self._colour

    # -- classification -------------------------------------------------------------------------
    def post_classification_reason(self) -> str | None:
        """Why the medium is classified before interpolation (the host's opacity texture), or
        None: classified after it, as VTK's ray caster does (the scalar interpolated, then the
        TF looked up), which needs one channel, a 1-D TF without gradient opacity, and no crop,
        clipping plane or slice weights (those live in the host's texture only). With a
        sharp TF the two differ by ~10 levels at the edges (docs/architecture.md)."""
        prop = self.volume.GetProperty()
        mapper = self.volume.GetMapper()
        scalars = self.host.image.GetPointData().GetScalars()
        if scalars is None or scalars.GetNumberOfComponents() != 1:
            return "more than one channel"
        if prop.GetTransferFunctionMode() != vtk.vtkVolumeProperty.TF_1D:
            return "a 2-D transfer function"
        if gradient_opacity_on(prop, 0):
            return "gradient opacity"
        if mapper.GetCropping():
            return "cropping"
        planes = mapper.GetClippingPlanes()
        if planes is not None and planes.GetNumberOfItems() > 0:
            return "clipping planes"
        if self.host.slice_weights is not None:
            return "slice weights"
        return None

    def _post_key(self) -> tuple:
        prop = self.volume.GetProperty()
        img = self.host.image
        return (img.GetMTime(), prop.GetScalarOpacity(0).GetMTime(),
                prop.GetRGBTransferFunction(0).GetMTime(), prop.GetScalarOpacityUnitDistance(0))

    def _post_textures(self, window: vtk.vtkRenderWindow) -> tuple[Texture3D, Texture2D]:
        """(scalar texture normalised to the table range, 4 × TABLE_SIZE table texture)."""
        key = self._post_key()
        if self._post is not None and self._post_key_value == key:
            return self._post
        from vtk.util.numpy_support import vtk_to_numpy

        img = self.host.image
        scalars = img.GetPointData().GetScalars()
        lo, hi = scalars.GetRange(0)
        hi = hi if hi > lo else lo + 1.0
        nx, ny, nz = img.GetDimensions()
        values = vtk_to_numpy(scalars).reshape(nz, ny, nx).astype(np.float32)
        normalised = (values - np.float32(lo)) / np.float32(hi - lo)
        prop = self.volume.GetProperty()
        xs = np.linspace(lo, hi, TABLE_SIZE)
        table = np.empty((4, TABLE_SIZE), np.float32)
        table[0] = [prop.GetScalarOpacity(0).GetValue(v) for v in xs]
        table[1:] = np.array([prop.GetRGBTransferFunction(0).GetColor(v) for v in xs]).T
        self._release_post()
        scalar_tex = Texture3D(window, (nz, ny, nx), data=normalised)
        scalar_tex.tex.Deactivate()
        table_tex = Texture2D(window, table)
        table_tex.tex.Deactivate()
        self._post = (scalar_tex, table_tex)
        self._post_key_value = key
        self.post_table = table
        self.post_scalars = normalised
        return self._post

    def _release_post(self) -> None:
        if self._post is not None:
            for t in self._post:
                t.release()
            self._post = None
            self._post_key_value = None

    def medium_textures(self, window: vtk.vtkRenderWindow, opacity: Texture3D
                        ) -> tuple[bool, Texture3D, Any]:
        """(post-classified?, the texture for ``opacityTex``, the colour input: the table
        (post) or the colour volume (pre))."""
        self.classification_reason = self.post_classification_reason()
        if self.classification_reason is None:
            scalar_tex, table_tex = self._post_textures(window)
            return True, scalar_tex, table_tex
        return False, opacity, self._colour_texture(window)

    def medium_program(self, window: vtk.vtkRenderWindow, post: bool, source: str,
                       label: str) -> ComputeProgram:
        """The compute renderers' frame program: ``source`` (GLSL 430) compiled with
        :data:`POST_DEFINES` when ``post`` (see :meth:`medium_textures`), rebuilt when that
        changes; it is used and released by the caller's frame (:meth:`_end_frame`)."""
        if self._program is None or self._program_post != post:
            if self._program is not None:
                self._program.release()
            text = source.replace("#version 430\n", "#version 430\n" + POST_DEFINES, 1
                                  ) if post else source
            self._program = ComputeProgram(window, text, label)
            self._program_post = post
        return self._program

    def _end_frame(self, *textures: Any) -> float:
        """After a compute renderer's dispatches: ``textures`` (``Texture3D`` or the post
        table) deactivated, the program done, one more frame counted; the new frame's weight
        in the running mean (1/iteration)."""
        for texture in textures:
            texture.tex.Deactivate()
        assert self._program is not None
        self._program.done()
        self.iteration += 1
        return 1.0 / self.iteration

    def _ensure_buffers(self, window: vtk.vtkRenderWindow) -> None:
        if self._quad is None:
            self._quad, self._composite = quad_program(window, COMPOSITE_FS)
        W, H = window.GetSize()
        if self._depth is None or (self._depth.GetWidth(), self._depth.GetHeight()) != (W, H):
            self._release_depth()
            self._depth = vtk.vtkTextureObject()
            self._depth.SetContext(window)
            self._depth.AllocateDepth(W, H, vtk.vtkTextureObject.Fixed32)
            self._depth_fbo = vtk.vtkOpenGLFramebufferObject()
            self._depth_fbo.SetContext(window)
            state = window.GetState()
            state.PushFramebufferBindings()
            self._depth_fbo.Bind()
            self._depth_fbo.AddDepthAttachment(self._depth)
            state.PopFramebufferBindings()
        w, h = self.renderer.GetSize()
        if self.result is None or (self.result.GetWidth(), self.result.GetHeight()) != (w, h):
            if self.result is not None:
                self.result.ReleaseGraphicsResources(window)
            self.result = vtk.vtkTextureObject()
            self.result.SetContext(window)
            self.result.Allocate2D(max(1, w), max(1, h), 4, vtk.VTK_FLOAT)  # GL_RGBA32F
            self.reset()

    def _copy_depth(self, window: vtk.vtkRenderWindow) -> None:
        """VTK's render-framebuffer depth into our texture (a blit also resolves MSAA)."""
        G = gl(window)
        W, H = window.GetSize()
        state = window.GetState()
        state.PushFramebufferBindings()
        state.vtkglBindFramebuffer(G.GL_READ_FRAMEBUFFER,
                                   window.GetRenderFramebuffer().GetFBOIndex())
        state.vtkglBindFramebuffer(G.GL_DRAW_FRAMEBUFFER, self._depth_fbo.GetFBOIndex())
        state.vtkglBlitFramebuffer(0, 0, W, H, 0, 0, W, H, G.GL_DEPTH_BUFFER_BIT, G.GL_NEAREST)
        state.PopFramebufferBindings()

    def _on_end(self, _renderer: Any, _event: str) -> None:
        host = self.host
        if host.closed or self.renderer.GetRenderWindow() is None:
            return
        window = self.renderer.GetRenderWindow()
        self._window = window
        w, h = self.renderer.GetSize()
        if w < 1 or h < 1 or host.render_window is None:
            return
        if self.last_error is not None:
            return
        t0 = time.perf_counter()
        try:
            # No cyclic GC inside VTK's render: collecting a forgotten render window here
            # leaves no context current (the host guards its StartEvent the same way).
            with _no_collection():
                self._frame(window)
        except Exception as exc:  # a GL failure must not take the view down: stop drawing
            logger.exception("the %s renderer failed", self.NAME)
            self.last_error = f"vtkvol: the {self.NAME} renderer failed ({exc})"
            if self.host.on_error is not None:
                self.host.on_error(self.last_error)
            return
        self.last_pass_ms = (time.perf_counter() - t0) * 1e3

    def _frame(self, window: vtk.vtkRenderWindow) -> None:
        try:  # the host's method, blend mode or lights may have changed since attach
            check_renderer(self.host, self.NAME)
        except ValueError as exc:
            # Never draw a combination this renderer does not support: hand the volume back
            # to VTK's ray caster (from the next frame on) and say why.
            self.last_error = str(exc)
            if self.host.on_error is not None:
                self.host.on_error(self.last_error)
            if self.host.beside is self:
                self.host.beside = None
            self.release()
            return
        self._update_proxy()
        self._ensure_buffers(window)
        view, content = self.view_signature(), self.content_signature()
        if content != self._content_key or (self.PROGRESSIVE and view != self._view_key):
            self.reset()
        self._view_key, self._content_key = view, content
        if not self.volume.GetMapper() or not self._was_visible:
            return
        self._copy_depth(window)
        opacity = self.host.opacity_texture()
        uniforms = self._uniform_base(window)
        scale = self.draw(opacity, uniforms)
        if scale is not None:  # None: the renderer composited over the scene itself
            self._composite_result(window, uniforms["viewport"], scale)
        if self.PROGRESSIVE and self.host.on_progress is not None:
            self.host.on_progress(self.iteration, self.converged)

    def _composite_result(self, window: vtk.vtkRenderWindow, viewport: list[float],
                          scale: float) -> None:
        state = window.GetState()
        state.Push()
        try:
            window.GetShaderCache().ReadyShaderProgram(self._composite)
            self.result.Activate()
            self._composite.SetUniformi("resultTex", self.result.GetTextureUnit())
            self._composite.SetUniform4f("viewport", viewport)
            self._composite.SetUniformf("scale", float(scale))
            blend_premultiplied_over(window)
            self._quad.Render()
            self.result.Deactivate()
        finally:
            state.Pop()

    def read_result(self) -> np.ndarray:
        """The accumulated premultiplied image ``(h, w, 4)`` float32, bottom row first, divided
        by the frames (what the composite draws). For tests and the benchmark."""
        window = self.renderer.GetRenderWindow()
        window.MakeCurrent()
        G = gl(window)
        self.result.Activate()
        w, h = self.result.GetWidth(), self.result.GetHeight()
        out = np.empty((h, w, 4), np.float32)
        window.GetState().vtkglPixelStorei(G.GL_PACK_ALIGNMENT, 1)
        G.glGetTexImage(G.GL_TEXTURE_2D, 0, G.GL_RGBA, G.GL_FLOAT, out)
        self.result.Deactivate()
        return out * self.result_scale()

    def result_scale(self) -> float:
        return 1.0

    # -- uniforms -------------------------------------------------------------------------------
    @staticmethod
    def set_uniforms(prog: vtk.vtkShaderProgram, values: dict[str, Any]) -> None:
        for name, v in values.items():
            if isinstance(v, np.ndarray) and v.shape == (4, 4):
                prog.SetUniformMatrix4x4(name, [float(x) for x in v.T.ravel()])
            elif isinstance(v, bool | int | np.integer):
                prog.SetUniformi(name, int(v))
            elif isinstance(v, float | np.floating):
                prog.SetUniformf(name, float(v))
            elif len(v) == 3:
                prog.SetUniform3f(name, [float(x) for x in v])
            elif len(v) == 4:
                prog.SetUniform4f(name, [float(x) for x in v])
            else:
                raise ValueError(f"uniform {name}: unsupported value {v!r}")

    # -- teardown -------------------------------------------------------------------------------
    def _release_depth(self) -> None:
        window = self._window or self.renderer.GetRenderWindow()
        if self._depth_fbo is not None:
            self._depth_fbo.ReleaseGraphicsResources(window)
            self._depth_fbo = None
        if self._depth is not None:
            self._depth.ReleaseGraphicsResources(window)
            self._depth = None

    def release_gl(self) -> None:
        """Free this renderer's own GL resources (subclasses add theirs)."""
        window = self._window
        if window is not None:
            window.MakeCurrent()
        if self._program is not None:
            self._program.release()
            self._program = None
        if window is None:
            return
        self._release_depth()
        if self._quad is not None:
            self._quad.ReleaseGraphicsResources(window)
            self._quad = None
            window.GetShaderCache().ReleaseCurrentShader()
        if self.result is not None:
            self.result.ReleaseGraphicsResources(window)
            self.result = None
        if self._colour is not None:
            self._colour.release()
            self._colour = None
        self._release_post()

    def release(self) -> None:
        """Detach: VTK's volume visible again (as it was), proxy and observer removed."""
        self.renderer.RemoveObserver(self._tag)
        self.renderer.RemoveActor(self._proxy)
        self.release_gl()
        self.volume.SetVisibility(self._was_visible)


def check_renderer(host: Illuminator, name: str) -> None:
    """Raise ``ValueError`` (one sentence, ``vtkvol:`` prefixed) when ``name`` cannot render
    the host's volume as it is set up now."""
    mapper = host.volume.GetMapper()
    blend = {vtk.vtkVolumeMapper.COMPOSITE_BLEND: "composite",
             vtk.vtkVolumeMapper.MAXIMUM_INTENSITY_BLEND: "mip",
             vtk.vtkVolumeMapper.MINIMUM_INTENSITY_BLEND: "minip",
             vtk.vtkVolumeMapper.AVERAGE_INTENSITY_BLEND: "average",
             vtk.vtkVolumeMapper.ADDITIVE_BLEND: "additive",
             vtk.vtkVolumeMapper.ISOSURFACE_BLEND: "isosurface",
             }.get(mapper.GetBlendMode(), "other")
    scalars = host.image.GetPointData().GetScalars()
    channels = scalars.GetNumberOfComponents() if scalars is not None else 1
    reason = unsupported_reason(name, method=host.method, blend_mode=blend,
                                lights=len(host.light_specs()), channels=channels)
    if reason is None and name != "raycast" and channels > 1 and not bool(
            host.volume.GetProperty().GetIndependentComponents()):
        reason = (f"the {name} renderer takes independent channels only; dependent "
                  f"{channels}-component colour data needs the raycast renderer")
    if reason is not None:
        raise ValueError(f"vtkvol: {reason}")


def blend_premultiplied_over(window: vtk.vtkRenderWindow) -> None:
    """GL state for drawing premultiplied colour over the scene: no depth test or depth
    writes, blending ``src + (1 − src α)·dst`` (colour and alpha). Call inside the window
    state's ``Push``/``Pop``, which restores VTK's state."""
    G = gl(window)
    state = window.GetState()
    state.vtkglDisable(G.GL_DEPTH_TEST)
    state.vtkglDepthMask(G.GL_FALSE)
    state.vtkglEnable(G.GL_BLEND)
    state.vtkglBlendFuncSeparate(G.GL_ONE, G.GL_ONE_MINUS_SRC_ALPHA,
                                 G.GL_ONE, G.GL_ONE_MINUS_SRC_ALPHA)
