// vtkvol host lighting, "medium" model: emission-absorption with scattering, no gradient.
// Replaces VTK's shading result per shaded sample; VTK's loop then multiplies by the step
// opacity, so a sample contributes alpha_step * C. Tested with VTK 9.7.1.
//
// Shading formula (docs/architecture.md, "Lighting models"):
//   C = a * albedo * ( ka * A(x) + sum_i T_i(x) * E_i(x) * 4pi p(cos theta_i) + S(x) )
//   a: single-scattering albedo (vv_albedo), albedo: the transfer function's colour, A: ambient
//   visibility, T_i: RGB transmittance towards light i, E_i: light colour * intensity (with
//   inverse-square fall-off where asked), p: Henyey-Greenstein phase function with asymmetry g
//   (vv_phaseG; g = 0 is isotropic, 4pi p = 1), theta_i: angle between the light's propagation
//   direction (-l_i) and the direction to the viewer, S: in-scattered irradiance from the
//   technique (multiple scattering), 0 by default; the bracket is clamped at 0. ka comes from the
//   vtkVolumeProperty. The bracket also holds the sky fill F (vv_fill, never attenuated), and C
//   is multiplied by the exposure (vv_exposure). With vv_exposureProbe = 1: T_i = A = 1, S = 0
//   (the automatic exposure's reference, vtkvol/engine/exposure.py).
//
// Range: VTK clamps every shaded sample to [0, 1] (computeColor: clamp(computeLighting(..))),
// which darkens the image wherever a * albedo * (ka + sum T E + S + F) exceeds 1 per sample
// (a lit sample with in-scattered light: measured 30 levels darker in red than the camera path
// tracer at a = 1, ka = 0.8). The model has no such clamp, and only the composite should meet
// the display's range: C is handed to VTK divided by VV_MEDIUM_RANGE, and the composite is
// multiplied by it again once the ray ends (finalizeRayCast), where the framebuffer clamps it.

//@inject //VTK::ComputeLighting::Dec pre before
// Headroom of a shaded sample above VTK's [0, 1] clamp (see "Range" above).
#define VV_MEDIUM_RANGE 64.0
// 4pi times the Henyey-Greenstein phase function: 1 for g = 0, normalised over the sphere.
float vv_phase4pi(float cosTheta, float g)
{
  float denom = 1.0 + g * g - 2.0 * g * cosTheta;
  return (1.0 - g * g) / (denom * sqrt(denom));
}

vec3 vv_shade_medium(vec3 albedo, int c)
{
  vec3 posDS = vv_texToDataset(g_dataPos);
  vec3 v = normalize(in_eyePosObjs[0].xyz - posDS);
  bool probe = vv_exposureProbe != 0;
  vec3 light = in_ambient[c]
    * vec3(probe ? 1.0 : vv_ambient_visibility(g_dataPos, vec3(0.0))) + vec3(vv_fill);
  for (int i = 0; i < vv_numLights; ++i)
  {
    vec3 l = vv_directionToLight(i, posDS);
    vec3 transmittance = probe ? vec3(1.0) : vv_light_transmittance_rgb(i, g_dataPos, l);
    light += transmittance * vv_lightColor(i, posDS) * vv_phase4pi(dot(-l, v), vv_phaseG);
  }
  // Diffusion-type techniques hand back scattered light that can be negative where it moves
  // light away from a peak; the total received is never negative.
  vec3 scattered = probe ? vec3(0.0) : vv_irradiance(g_dataPos);
  return vv_exposure * vv_albedo * albedo * max(light + scattered, vec3(0.0))
    * (1.0 / VV_MEDIUM_RANGE);
}

//@inject //VTK::ComputeLighting::Exit post replace
  finalColor.rgb = vv_shade_medium(color.rgb, lightingComponent);

//@inject //VTK::Base::Exit pre before
  // the composite of samples shaded at 1/VV_MEDIUM_RANGE (alpha is untouched)
  g_fragColor.rgb *= VV_MEDIUM_RANGE;
