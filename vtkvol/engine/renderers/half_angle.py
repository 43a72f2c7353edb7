"""Half-angle slicing (seed 001 §2.3.1, eqs. 2.41–2.44, after Kniss et al. 2003).

The volume is cut by planes perpendicular to the **half vector** s between the view direction v
(camera → volume, at the screen's centre) and the light's propagation direction l (light →
volume): s = normalize(v + l) when v·l ≥ 0 (the light shines from the viewer's side, slices go
front to back for the eye, *under* operator), else s = normalize(−v + l) (the light shines
towards the viewer, slices go back to front for the eye, *over* operator). Either way the
slices are processed front to back **as seen from the light**, so when slice k is shaded its
light has passed through slices 0…k−1 only.

Per slice k (dataset µm, planes s·p = σ_k, σ_k = σ_min + (k + j)·d, d = smallest voxel edge /
``slices_per_voxel``, j ∈ [0, 1) the frame's jitter) one compute dispatch does both passes,
reading light buffer A and writing light buffer B (then they swap): eye and light buffers stay
in lockstep.

* **Eye pass** (one invocation per pixel): the pixel's ray meets plane k at p (inside the
  volume box and in front of VTK's opaque depth, else nothing). Opacity per unit distance α_u
  and colour c from the host's classified medium (:mod:`.base`); the distance between planes
  along this ray is Δ = d / |cos θ| (eq. 2.41, θ between ray and s), so
  α = 1 − (1 − α_u)^(Δ / unit_distance). The light at p is read from A at p's orthographic
  projection on the light buffer: direct transmittance T and indirect RGB transmittance T_i,
  combined as L = (T + w·T_i) / (1 + w) (the ``translucency`` technique's normalised reading of
  eq. 2.44: an unoccluded sample gets the light once; docs/translucency.md §2). The sample
  emits the host's **medium model** (what the camera path tracer computes):
  g = exposure · a·c · (E · 4π·p_HG(cos) · L + k_a + F) with a the albedo, E the light's colour ×
  intensity, p_HG the Henyey–Greenstein phase (the host's g), k_a the property's ambient, F
  the host's fill. It is composited premultiplied into the frame's eye buffer with under
  (front to back) or over (back to front).
* **Light pass** (one invocation per light-buffer texel): the texel's light ray meets plane k
  at p; across one slice the light travels Δ_l = d / (s·l). Direct: T ← T · (1 − α_u)^(Δ_l /
  unit). Indirect: T_i ← blur(T_i) · exp(−τ_i Δ_l) with the chromatic indirect extinction
  τ_i,c = k · τ · (1 − tint · c_c) (τ = −ln(1 − α_u) / unit; the ``translucency`` technique's
  τ_i) and blur = the mean of 4 bilinear taps of A at distance Δ_l · tan(θ_c) µm (θ_c the
  cone's half-angle) around the texel, in directions rotated by a per-slice, per-frame hash
  angle (Kniss's 4 jittered taps; randomised per slice, not per texel, so that the numpy twin
  :mod:`vtkvol.reference.half_angle` reproduces them exactly).

Each frame jitters the slice origin j (a golden-ratio sequence) and the frames are averaged in
the accumulation buffer (progressive: ``samples`` frames, then converged), which removes the
slice pattern. The light buffer is orthographic, ``light_resolution``² texels over the volume
box's bounding sphere (default: about one texel per smallest voxel edge).

**One light.** The slicing axis depends on the light, so a second light would need a second,
differently oriented slicing whose eye contributions cannot be composited slice by slice with
the first: more than one enabled light is refused (the model's
:func:`~vtkvol.model.renderers.unsupported_reason`). A **point light** is sliced as a
directional light along the line from its position to the volume's centre (orthographic light
buffer; Kniss used a perspective light camera); its inverse-square fall-off is applied per
sample. A light's size is not used (the indirect blur stands for soft light).

Host features: the classified opacity texture carries the TF, gradient opacity, crop,
clipping planes, slice and channel weights; 1–4 independent channels through the colour
volume of :mod:`.base`. Blend modes other than composite are refused.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import vtk

from vtkvol.engine.gl import Texture3D, gl, linear_texture_2d
from vtkvol.engine.renderers.base import COMMON_GLSL, BesideRenderer

if TYPE_CHECKING:
    from vtkvol.engine.illuminator import Illuminator

MAX_SLICES = 4096
DEFAULT_SAMPLES = 8
GOLDEN = 0.6180339887498949

CS = """#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f) uniform image2D eyeImg;      // this frame's eye buffer (premultiplied)
layout(rgba32f) uniform image2D lightOut;    // light buffer B (written)
layout(rgba32f) uniform image2D accum;       // accumulation over frames (mode 2)
uniform sampler2D lightIn;                   // light buffer A (read): rgb T_i, a T
""" + COMMON_GLSL + """
uniform int mode;              // 0: slice, 1: clear eye + light B to unlit, 2: accumulate
uniform int first;             // mode 2: overwrite the accumulation (first frame)
uniform vec3 sAxis;            // slice normal (unit)
uniform vec3 lDir;             // light propagation direction (unit)
uniform vec3 lU; uniform vec3 lW;   // light buffer axes (unit, ⟂ lDir)
uniform vec3 centre;           // volume box centre (µm)
uniform float radius;          // half-extent of the light buffer (µm)
uniform int lightRes;          // light buffer texels per side
uniform float sigmaK;          // plane k: dot(sAxis, p) = sigmaK (µm)
uniform float sliceStep;       // d (µm)
uniform int under;             // 1: front to back for the eye, 0: back to front
uniform vec3 lightColour;      // E (colour x intensity)
uniform vec3 lightPos;         // point light position (µm) when pointLight = 1
uniform int pointLight;
uniform float falloff;         // d0 (µm), 0: none
uniform float albedo;
uniform float g;
uniform float ambient;         // ka + F
uniform float exposure;
uniform float indirectW;       // w
uniform float indirectK;       // k
uniform float tint;
uniform float blurRadius;      // µm: Δ_l tan(theta_c)
uniform float blurAngle;       // rotation of the 4 taps (rad)
bool inBox(vec3 p) {
  vec3 v = (p - dOrigin) / dSpacing;
  return all(greaterThanEqual(v, vec3(-1e-4))) && all(lessThanEqual(v, dims - 1.0 + 1e-4));
}
vec2 lightUV(vec3 p) {
  vec3 q = p - centre;
  return vec2(dot(q, lU), dot(q, lW)) / (2.0 * radius) + 0.5;
}
float phase4pi(float c) {
  float dn = 1.0 + g * g - 2.0 * g * c;
  return (1.0 - g * g) / (dn * sqrt(dn));
}
void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  bool eye = px.x < int(viewport.z) && px.y < int(viewport.w);
  bool light = px.x < lightRes && px.y < lightRes;
  if (mode == 1) {
    if (eye) imageStore(eyeImg, px, vec4(0.0));
    if (light) imageStore(lightOut, px, vec4(1.0));
    return;
  }
  if (mode == 2) {
    if (eye) imageStore(accum, px, imageLoad(eyeImg, px)
                                   + (first == 1 ? vec4(0.0) : imageLoad(accum, px)));
    return;
  }
  float sl = dot(sAxis, lDir);
  if (eye) {
    vec3 o, d; float t0, t1;
    if (cameraRay(viewport.xy + vec2(px) + 0.5, px + ivec2(viewport.xy), o, d, t0, t1)) {
      float cosT = dot(sAxis, d);
      float t = abs(cosT) > 1e-6 ? (sigmaK - dot(sAxis, o)) / cosT : -1.0;
      if (t >= t0 && t <= t1) {
        vec3 p = o + t * d;
        float au = clamp(alphaAt(p), 0.0, 0.999999);
        if (au > 0.0) {
          float a = 1.0 - pow(1.0 - au, sliceStep / abs(cosT) / unitDistance);
          vec4 lt = texture(lightIn, lightUV(p));
          vec3 L = (vec3(lt.a) + indirectW * lt.rgb) / (1.0 + indirectW);
          vec3 E = lightColour;
          vec3 toLight = -lDir;
          if (pointLight == 1) {
            vec3 r = lightPos - p;
            toLight = normalize(r);
            if (falloff > 0.0) E *= falloff * falloff / max(dot(r, r), 1e-12);
          }
          vec3 c = exposure * albedo * colourAt(p)
                   * (E * phase4pi(dot(toLight, d)) * L + ambient);
          vec4 acc = imageLoad(eyeImg, px);
          acc = under == 1 ? acc + (1.0 - acc.a) * vec4(c * a, a)
                           : acc * (1.0 - a) + vec4(c * a, a);
          imageStore(eyeImg, px, acc);
        }
      }
    }
  }
  if (light) {
    vec2 uv = (vec2(px) + 0.5) / float(lightRes);
    vec2 xy = (uv - 0.5) * 2.0 * radius;
    vec3 q = centre + xy.x * lU + xy.y * lW;
    vec3 p = q + (sigmaK - dot(sAxis, q)) / sl * lDir;
    float dl = sliceStep / sl;
    vec4 prev = texture(lightIn, uv);
    vec3 blur = vec3(0.0);
    float rUV = blurRadius / (2.0 * radius);
    for (int m = 0; m < 4; ++m) {
      float ph = blurAngle + 1.5707963 * float(m);
      blur += texture(lightIn, uv + rUV * vec2(cos(ph), sin(ph))).rgb;
    }
    blur *= 0.25;
    float au = inBox(p) ? clamp(alphaAt(p), 0.0, 0.999999) : 0.0;
    float tau = -log(1.0 - au) / unitDistance;
    // The colour only where there is extinction (most of the light buffer is empty space).
    vec3 tauI = au > 0.0 ? indirectK * tau * (1.0 - tint * colourAt(p)) : vec3(0.0);
    imageStore(lightOut, px, vec4(blur * exp(-tauI * dl), prev.a * exp(-tau * dl)));
  }
}
"""


def slice_angle(k: int, frame: int) -> float:
    """Rotation (rad) of slice ``k``'s 4 blur taps in frame ``frame``: a PCG-style integer hash,
    the same in the numpy twin."""
    v = (k * 9781 + frame * 6271 + 1) & 0xFFFFFFFF
    s = (v * 747796405 + 2891336453) & 0xFFFFFFFF
    w = (((s >> ((s >> 28) + 4)) ^ s) * 277803737) & 0xFFFFFFFF
    w = ((w >> 22) ^ w) & 0xFFFFFFFF
    return 2.0 * math.pi * w / 4294967296.0


def frame_jitter(frame: int) -> float:
    """Slice-origin offset of frame ``frame`` in slice spacings, in [0, 1) (golden ratio)."""
    return (0.5 + frame * GOLDEN) % 1.0


def slicing_geometry(view: np.ndarray, light_dir: np.ndarray) -> tuple[np.ndarray, bool]:
    """(slice normal s, front-to-back for the eye?) for view direction ``view`` (camera →
    volume) and light propagation direction ``light_dir`` (light → volume), both unit."""
    if float(view @ light_dir) >= 0.0:
        s = view + light_dir
        under = True
    else:
        s = -view + light_dir
        under = False
    n = np.linalg.norm(s)
    if n < 1e-9:  # light exactly opposite the view: the slices face the light
        s, n = light_dir.copy(), 1.0
    return s / n, under


def light_axes(light_dir: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane ⟂ ``light_dir`` (the light buffer's u and w)."""
    a = np.array([1.0, 0.0, 0.0]) if abs(light_dir[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(light_dir, a)
    u /= np.linalg.norm(u)
    return u, np.cross(light_dir, u)


class HalfAngleSlicing(BesideRenderer):
    """Half-angle slicing with chromatic, blurred indirect light (see the module docstring)."""

    NAME: ClassVar[str] = "half_angle"
    PROGRESSIVE: ClassVar[bool] = True

    def __init__(self, host: Illuminator, *, slices_per_voxel: float = 1.0,
                 light_resolution: int | None = None, samples: int = DEFAULT_SAMPLES,
                 indirect_angle: float = 15.0, indirect_extinction: float = 0.5,
                 tint: float = 0.75, indirect_strength: float = 1.0) -> None:
        if not 0.05 <= slices_per_voxel <= 16:
            raise ValueError(f"slices_per_voxel must be in 0.05…16, not {slices_per_voxel}")
        if light_resolution is not None and not 8 <= light_resolution <= 2048:
            raise ValueError(f"light_resolution must be in 8…2048, not {light_resolution}")
        if samples < 1:
            raise ValueError(f"samples must be ≥ 1, not {samples}")
        if not 0.0 <= indirect_angle < 90.0:
            raise ValueError(f"indirect_angle must be in 0…90 degrees, not {indirect_angle}")
        if indirect_extinction < 0 or not 0 <= tint <= 1 or indirect_strength < 0:
            raise ValueError("indirect_extinction and indirect_strength must be ≥ 0 and tint "
                             "in 0…1")
        self.slices_per_voxel = float(slices_per_voxel)
        #: Light-buffer texels per side; None: one texel per smallest voxel edge across the
        #: box's bounding sphere, rounded up to a power of two within 32…512 (the light pass
        #: dominates a frame on llvmpipe: a 128² buffer for a 32³ volume cost ~3× a 64² one).
        self.requested_light_resolution = light_resolution
        self.light_resolution = int(light_resolution or 64)
        self.indirect_angle = float(indirect_angle)
        self.indirect_extinction = float(indirect_extinction)
        self.tint = float(tint)
        self.indirect_strength = float(indirect_strength)
        self._lights: list[vtk.vtkTextureObject] = []
        self._eye: vtk.vtkTextureObject | None = None
        self.slices = 0  #: slices drawn in the last frame
        self.under = True  #: the last frame composited front to back for the eye
        self.geometry: dict[str, Any] = {}  #: the last frame's slicing set-up (tests, twin)
        super().__init__(host)
        self.target_iterations = int(samples)

    def settings_signature(self) -> tuple:
        return (self.slices_per_voxel, self.requested_light_resolution, self.indirect_angle,
                self.indirect_extinction, self.tint, self.indirect_strength)

    def result_scale(self) -> float:
        return 1.0 / max(1, self.iteration)

    def _texture(self, window: Any, w: int, h: int) -> vtk.vtkTextureObject:
        tex = linear_texture_2d(window)
        tex.Allocate2D(w, h, 4, vtk.VTK_FLOAT)  # GL_RGBA32F
        return tex

    def _ensure_targets(self, window: Any) -> None:
        n = self.light_resolution
        if not self._lights or self._lights[0].GetWidth() != n:
            self._release_targets(window)
            self._lights = [self._texture(window, n, n) for _ in range(2)]
        w, h = self.renderer.GetSize()
        if self._eye is None or (self._eye.GetWidth(), self._eye.GetHeight()) != (w, h):
            if self._eye is not None:
                self._eye.ReleaseGraphicsResources(window)
            self._eye = self._texture(window, max(1, w), max(1, h))

    def _release_targets(self, window: Any) -> None:
        for t in self._lights:
            t.ReleaseGraphicsResources(window)
        self._lights = []
        if self._eye is not None:
            self._eye.ReleaseGraphicsResources(window)
            self._eye = None

    def frame_geometry(self, ndc_to_data: np.ndarray, frame: int) -> dict[str, Any]:
        """The slicing of frame ``frame`` (dataset µm): slice normal, order, light frame,
        plane positions. The numpy twin takes the same dictionary."""
        img = self.host.image
        spacing = np.abs(np.array(img.GetSpacing(), float))
        origin = np.array(img.GetOrigin(), float)
        hi = origin + (np.array(img.GetDimensions(), float) - 1) * spacing
        centre = (origin + hi) / 2
        radius = max(float(np.linalg.norm(hi - origin)) / 2, 1e-6)
        if self.requested_light_resolution is None:
            texels = 2 * radius / float(spacing.min())
            self.light_resolution = int(min(512, max(32, 2 ** math.ceil(math.log2(
                max(texels, 1.0))))))

        def unproject(z: float) -> np.ndarray:
            q = ndc_to_data @ np.array([0.0, 0.0, z, 1.0])
            return q[:3] / q[3]

        view = unproject(1.0) - unproject(-1.0)
        view /= np.linalg.norm(view)
        spec = self.host.light_specs()[0]
        if spec.is_point:
            ldir = centre - np.asarray(spec.vector, float)
            nrm = np.linalg.norm(ldir)
            ldir = ldir / nrm if nrm > 1e-9 else -view
        else:
            ldir = -np.asarray(spec.vector, float)
            ldir /= np.linalg.norm(ldir)
        s, under = slicing_geometry(view, ldir)
        u, w = light_axes(ldir)
        step = float(spacing.min()) / self.slices_per_voxel
        corners = np.array([[x, y, z] for x in (origin[0], hi[0]) for y in (origin[1], hi[1])
                            for z in (origin[2], hi[2])])
        proj = corners @ s
        jitter = frame_jitter(frame)
        n = min(MAX_SLICES, int(np.floor((proj.max() - proj.min()) / step - jitter)) + 1)
        sigmas = proj.min() + (np.arange(n) + jitter) * step
        sl = float(s @ ldir)
        return {
            "axis": s, "under": under, "light_dir": ldir, "u": u, "w": w, "centre": centre,
            "radius": radius, "step": step, "sigmas": sigmas, "frame": frame,
            "blur_radius": step / sl * math.tan(math.radians(self.indirect_angle)),
            "light_resolution": self.light_resolution,
            "light": spec, "albedo": float(self.host.albedo), "g": float(self.host.phase_g),
            "ambient": float(self.volume.GetProperty().GetAmbient(0)) + self.host.fill,
            "exposure": float(self.host.exposure), "indirect_strength": self.indirect_strength,
            "indirect_extinction": self.indirect_extinction, "tint": self.tint,
        }

    def draw(self, opacity: Texture3D, uniforms: dict[str, Any]) -> float:
        window = self.renderer.GetRenderWindow()
        G = gl(window)
        if self.iteration >= self.target_iterations:
            # Converged: the jittered frames are averaged; a repaint shows them as they are
            # (a new frame would cost a full slicing and change nothing visible).
            return 1.0 / self.iteration
        post, opacity, colour = self.medium_textures(window, opacity)
        self.medium_program(window, post, CS, "half-angle slicing")
        geo = self.frame_geometry(uniforms["ndcToData"], self.iteration)
        self._ensure_targets(window)
        self.geometry = geo
        self.under = geo["under"]
        self.slices = len(geo["sigmas"])
        spec = geo["light"]
        p = self._program.use()
        units = [opacity.activate(), colour.activate()]
        self._depth.Activate()
        values = dict(uniforms)
        values.update({
            "opacityTex": units[0], "tableTex" if post else "colourTex": units[1],
            "depthTex": self._depth.GetTextureUnit(),
            "eyeImg": 0, "lightOut": 1, "accum": 2,
            "sAxis": tuple(geo["axis"]), "lDir": tuple(geo["light_dir"]),
            "lU": tuple(geo["u"]), "lW": tuple(geo["w"]), "centre": tuple(geo["centre"]),
            "radius": geo["radius"], "lightRes": self.light_resolution,
            "sliceStep": geo["step"], "under": int(geo["under"]),
            "lightColour": tuple(spec.color), "lightPos": tuple(spec.vector),
            "pointLight": int(spec.is_point), "falloff": float(spec.falloff_distance),
            "albedo": geo["albedo"], "g": geo["g"], "ambient": geo["ambient"],
            "exposure": geo["exposure"], "indirectW": self.indirect_strength,
            "indirectK": self.indirect_extinction, "tint": self.tint,
            "blurRadius": geo["blur_radius"], "sigmaK": 0.0, "blurAngle": 0.0, "mode": 1,
            "first": 0,
        })
        self.set_uniforms(p, values)
        w, h = self.renderer.GetSize()
        n = self.light_resolution
        groups = ((max(w, n) + 7) // 8, (max(h, n) + 7) // 8, 1)
        eye = self._eye.GetHandle()
        G.glBindImageTexture(0, eye, 0, G.GL_FALSE, 0, G.GL_READ_WRITE, G.GL_RGBA32F)
        G.glBindImageTexture(2, self.result.GetHandle(), 0, G.GL_FALSE, 0, G.GL_READ_WRITE,
                             G.GL_RGBA32F)
        # Mode 1: the eye buffer cleared, light buffer 0 set to unlit (T = T_i = 1).
        G.glBindImageTexture(1, self._lights[0].GetHandle(), 0, G.GL_FALSE, 0,
                             G.GL_WRITE_ONLY, G.GL_RGBA32F)
        self._program.dispatch(groups)
        p.SetUniformi("mode", 0)
        for k, sigma in enumerate(geo["sigmas"]):
            read, write = self._lights[k % 2], self._lights[(k + 1) % 2]
            read.Activate()
            p.SetUniformi("lightIn", read.GetTextureUnit())
            G.glBindImageTexture(1, write.GetHandle(), 0, G.GL_FALSE, 0, G.GL_WRITE_ONLY,
                                 G.GL_RGBA32F)
            p.SetUniformf("sigmaK", float(sigma))
            p.SetUniformf("blurAngle", slice_angle(k, self.iteration))
            self._program.dispatch(groups)
            read.Deactivate()
        p.SetUniformi("mode", 2)
        p.SetUniformi("first", int(self.iteration == 0))  # the first frame overwrites
        self._program.dispatch(groups)
        self._depth.Deactivate()
        return self._end_frame(colour, opacity)

    def release_gl(self) -> None:
        if self._window is not None:
            self._window.MakeCurrent()
            self._release_targets(self._window)
        super().release_gl()


__all__ = ["DEFAULT_SAMPLES", "HalfAngleSlicing", "frame_jitter", "light_axes", "slice_angle",
           "slicing_geometry"]
