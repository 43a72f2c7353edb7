// vtkvol technique "shadow_volume": the light-volume lookup written per sample, the reference
// formula of shadow_volume.glsl (which computes the same map and offsets once per fragment).
// Not used for rendering: tests/test_shadow_volume_lookup.py renders with it beside the shipped
// lookup and compares the images, benchmarks/shadow_volume_timing.py (lookup_frame_ratios)
// times both. Same uniforms and texture as shadow_volume.glsl.
//
// Per sample and light: the near end of the sample's ray segment (texPos - g_dirStep), the
// direction towards the light in texture units, the offset of h0 light-grid cells along it,
// VTK's texture coordinate → 0..1 over the point bounds → the light grid's texture coordinate,
// one trilinear fetch.

//@inject //VTK::ComputeLighting::Dec pre before
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)
{
  vec3 dirTex = vv_datasetDirToTex(dirDS);                          // texture units per µm
  float cellsPerUm = length(dirTex / vv_shadow_volume_cellTex);
  vec3 p = texPos - g_dirStep + dirTex * (vv_shadow_volume_offset / max(cellsPerUm, 1e-30));
  vec3 tc = vv_unitToGrid(vv_texToUnit(p), vv_shadow_volume_dims);
  float v = texture(vv_shadow_volume_tex, tc)[light];
  return 1.0 - vv_shadow_volume_strength * (1.0 - v);
}

float vv_ambient_visibility(vec3 texPos, vec3 normalDS) { return 1.0; }
