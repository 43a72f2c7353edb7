// vtkvol host lighting, "surface" model: replaces VTK's shading result by ours, per shaded
// sample. Injected after the technique's code and the hook defaults. Tested with VTK 9.7.1,
// headlight and scene-light variants of computeLighting() (both define `shading_gradient` and
// `lightingComponent`).
//
// Shading formula (docs/architecture.md, "Lighting models"):
//   n   = -normalize(gradient)                      outward normal, dataset space
//   C   = ka * albedo * A(x)                         A: ambient visibility (1 = unoccluded)
//       + sum_i  T_i(x) * E_i(x) * ( kd * max(n.l_i, 0) * albedo + ks * max(n.h_i, 0)^p )
//       + albedo * S(x)                              S: in-scattered irradiance (default 0)
//       + F * albedo                                 F: sky fill (vv_fill), never shadowed
//   then times the exposure (vv_exposure). With vv_exposureProbe = 1 the sample is lit as by
//   local shading (T_i = A = 1, S = 0): the automatic exposure's reference frame
//   (vtkvol/engine/exposure.py).
//   T_i: RGB transmittance towards light i (1 = unshadowed), E_i: light colour * intensity,
//   with inverse-square fall-off where the light asks for it. With two-sided lighting (the
//   renderer's default) n is first flipped to face the viewer, so a surface seen from inside is
//   lit like one seen from outside. Where the gradient is zero (homogeneous interior) the sample
//   is lit as an unoriented medium: n.l := 1, no specular. ka, kd, ks, p come from the
//   vtkVolumeProperty (per component).

//@inject //VTK::ComputeLighting::Dec pre before
#ifdef VV_MC_SHARE_LIGHT
// Multi-channel sample (host_multichannel.glsl): the transmittance towards each light depends
// on the position only, so it is evaluated once per sample for every component.
vec3 vv_mcTransmittance[4];

void vv_mcLights()
{
  vec3 posDS = vv_texToDataset(g_dataPos);
  for (int i = 0; i < vv_numLights; ++i)
  {
    vv_mcTransmittance[i] = vv_exposureProbe != 0 ? vec3(1.0)
      : vv_light_transmittance_rgb(i, g_dataPos, vv_directionToLight(i, posDS));
  }
}
#endif

vec3 vv_shade(vec3 albedo, vec3 gradientDS, int c)
{
  vec3 posDS = vv_texToDataset(g_dataPos);
  float glen = length(gradientDS);
  bool oriented = glen > 1e-12;
  vec3 n = oriented ? -gradientDS / glen : vec3(0.0);
  vec3 v = normalize(in_eyePosObjs[0].xyz - posDS);
  if (in_twoSidedLighting && dot(n, v) < 0.0) n = -n;
  bool probe = vv_exposureProbe != 0;
  vec3 color = in_ambient[c] * albedo * (probe ? 1.0 : vv_ambient_visibility(g_dataPos, n));
  for (int i = 0; i < vv_numLights; ++i)
  {
    vec3 l = vv_directionToLight(i, posDS);
#ifdef VV_MC_SHARE_LIGHT
    vec3 transmittance = vv_mcTransmittance[i];
#else
    vec3 transmittance = probe ? vec3(1.0) : vv_light_transmittance_rgb(i, g_dataPos, l);
#endif
    float ndl = 1.0;
    float spec = 0.0;
    if (oriented)
    {
      ndl = dot(n, l);
      vec3 h = normalize(l + v);
      float ndh = dot(n, h);
      ndl = max(ndl, 0.0);
      spec = ndl > 0.0 ? pow(max(ndh, 0.0), in_shininess[c]) : 0.0;
    }
    color += transmittance * vv_lightColor(i, posDS)
      * (in_diffuse[c] * ndl * albedo + in_specular[c] * spec);
  }
  color += vv_fill * albedo;
  return vv_exposure * (probe ? color : color + albedo * vv_irradiance(g_dataPos));
}

//@inject //VTK::ComputeLighting::Exit post replace
  finalColor.rgb = vv_shade(color.rgb, shading_gradient.xyz, lightingComponent);
