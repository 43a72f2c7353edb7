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
// Shading (host_lighting.glsl): V multiplies the diffuse and specular terms of its light;
// ambient is kept (vv_ambient_visibility = 1: this technique computes no occlusion).

//@inject //VTK::ComputeLighting::Dec pre before
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)
{
  // Offset h0 cells towards the light: a cell is measured in the light grid's own (possibly
  // anisotropic) units, so the offset is h0 cells whatever the direction.
  vec3 dirTex = vv_datasetDirToTex(dirDS);                          // texture units per µm
  float cellsPerUm = length(dirTex / vv_shadow_volume_cellTex);
  vec3 p = texPos + dirTex * (vv_shadow_volume_offset / max(cellsPerUm, 1e-30));
  vec3 tc = vv_unitToGrid(vv_texToUnit(p), vv_shadow_volume_dims);
  float v = texture(vv_shadow_volume_tex, tc)[light];
  return 1.0 - vv_shadow_volume_strength * (1.0 - v);
}

float vv_ambient_visibility(vec3 texPos, vec3 normalDS) { return 1.0; }
