// vtkvol slice-contribution weights (seed 002 §2.11): every sample's opacity (and so its
// premultiplied RGBA) is multiplied by wX(x)·wY(y)·wZ(z); samples with weight < 1e-10 are
// discarded. Injected only when the weights are not all 1 (compile-time, no cost otherwise).
// Uniforms:
//   sampler2D vv_sliceWeights    W×3 R32F lookup table; rows x, y, z; columns 0..1 across the
//                                volume's point bounds on that axis
//   float     vv_sliceWeightsWidth  W
// Define VV_INDEPENDENT when the volume has independent components (computeOpacity(scalar, c)).

//@inject //VTK::ComputeOpacity::Dec pre after
float vv_sliceWeight(vec3 texPos)
{
  vec3 u = clamp(vv_texToUnit(texPos), 0.0, 1.0);
  vec3 s = (0.5 + u * (vv_sliceWeightsWidth - 1.0)) / vv_sliceWeightsWidth;
  float w = texture(vv_sliceWeights, vec2(s.x, 1.0 / 6.0)).r
          * texture(vv_sliceWeights, vec2(s.y, 3.0 / 6.0)).r
          * texture(vv_sliceWeights, vec2(s.z, 5.0 / 6.0)).r;
  return w < 1e-10 ? 0.0 : w;
}
#ifdef VV_INDEPENDENT
float vv_weightedOpacity(vec4 scalar, int c) { return computeOpacity(scalar, c) * vv_sliceWeight(g_dataPos); }
#else
float vv_weightedOpacity(vec4 scalar) { return computeOpacity(scalar) * vv_sliceWeight(g_dataPos); }
#endif
#undef computeOpacity
#define computeOpacity vv_weightedOpacity
