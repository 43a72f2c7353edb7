// vtkvol pre-integrated classification (seed 000 §4.1, seed 002 §5.2.1; docs/rendering.md,
// vtkvol/engine/preintegration.py). Injected by the host for RenderSettings.preintegration on
// one channel, composite blend, 1-D TF. Each sample classifies the segment from the previous
// sample (front, s_f) to this one (back, s_b) instead of the point: opacity and associated
// colour come from the 2-D table, which already integrates over the sample distance (VTK's
// opacity correction is not applied again: the table's diagonal is that correction).
// The wrapper is the innermost computeOpacity (injected before the slice weights and the
// corrected filter, which pass their weighted/corrected scalar through it). The colour the
// lighting receives is the segment's associated colour divided by its opacity (VTK multiplies
// by the opacity again when compositing).
// Uniforms:
//   sampler2D vv_piTable   R32F, N columns (s_b) × 4N rows: planes R, G, B, A of N rows (s_f)
// Define VV_PI_SIZE: N (float).

//@inject //VTK::ComputeOpacity::Dec pre after
float vv_piPrev = -1.0;  // TF coordinate of the previous sample; < 0: none (ray start, skip)
vec3 vv_piRGB = vec3(0.0);  // the current segment's colour (not associated)

// Plane `plane` of the table at (front, back), both 0…1 (texel centres at the ends).
float vv_piFetch(float front, float back, float plane)
{
  vec2 uv = vec2((0.5 + back * (VV_PI_SIZE - 1.0)) / VV_PI_SIZE,
                 (plane * VV_PI_SIZE + 0.5 + front * (VV_PI_SIZE - 1.0)) / (4.0 * VV_PI_SIZE));
  return texture(vv_piTable, uv).r;
}

float vv_piOpacity(vec4 scalar)
{
  float back = clamp(scalar.w, 0.0, 1.0);
  float front = vv_piPrev < 0.0 ? back : vv_piPrev;
  vv_piPrev = back;
  float a = vv_piFetch(front, back, 3.0);
  vec3 c = vec3(vv_piFetch(front, back, 0.0), vv_piFetch(front, back, 1.0),
                vv_piFetch(front, back, 2.0));
  vv_piRGB = a > 0.0 ? clamp(c / a, 0.0, 1.0) : vec3(0.0);
  return a;
}

// Stands for VTK's colour-table fetch in computeColor (a replaced literal): the segment's
// colour, already integrated.
vec4 vv_piColorTex(sampler2D table, vec2 coord) { return vec4(vv_piRGB, 1.0); }
#define computeOpacity vv_piOpacity

//@inject //VTK::PreComputeGradients::Impl pre before
// A skipped sample (empty space, crop, clipping) has no scalar: the next segment starts anew.
if (g_skip) vv_piPrev = -1.0;
