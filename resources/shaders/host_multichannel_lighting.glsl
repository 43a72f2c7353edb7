// vtkvol multi-channel sample, RenderSettings.multichannel_lighting = "shared": every channel is
// classified unlit and the sample is lit ONCE, by the technique's own lighting (VTK's
// computeLighting with the host's and the technique's replacement at ComputeLighting::Exit:
// every light, the transmittance / light-visibility hooks, ambient visibility, in-scattered
// irradiance), evaluated on the sample's mixed colour with one normal and one material.
// Injected by the host after host_multichannel.glsl (which calls vv_mcShareLighting) where the
// lighting runs per sample: shaded surface lighting with a shared gradient, or the medium
// model. Tested with VTK 9.7.1.
//
// Per sample, with w_c = alpha_c * in_componentWeight[c] / sum_k alpha_k * in_componentWeight[k]
// (the weights VTK's compositing loop gives each channel's colour):
//   albedo   = sum_c w_c * albedo_c                   (the channels' TF colours, unlit)
//   n        = normalize(sum_c w_c * n_c)             n_c: channel c's outward unit normal, VTK's
//                                                     -normalize(gradient_c), turned towards the
//                                                     viewer first with two-sided lighting
//   |grad|   = sum_c w_c * |gradient_c * spacing|     (the magnitude translucency's surface
//                                                     factor reads; the host's shading ignores it)
//   ka, kd, ks, p = sum_c w_c * (channel c's value)   (the material)
//   colour   = clamp(computeLighting(albedo), 0, 1), given to every channel
// VTK's compositing loop then weighs that colour with each channel's opacity exactly as it
// weighs per-channel colours, with the scene's channel mixing (which only changes alpha).
// Surface lighting is affine in the albedo (ambient and diffuse scale it, specular adds), so
// this equals lighting every channel with the shared normal and material and mixing the
// results (up to VTK's per-channel clamp); where one channel is visible at a sample it is
// that channel's own lighting. The medium model has no normal: there only the material (ka) is
// mixed. Why the normal is the weighted sum of unit normals and not the gradient of the
// combined opacity: it needs no more fetches than the shared six (the opacity's gradient would
// take six opacity lookups per channel), it is the channel's own normal wherever one channel
// shows, and channels whose data differ in range by orders of magnitude weigh by what is seen
// (their opacity), not by their units.
//
// Defines: VV_MC_SHARED_NORMAL (surface model: build the combined gradient);
// VV_MC_CHANNEL_GRADIENT (the per-channel gradient from the shared fetches: vv_mcGradient or
// vv_ipGradient). VV_MC_COMPONENTS comes from host_multichannel.glsl.

//@inject //VTK::ComputeLighting::Dec pre before
// The mixed material, read by the lighting through the macros below (index 0 is the one used:
// vv_mcShareLighting lights as component 0; all four are filled so no index reads garbage).
vec3 vv_mcAmbient[4];
vec3 vv_mcDiffuse[4];
vec3 vv_mcSpecular[4];
float vv_mcShininess[4];

void vv_mcMixMaterial(vec4 w)
{
  vec3 ka = w[0] * in_ambient[0] + w[1] * in_ambient[1];
  vec3 kd = w[0] * in_diffuse[0] + w[1] * in_diffuse[1];
  vec3 ks = w[0] * in_specular[0] + w[1] * in_specular[1];
  float p = w[0] * in_shininess[0] + w[1] * in_shininess[1];
#if VV_MC_COMPONENTS > 2
  ka += w[2] * in_ambient[2]; kd += w[2] * in_diffuse[2];
  ks += w[2] * in_specular[2]; p += w[2] * in_shininess[2];
#endif
#if VV_MC_COMPONENTS > 3
  ka += w[3] * in_ambient[3]; kd += w[3] * in_diffuse[3];
  ks += w[3] * in_specular[3]; p += w[3] * in_shininess[3];
#endif
  for (int c = 0; c < 4; ++c)
  {
    vv_mcAmbient[c] = ka;
    vv_mcDiffuse[c] = kd;
    vv_mcSpecular[c] = ks;
    vv_mcShininess[c] = p;
  }
}

// Until computeColor: the lighting code (VTK's computeLighting, the host's and the technique's
// shading functions) reads the mixed material.
#define in_ambient vv_mcAmbient
#define in_diffuse vv_mcDiffuse
#define in_specular vv_mcSpecular
#define in_shininess vv_mcShininess

#ifdef VV_MC_SHARED_NORMAL
// The combined gradient (dataset space, VTK's orientation: pointing into the structure), set
// once per sample before the one lighting call, which asks for it through computeGradient.
vec4 vv_mcSharedGradient;

vec4 vv_mcSharedGradientAt(in vec3 texPos, in int c, in sampler3D volume, in int index)
{
  return vv_mcSharedGradient;
}
#undef computeGradient
#define computeGradient vv_mcSharedGradientAt
#endif

//@inject //VTK::ComputeColor::Dec pre before
#undef in_ambient
#undef in_diffuse
#undef in_specular
#undef in_shininess
#ifdef VV_MC_SHARED_NORMAL
#undef computeGradient
#define computeGradient VV_MC_CHANNEL_GRADIENT
#endif

// computeColor classifies unlit: its computeLighting call returns the TF colour as it is.
vec4 vv_mcUnlit(vec4 color, int component, float label)
{
  return color;
}
#define computeLighting vv_mcUnlit

//@inject //VTK::ComputeColor::Dec pre after
#undef computeLighting

#ifdef VV_MC_SHARED_NORMAL
// Channel c's outward unit normal as the host's shading builds it (VTK's normalised gradient,
// negated; zero where the gradient is zero), turned towards the viewer with two-sided lighting.
vec3 vv_mcNormal(vec3 gradientDS, vec3 toViewer)
{
  float len = length(gradientDS);
  vec3 n = len > 0.0 ? -gradientDS / len : vec3(0.0);
  return (in_twoSidedLighting && dot(n, toViewer) < 0.0) ? -n : n;
}

vec4 vv_mcCombinedGradient(vec4 w)
{
  vec3 toViewer = normalize(in_eyePosObjs[0].xyz - vv_texToDataset(g_dataPos));
  vec3 spacing = in_cellSpacing[0];
  vec3 g = VV_MC_CHANNEL_GRADIENT(g_dataPos, 0, in_volume[0], 0).xyz;
  vec3 normal = w[0] * vv_mcNormal(g, toViewer);
  float magnitude = w[0] * length(g * spacing);
  g = VV_MC_CHANNEL_GRADIENT(g_dataPos, 1, in_volume[0], 0).xyz;
  normal += w[1] * vv_mcNormal(g, toViewer);
  magnitude += w[1] * length(g * spacing);
#if VV_MC_COMPONENTS > 2
  g = VV_MC_CHANNEL_GRADIENT(g_dataPos, 2, in_volume[0], 0).xyz;
  normal += w[2] * vv_mcNormal(g, toViewer);
  magnitude += w[2] * length(g * spacing);
#endif
#if VV_MC_COMPONENTS > 3
  g = VV_MC_CHANNEL_GRADIENT(g_dataPos, 3, in_volume[0], 0).xyz;
  normal += w[3] * vv_mcNormal(g, toViewer);
  magnitude += w[3] * length(g * spacing);
#endif
  float len = length(normal);
  if (len <= 1e-6)
  {
    return vec4(0.0, 0.0, 0.0, -1.0);  // opposed normals cancel: lit as an unoriented medium
  }
  vec3 direction = -normal / len;
  return vec4(direction * (magnitude / length(direction * spacing)), -1.0);
}
#endif

// Light the sample once (see the top of the file); every channel gets the lit mixed colour.
void vv_mcShareLighting(inout vec4 color[4], float totalAlpha)
{
  if (totalAlpha <= 0.0)
  {
    return;  // nothing visible here: VTK's loop adds nothing
  }
  vec4 w = vec4(color[0][3] * in_componentWeight[0], color[1][3] * in_componentWeight[1],
                0.0, 0.0);
#if VV_MC_COMPONENTS > 2
  w[2] = color[2][3] * in_componentWeight[2];
#endif
#if VV_MC_COMPONENTS > 3
  w[3] = color[3][3] * in_componentWeight[3];
#endif
  // llvmpipe runs this for the lanes that returned above too (under a mask): keep them free
  // of NaN, and give them the channels' mean normal, as cheap to light as a visible sample.
  w = totalAlpha > 0.0 ? w / totalAlpha : vec4(1.0 / float(VV_MC_COMPONENTS));
  vec3 albedo = w[0] * color[0].rgb + w[1] * color[1].rgb;
#if VV_MC_COMPONENTS > 2
  albedo += w[2] * color[2].rgb;
#endif
#if VV_MC_COMPONENTS > 3
  albedo += w[3] * color[3].rgb;
#endif
  vv_mcMixMaterial(w);
#ifdef VV_MC_SHARED_NORMAL
  vv_mcSharedGradient = vv_mcCombinedGradient(w);
#endif
  vec3 lit = clamp(computeLighting(vec4(albedo, 1.0), 0, 0.0).rgb, 0.0, 1.0);
  color[0].rgb = lit;
  color[1].rgb = lit;
#if VV_MC_COMPONENTS > 2
  color[2].rgb = lit;
#endif
#if VV_MC_COMPONENTS > 3
  color[3].rgb = lit;
#endif
}
