// vtkvol engine: the direct irradiance E_0 = sum_l colour_l * falloff_l * direct_l at a voxel,
// shared by source_diffusion.comp.glsl (q on the data grid) and source_restrict.comp.glsl (q
// restricted to a reduced grid); vtkvol/engine/diffusion.py:source_term is its numpy twin. The
// including shader declares vv_numLights, vv_color[4] and vv_falloff[4] (position in um and d0
// in um; d0 = 0: no inverse-square fall-off).

vec3 vv_directIrradiance(vec4 rho, vec3 pos)
{
  vec3 e0 = vec3(0.0);
  for (int l = 0; l < vv_numLights; ++l)
  {
    float f = 1.0;
    if (vv_falloff[l].w > 0.0)
    {
      vec3 r = pos - vv_falloff[l].xyz;
      f = vv_falloff[l].w * vv_falloff[l].w / max(dot(r, r), 1e-12);
    }
    e0 += rho[l] * f * vv_color[l];
  }
  return e0;
}
