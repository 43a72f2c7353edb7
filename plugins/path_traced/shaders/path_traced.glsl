// vtkvol technique "path_traced": shading reads Monte-Carlo light computed on the CPU by
// plugins/path_traced/technique.py (vtkvol.reference's path tracer) on the data's own grid, so
// texPos is the lookup coordinate. Lighting model: medium. Tested with VTK 9.7.1.
//
// Textures (bound by the host, retyped from int to sampler3D):
//   vv_path_traced_direct     exact transmittance towards light l in channel l (0..1)
//   vv_path_traced_scattered  in-scattered light (all orders), rgb, in the lights' units

//@inject //VTK::ComputeLighting::Dec pre before
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)
{
  return texture(vv_path_traced_direct, texPos)[light];
}

vec3 vv_irradiance(vec3 texPos)
{
  return texture(vv_path_traced_scattered, texPos).rgb;
}
