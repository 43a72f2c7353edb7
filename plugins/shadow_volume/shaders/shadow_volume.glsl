// vtkvol technique "shadow_volume": shadows read from a precomputed light volume.
// Tested with VTK 9.7.1 (vtkOpenGLGPUVolumeRayCastMapper), single and independent components.
//
// The light volume (plugins/shadow_volume/technique.py, shaders/propagate.comp.glsl)
// holds, per light, the visibility V in 0..1 at the cell centres of a grid of
// vv_shadow_volume_dims cells spanning the data's point bounds; light i is channel i of one
// texture (R32F for one light, RG32F for two, RGBA32F for three or four). It is clamped to a
// border of 1, so lookups pushed outside the volume are unshadowed.
//
// Uniforms (custom, set by the host):
//   sampler3D vv_shadow_volume_tex       light volume (declared int by VTK, retyped by the host)
//   vec3  vv_shadow_volume_dims          light-grid cells (x, y, z)
//   vec3  vv_shadow_volume_cellTex       one light-grid cell in data texture coordinates
//   float vv_shadow_volume_strength      0..1: visibility = 1 - strength * (1 - V)
//   float vv_shadow_volume_offset        h0: lookup offset towards the light, light-grid cells
//
// Where a sample reads its light (docs/shadow-volume.md, "Sample phase at opaque surfaces"): at
// the near end of the ray segment it closes, g_dataPos - g_dirStep (one ray step towards the
// viewer), then h0 cells towards the light. VTK composites the sample's opacity for that whole
// segment, and at an opaque surface the light is absorbed where the ray enters it. Read at the
// sample itself, the lookup lands anywhere up to one step inside the surface, where the
// visibility falls steeply with depth; how deep depends on where the ray's sample lattice
// (it starts on the bounding box) happens to meet the surface, which in a perspective view
// changes from ray to ray: lit surfaces darkened towards the image edges (issue 26).
//
// Cost per shaded sample and light (docs/shadow-volume.md, "Frame time"): one fused
// multiply-add from VTK's texture coordinate to the light grid's, then one trilinear fetch. The
// map, the ray's step back and each directional light's offset are constant along a ray (the
// step is the ray's own: in perspective every ray has its own direction), so they are computed
// once per fragment (vv_sv_setup, after VTK has set up the ray) instead of per sample: on
// llvmpipe that arithmetic (a matrix product, a length and two divisions per sample and light)
// was more than half of the technique's cost. Point lights (VV_SV_POINT_LIGHTS, set by the host
// when any light is one) take their offset direction per sample, in light-grid cells.
//
// Shading (host_lighting.glsl): V multiplies the diffuse and specular terms of its light;
// ambient is kept (vv_ambient_visibility = 1: this technique computes no occlusion).

//@inject //VTK::ComputeLighting::Dec pre before
// Light-grid texture coordinate = VTK's texture coordinate * vv_sv_texToGrid + vv_sv_gridBias[i]
// (bias: the grid's own origin, one step of this ray back towards the viewer, and for
// directional light i the offset towards the light).
vec3 vv_sv_texToGrid;
vec3 vv_sv_gridBias[4];
#if VV_SV_POINT_LIGHTS
vec3 vv_sv_lightGrid[4];  // point light i in light-grid texture coordinates
#endif

// Once per fragment, after VTK's ray set-up (g_dirStep is this ray's step, texture units): the
// affine map from VTK's texture coordinates (0..1 over the data texture) to the light grid's
// (the same point bounds, vv_shadow_volume_dims cells), the step back to the near end of the
// sample's segment, and the offset of h0 light-grid cells towards each directional light. A
// cell is measured in the light grid's own (possibly anisotropic) units, so the offset is h0
// cells whatever the direction.
void vv_sv_setup()
{
  vec3 dims = vv_shadow_volume_dims;
  vec3 unitPerTex = 1.0 / (in_texMax[0] - in_texMin[0]);
  vv_sv_texToGrid = unitPerTex * (dims - 1.0) / dims;
  vec3 origin = (0.5 - in_texMin[0] * unitPerTex * (dims - 1.0)) / dims;
  vec3 segmentStart = origin - g_dirStep * vv_sv_texToGrid;
  for (int i = 0; i < vv_numLights; ++i)
  {
    vv_sv_gridBias[i] = segmentStart;
#if VV_SV_POINT_LIGHTS
    // The light's own position is not moved (only the lookup point is).
    vec3 lightTex = (in_inverseTextureDatasetMatrix[0] * vec4(vv_lightVector(i), 1.0)).xyz;
    vv_sv_lightGrid[i] = lightTex * vv_sv_texToGrid + origin;
    if (vv_lightIsPoint(i)) continue;
#endif
    vec3 dirTex = vv_datasetDirToTex(normalize(vv_lightVector(i)));  // texture units per µm
    float cellsPerUm = length(dirTex / vv_shadow_volume_cellTex);
    vec3 offsetTex = dirTex * (vv_shadow_volume_offset / max(cellsPerUm, 1e-30));
    vv_sv_gridBias[i] += offsetTex * vv_sv_texToGrid;
  }
}

float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)
{
  vec3 tc = texPos * vv_sv_texToGrid + vv_sv_gridBias[light];
#if VV_SV_POINT_LIGHTS
  if (vv_lightIsPoint(light))
  {
    // h0 cells along the direction to the light, measured in cells (an affine map keeps the
    // direction, so this is dirDS's direction).
    vec3 toLightCells = (vv_sv_lightGrid[light] - tc) * vv_shadow_volume_dims;
    float len = length(toLightCells);
    tc += len > 0.0 ? toLightCells * (vv_shadow_volume_offset / (len * vv_shadow_volume_dims))
                    : vec3(0.0);
  }
#endif
  float v = texture(vv_shadow_volume_tex, tc)[light];
  return 1.0 - vv_shadow_volume_strength * (1.0 - v);
}

float vv_ambient_visibility(vec3 texPos, vec3 normalDS) { return 1.0; }

//@inject //VTK::Base::Init pre after
  vv_sv_setup();
