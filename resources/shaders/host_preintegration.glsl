// vtkvol pre-integrated classification (seed 000 §4.1, seed 002 §5.2.1; docs/rendering.md,
// vtkvol/engine/preintegration.py). Injected by the host for RenderSettings.preintegration on
// one to four channels (independent components), composite blend, 1-D TF. Each sample
// classifies, per channel, the segment from the previous sample (front, s_f) to this one
// (back, s_b) instead of the point: opacity and associated colour come from that channel's 2-D
// table, which already integrates over the sample distance (VTK's opacity correction is not
// applied again: the table's diagonal is that correction). The channels' segments are then
// combined by VTK's own multi-component code (its mixing of color[i], untouched), exactly as
// it combines the per-channel samples without pre-integration.
// The wrapper is the innermost computeOpacity (injected before the slice weights and the
// corrected filter, which pass their weighted/corrected scalar through it). The colour the
// lighting receives is the segment's associated colour divided by its opacity (VTK multiplies
// by the opacity again when compositing).
// Uniforms:
//   sampler2D vv_piTable   R32F atlas, N columns (s_b) × 4CN rows: channel c's planes R, G, B,
//                          A are planes 4c…4c+3 of N rows (s_f) each
// Defines: VV_PI_SIZE: N (float); VV_PI_CHANNELS: C (1…4); VV_INDEPENDENT: independent
// components (computeOpacity(scalar, c), computeColor's fetch per component).

//@inject //VTK::ComputeOpacity::Dec pre after
// TF coordinate of each channel's previous sample; < 0: none (ray start, skip)
vec4 vv_piPrev = vec4(-1.0);
vec3 vv_piRGB[VV_PI_CHANNELS];  // each channel's current segment colour (not associated)

// Plane `plane` (4c + R/G/B/A) of the atlas at (front, back), both 0…1 (texel centres at the
// ends).
float vv_piFetch(float front, float back, float plane)
{
  vec2 uv = vec2((0.5 + back * (VV_PI_SIZE - 1.0)) / VV_PI_SIZE,
                 (plane * VV_PI_SIZE + 0.5 + front * (VV_PI_SIZE - 1.0))
                 / (4.0 * float(VV_PI_CHANNELS) * VV_PI_SIZE));
  return texture(vv_piTable, uv).r;
}

// Channel c's segment ending at TF coordinate `value`: its opacity; its colour in vv_piRGB[c].
float vv_piSegment(float value, int c)
{
  float back = clamp(value, 0.0, 1.0);
  float front = vv_piPrev[c] < 0.0 ? back : vv_piPrev[c];
  vv_piPrev[c] = back;
  float p = 4.0 * float(c);
  float a = vv_piFetch(front, back, p + 3.0);
  vec3 col = vec3(vv_piFetch(front, back, p), vv_piFetch(front, back, p + 1.0),
                  vv_piFetch(front, back, p + 2.0));
  vv_piRGB[c] = a > 0.0 ? clamp(col / a, 0.0, 1.0) : vec3(0.0);
  return a;
}

#ifdef VV_INDEPENDENT
float vv_piOpacity(vec4 scalar, int c) { return vv_piSegment(scalar[c], c); }
// Stands for VTK's colour-table fetch of component c in computeColor (a replaced literal):
// the channel's segment colour, already integrated.
vec4 vv_piColorTex(int c, sampler2D table, vec2 coord) { return vec4(vv_piRGB[c], 1.0); }
#else
float vv_piOpacity(vec4 scalar) { return vv_piSegment(scalar.w, 0); }
// Stands for VTK's colour-table fetch in computeColor (a replaced literal): the segment's
// colour, already integrated.
vec4 vv_piColorTex(sampler2D table, vec2 coord) { return vec4(vv_piRGB[0], 1.0); }
#endif
#define computeOpacity vv_piOpacity

//@inject //VTK::PreComputeGradients::Impl pre before
// A skipped sample (empty space, crop, clipping) has no scalar: the next segments start anew.
if (g_skip) vv_piPrev = vec4(-1.0);
