// vtkvol multi-channel sample: VTK's per-component work with constant component indices, and one
// set of gradient fetches for every component. Injected by the host for independent components
// (two to four channels) on a composite blend. Same arithmetic as VTK's template, so the image
// is VTK's own (docs/benchmarks.md, "Multi-channel frames"). Tested with VTK 9.7.
//
// Why: VTK classifies and shades the components in a loop over `i < in_noOfComponents` (a
// uniform), calling computeOpacity(scalar, i) and computeColor(scalar, a, i), whose bodies are
// `if (component == 0) {…} if (component == 1) {…}`. With `i` unknown at compile time every
// branch is code the GPU may run: llvmpipe runs each under a lane mask, so each call does the
// work of every component (two channels: 4 TF lookups and 4 lightings per sample instead of
// 2). vv_mcClassify makes the same calls with literal indices, so the branches fold away, and
// VTK's first loop is emptied by the host (its compositing loop is kept, with the channel
// mixing the scene chose).
//
// VV_MC_SHARE_GRADIENT (shaded, no gradient opacity, no volumetric scattering, no corrected
// trilinear filter, which shares its own fetches): computeGradient(g_dataPos, c, …) reads
// component c of six neighbour fetches made once per sample instead of six per component;
// the neighbours are VTK's own (± in_cellStep), so the gradient is VTK's.
//
// VV_MC_SHARE_LIGHT (shaded, surface lighting; defined in host_lighting.glsl's load): the
// transmittance towards each light, which depends on the position only, is evaluated once per
// sample (vv_mcLights) instead of once per component.
//
// VV_MC_SHARED_LIGHTING (RenderSettings.multichannel_lighting = "shared"): the channels are
// classified unlit and the sample is lit once (host_multichannel_lighting.glsl, loaded after
// this file, defines vv_mcShareLighting).
//
// Defines: VV_MC_COMPONENTS (2, 3 or 4); VV_MC_SHARE_GRADIENT; VV_MC_SHARE_LIGHT;
// VV_MC_SHARED_LIGHTING.

//@inject //VTK::ComputeGradient::Dec pre after
#ifdef VV_MC_SHARE_GRADIENT
vec4 vv_mcXp, vv_mcXm, vv_mcYp, vv_mcYm, vv_mcZp, vv_mcZm;  // raw fetches at p ± in_cellStep

void vv_mcNeighbours()
{
  vec3 s = in_cellStep[0];
  vv_mcXp = texture(in_volume[0], g_dataPos + vec3(s.x, 0.0, 0.0));
  vv_mcXm = texture(in_volume[0], g_dataPos - vec3(s.x, 0.0, 0.0));
  vv_mcYp = texture(in_volume[0], g_dataPos + vec3(0.0, s.y, 0.0));
  vv_mcYm = texture(in_volume[0], g_dataPos - vec3(0.0, s.y, 0.0));
  vv_mcZp = texture(in_volume[0], g_dataPos + vec3(0.0, 0.0, s.z));
  vv_mcZm = texture(in_volume[0], g_dataPos - vec3(0.0, 0.0, s.z));
}

// VTK's computeGradient (central differences, scaled like VTK's, dummy magnitude -1) from the
// shared fetches. computeLighting calls it only at (g_dataPos, volume 0).
vec4 vv_mcGradient(in vec3 texPos, in int c, in sampler3D volume, in int index)
{
  vec3 g1 = vec3(vv_mcXp[c], vv_mcYp[c], vv_mcZp[c]);
  vec3 g2 = vec3(vv_mcXm[c], vv_mcYm[c], vv_mcZm[c]);
  g1 = g1 * in_volume_scale[0][c] + in_volume_bias[0][c];
  g2 = g2 * in_volume_scale[0][c] + in_volume_bias[0][c];
  return vec4((g1 - g2) / in_cellSpacing[0], -1.0);
}
#define computeGradient vv_mcGradient
#endif

//@inject //VTK::ComputeColor::Dec pre after
#ifdef VV_MC_SHARED_LIGHTING
void vv_mcShareLighting(inout vec4 color[4], float totalAlpha);
#endif

// VTK's classification loop body for each component, indices literal. `scalar` is VTK's
// (scaled) sample; computeOpacity/computeColor are whatever the host wrapped them into (slice
// weights, corrected trilinear filter).
void vv_mcClassify(vec4 scalar, inout vec4 color[4], inout float totalAlpha)
{
#ifdef VV_MC_SHARE_GRADIENT
  vv_mcNeighbours();
#endif
#ifdef VV_MC_SHARE_LIGHT
  vv_mcLights();
#endif
  color[0][3] = computeOpacity(scalar, 0);
  color[0] = computeColor(scalar, color[0][3], 0);
  totalAlpha += color[0][3] * in_componentWeight[0];
  color[1][3] = computeOpacity(scalar, 1);
  color[1] = computeColor(scalar, color[1][3], 1);
  totalAlpha += color[1][3] * in_componentWeight[1];
#if VV_MC_COMPONENTS > 2
  color[2][3] = computeOpacity(scalar, 2);
  color[2] = computeColor(scalar, color[2][3], 2);
  totalAlpha += color[2][3] * in_componentWeight[2];
#endif
#if VV_MC_COMPONENTS > 3
  color[3][3] = computeOpacity(scalar, 3);
  color[3] = computeColor(scalar, color[3][3], 3);
  totalAlpha += color[3][3] * in_componentWeight[3];
#endif
#ifdef VV_MC_SHARED_LIGHTING
  vv_mcShareLighting(color, totalAlpha);
#endif
}
