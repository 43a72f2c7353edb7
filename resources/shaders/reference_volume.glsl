// vtkvol benchmark technique "bench_reference": shades with precomputed CPU reference volumes.
// Used only by `vtkvol bench` (vtkvol/bench/reference_technique.py), never offered to users.
// It renders "the same view in the same shader" as every technique, with the light and ambient
// visibility replaced by independent numpy references (vtkvol.reference), so an image
// comparison measures only the error of the technique's illumination. Tested with VTK 9.7.1.
//
// Textures (bound by the host, retyped from int to sampler3D), at the data's voxel centres:
//   vv_bench_reference_light0..3   transmittance towards light i, 0..1 (1 = unshadowed)
//   vv_bench_reference_ambient     ambient visibility 1 - AO, 0..1 (only with VV_REF_AO 1)
//   vv_bench_reference_irradiance  RGB in-scattered light of the medium model, >= 0 (only with
//                                  VV_REF_IRRADIANCE 1)
// Uniforms (custom, set by the host every frame):
//   vec3 vv_bench_reference_dims   grid dimensions (x, y, z) of the reference volumes
// Compile-time variants: VV_REF_LIGHTS (0..4 light textures), VV_REF_AO (0 | 1),
// VV_REF_IRRADIANCE (0 | 1).

//@inject //VTK::ComputeLighting::Dec pre before
vec3 vv_ref_coord(vec3 texPos)
{
  return vv_unitToGrid(vv_texToUnit(texPos), vv_bench_reference_dims);
}

float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)
{
  vec3 tc = vv_ref_coord(texPos);
#if VV_REF_LIGHTS > 0
  if (light == 0) return texture(vv_bench_reference_light0, tc).r;
#endif
#if VV_REF_LIGHTS > 1
  if (light == 1) return texture(vv_bench_reference_light1, tc).r;
#endif
#if VV_REF_LIGHTS > 2
  if (light == 2) return texture(vv_bench_reference_light2, tc).r;
#endif
#if VV_REF_LIGHTS > 3
  if (light == 3) return texture(vv_bench_reference_light3, tc).r;
#endif
  return 1.0;
}

float vv_ambient_visibility(vec3 texPos, vec3 normalDS)
{
#if VV_REF_AO
  return texture(vv_bench_reference_ambient, vv_ref_coord(texPos)).r;
#else
  return 1.0;
#endif
}

// Defined in every variant (the host sees the definition and drops its own default).
vec3 vv_irradiance(vec3 texPos)
{
#if VV_REF_IRRADIANCE
  return texture(vv_bench_reference_irradiance, vv_ref_coord(texPos)).rgb;
#else
  return vec3(0.0);
#endif
}
