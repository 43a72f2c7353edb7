// vtkvol technique "cone_traced": the cone march, included by the fragment shader
// (cone_traced.glsl) and the AO bake (bake_ao.comp.glsl); its numpy twin is cone_trace_cpu()
// in plugins/cone_traced/cpu.py. The includer defines VV_CONE_MAX_STEPS (step bound) and
// VV_CONE_TAU_EXIT (optical depth at which the cone counts as closed).
//
// Transmittance (0..1] of one cone starting at texture position tex0 (0..1, voxel centres at
// (i+0.5)/N). One ray: front-to-back accumulation of optical depth (tau += D * ds / u, i.e. per
// step alpha = 1 - (1 - F)^(ds/u), independent of h), midpoint of each segment, starting at h0.
// The level rises (and the step doubles) while the cone's half-width b*sinAngle exceeds
// lodWidth·2^L voxels (lodWidth = lod_width·σ; the thesis rule has lod_width = 2). The march is
// in voxel space of the data grid, so the rule and the steps hold for anisotropic spacing too.
//
//   pyramid    D_L = -ln(1 - F_L) per opacity unit distance, border 0, levels 0..maxLod
//   dVox       the cone axis in voxels per µm, per axis (length = voxels per µm along it)
//   dims       data dimensions (x, y, z) voxels
//   unitUm     opacity unit distance u, µm
//   maxDistUm  where the march stops (µm), besides the box and VV_CONE_TAU_EXIT
//   h, h0      level-0 step and start offset, voxels along the cone
float vv_cone_march(sampler3D pyramid, vec3 tex0, vec3 dVox, vec3 dims, float unitUm,
                    float maxDistUm, float sinAngle, float lodWidth, float h, float h0,
                    float maxLod)
{
  float perUm = length(dVox);
  if (!(perUm > 0.0)) return 1.0;
  vec3 stepTex = dVox / (perUm * dims);     // texture coordinates per voxel along the cone
  float depthPerVoxel = 1.0 / (perUm * unitUm);  // unit distances per voxel along the cone
  float tauExit = VV_CONE_TAU_EXIT / depthPerVoxel;
  float bMax = maxDistUm * perUm;
  float lod = 0.0;
  float scale = 1.0;
  float b = h0;
  float tau = 0.0;
  for (int i = 0; i < VV_CONE_MAX_STEPS; ++i)
  {
    for (int j = 0; j < 16 && b * sinAngle > lodWidth * scale && lod < maxLod; ++j)
    {
      lod += 1.0;
      scale *= 2.0;
    }
    float s = min(h * scale, bMax - b);
    if (!(s > 0.0)) break;
    vec3 tc = tex0 + (b + 0.5 * s) * stepTex;
    if (any(lessThan(tc, vec3(0.0))) || any(greaterThan(tc, vec3(1.0)))) break;
    tau += textureLod(pyramid, tc, lod).r * s;
    if (tau > tauExit) break;
    b += s;
  }
  return exp(-tau * depthPerVoxel);
}
