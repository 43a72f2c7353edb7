// vtkvol technique "translucency": direct + coloured indirect light read from a precomputed
// light volume per light (docs/translucency.md). Tested with VTK 9.7.1
// (vtkOpenGLGPUVolumeRayCastMapper), single and independent components.
//
// Light volume of light i (plugins/translucency/technique.py, built with the shadow volume's
// shaders/propagate.comp.glsl): an RGBA32F texture vv_translucency_light<i> on a grid of
// vv_translucency_dims cells spanning the data's point bounds; RGB = indirect transmittance
// T_i (chromatic extinction, blurred within the cone), A = direct transmittance T (the shadow
// volume's transmittance model). Clamped to a border of 1 (unshadowed outside).
//
// Defines (compile time): VV_TL_LIGHTS = number of light volumes (0..4).
// Uniforms (custom, set by the host):
//   sampler3D vv_translucency_light0..3         light volumes (declared int by VTK, retyped)
//   vec3  vv_translucency_dims                  light-grid cells (x, y, z)
//   vec3  vv_translucency_cellTex               one light-grid cell in data texture coordinates
//   float vv_translucency_offset                h0: lookup offset towards the light, cells
//   float vv_translucency_indirect_strength     w in I_l = T + w T_i (eq. 2.44: w = 1)
//   int   vv_translucency_indirect_normalised   1: I_l divided by 1 + w
//   float vv_translucency_gradient_low/_high    g0, g1 of the surface-shading factor S
//
// Shading: the host's surface model with T_i(x) := (T + w T_i,rgb) / (1 + w) (eq. 2.44: C is
// multiplied by the sum of the transmittances; the division only while indirect_normalised is
// on). With surface_factor = gradient, surface_factor.glsl replaces the host's binary
// oriented/unoriented rule by Kniss's S(t) (vv_translucency_surfaceFactor).

//@inject //VTK::ComputeLighting::Dec pre before
#ifndef VV_TL_LIGHTS
#define VV_TL_LIGHTS 0
#endif

#if VV_TL_LIGHTS > 0
// Light i's volume at light-grid texture coordinate tc. Samplers cannot be indexed by a
// non-constant in GLSL 1.50, hence the chain (the light loop's index is uniform per draw).
vec4 vv_translucency_fetch(int light, vec3 tc)
{
#if VV_TL_LIGHTS > 3
  if (light == 3) return texture(vv_translucency_light3, tc);
#endif
#if VV_TL_LIGHTS > 2
  if (light == 2) return texture(vv_translucency_light2, tc);
#endif
#if VV_TL_LIGHTS > 1
  if (light == 1) return texture(vv_translucency_light1, tc);
#endif
  return texture(vv_translucency_light0, tc);
}
#endif

vec3 vv_light_transmittance_rgb(int light, vec3 texPos, vec3 dirDS)
{
  // As the shadow volume reads its volume (shadow_volume.glsl, docs/shadow-volume.md "Sample
  // phase at opaque surfaces"): from the near end of the sample's ray segment (one step of
  // this ray towards the viewer; read at the sample, an opaque surface's light depended on
  // where the ray's samples met it, which varies from ray to ray in perspective), offset h0
  // cells towards the light (a cell is measured in the light grid's own, possibly
  // anisotropic, units).
  vec3 dirTex = vv_datasetDirToTex(dirDS);                          // texture units per µm
  float cellsPerUm = length(dirTex / vv_translucency_cellTex);
  vec3 p = texPos - g_dirStep + dirTex * (vv_translucency_offset / max(cellsPerUm, 1e-30));
  vec3 tc = vv_unitToGrid(vv_texToUnit(p), vv_translucency_dims);
#if VV_TL_LIGHTS > 0
  vec4 t = light < VV_TL_LIGHTS ? vv_translucency_fetch(light, tc) : vec4(1.0);
#else
  vec4 t = vec4(1.0);   // no light volume: nothing attenuates
#endif
  // Eq. 2.44's sum; normalised by 1 + w so that unoccluded light is the irradiance once.
  float w = vv_translucency_indirect_strength;
  float norm = vv_translucency_indirect_normalised != 0 ? 1.0 / (1.0 + w) : 1.0;
  return norm * (vec3(t.a) + w * t.rgb);
}

// Kniss's surface-shading factor S in 0..1 from the gradient magnitude g (change of the value
// per voxel as a fraction of the transfer function's range): smoothstep(g0, g1, g), with
// g1 < g0 read as g1 = g0 (a step at g0). g0 = g1 = 0 is the host's binary rule.
float vv_translucency_surfaceFactor(float g)
{
  float lo = vv_translucency_gradient_low;
  float width = max(vv_translucency_gradient_high - lo, 0.0);
  float t = width > 0.0 ? clamp((g - lo) / width, 0.0, 1.0) : (g > lo ? 1.0 : 0.0);
  return t * t * (3.0 - 2.0 * t);
}
