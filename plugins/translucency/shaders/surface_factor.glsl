// vtkvol technique "translucency": the surface model with Kniss's surface-shading factor
// S(t) (seed 001 eq. 2.44, C(t) = g(t)·((1 − S) + f_s·S)) instead of the host's binary rule.
// Loaded only when VTK builds its shaded computeLighting() and surface_factor = gradient
// (technique.py). Tested with VTK 9.7.1.
//
// The host's formula (resources/shaders/host_lighting.glsl) with n·l and the specular term
// blended by S: an unoriented sample (S = 0) is lit as the host lights homogeneous interiors
// (n·l := 1, no specular), an oriented one (S = 1) by Blinn–Phong, so S = 1 wherever the
// gradient is not zero gives the host's image exactly. This technique computes no ambient
// occlusion and no in-scattered irradiance (the host's defaults, 1 and 0, are written in).
// Like the host's, the result includes the sky fill (vv_fill) and the exposure (vv_exposure);
// vv_exposureProbe = 1 lights it unobstructed (the automatic exposure's reference).

//@inject //VTK::ComputeLighting::Dec pre before
vec3 vv_translucency_shade(vec3 albedo, vec3 gradientDS, int c)
{
  vec3 posDS = vv_texToDataset(g_dataPos);
  float glen = length(gradientDS);
  bool oriented = glen > 1e-12;
  // VTK's shading gradient is the central difference over two cells divided by one cell's
  // spacing (µm): half of it times the spacing is the change per voxel along each axis.
  float S = oriented ? vv_translucency_surfaceFactor(0.5 * length(gradientDS
                                                                  * in_cellSpacing[0])) : 0.0;
  vec3 n = oriented ? -gradientDS / glen : vec3(0.0);
  vec3 v = normalize(in_eyePosObjs[0].xyz - posDS);
  if (in_twoSidedLighting && dot(n, v) < 0.0) n = -n;
  bool probe = vv_exposureProbe != 0;
  vec3 color = (in_ambient[c] + vv_fill) * albedo;
  for (int i = 0; i < vv_numLights; ++i)
  {
    vec3 l = vv_directionToLight(i, posDS);
    vec3 transmittance = probe ? vec3(1.0) : vv_light_transmittance_rgb(i, g_dataPos, l);
    float ndl = 0.0;
    float spec = 0.0;
    if (oriented)
    {
      ndl = max(dot(n, l), 0.0);
      vec3 h = normalize(l + v);
      spec = ndl > 0.0 ? pow(max(dot(n, h), 0.0), in_shininess[c]) : 0.0;
    }
    color += transmittance * vv_lightColor(i, posDS)
      * (in_diffuse[c] * mix(1.0, ndl, S) * albedo + S * in_specular[c] * spec);
  }
  return vv_exposure * color;
}

//@inject //VTK::ComputeLighting::Exit post after
  finalColor.rgb = vv_translucency_shade(color.rgb, shading_gradient.xyz, lightingComponent);
