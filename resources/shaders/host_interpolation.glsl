// vtkvol corrected trilinear reconstruction (Csébfalvi; seed 001 §2.6, eq. 2.55 with the ½ that
// eq. 2.52 lacks). Injected by the host only for RenderSettings.interpolation = "corrected" on
// a composite blend; docs/reconstruction.md has the derivation and the measurements.
//
// At the sample p = g_dataPos (texture space), in voxel coordinates p = (i+α, j+β, k+γ):
//   f(p)  = VTK's own (hardware trilinear) sample, already scaled to its TF coordinate
//   s_a   = f(p − e_a) − 2 f(p) + f(p + e_a)        a = x, y, z; e_a = exactly one voxel
//   f̃(p) = f(p) + s_x (α²−α)/2 + s_y (β²−β)/2 + s_z (γ²−γ)/2
// f̃ replaces the scalar given to computeOpacity and computeColor (the TF lookups clamp the
// overshoot f̃ can have, as Catmull-Rom does). The six neighbour fetches are made once per
// sample at //VTK::PreComputeGradients::Impl (top of the loop body, before VTK's own fetch);
// the per-component calls and computeGradient reuse them.
//
// Shaded (VV_IP_SHARE_GRADIENT): computeGradient at the sample returns the central difference
// of the same six fetches, so the correction costs no extra fetch. VTK's own gradient steps by
// in_cellStep = 1/(N−1) (≈ N/(N−1) voxels), the correction needs exactly one voxel (1/N), so in
// this mode the normal is the one-voxel central difference: the same direction VTK intends,
// from fetches 1/N instead of 1/(N−1) apart.
//
// Defines: VV_INDEPENDENT (independent components: computeOpacity(scalar, c),
// computeColor(scalar, a, c)); VV_IP_SHARE_GRADIENT (shaded, no gradient opacity).
// Must come after host_slice_weights.glsl, which also wraps computeOpacity.

//@inject //VTK::ComputeOpacity::Dec pre after
// Six named globals and no branch: llvmpipe runs both sides of a branch under a lane mask, so
// a memoising `if` or a fallback would execute the fetches it meant to skip; and dynamically
// indexed arrays spill to memory.
vec4 vv_ipXp, vv_ipXm, vv_ipYp, vv_ipYm, vv_ipZp, vv_ipZm;  // scaled samples at p ± e_a

vec4 vv_ipFetch(vec3 texPos)
{
  return texture(in_volume[0], texPos) * in_volume_scale[0] + in_volume_bias[0];
}

// The six one-voxel neighbours of g_dataPos, fetched once per sample at the top of the loop
// body. One voxel in texture space is 1/N = 2·texMin (point data: voxel centres at (i+0.5)/N).
void vv_ipNeighbours()
{
  vec3 voxel = 2.0 * in_texMin[0];
  vv_ipXp = vv_ipFetch(g_dataPos + vec3(voxel.x, 0.0, 0.0));
  vv_ipXm = vv_ipFetch(g_dataPos - vec3(voxel.x, 0.0, 0.0));
  vv_ipYp = vv_ipFetch(g_dataPos + vec3(0.0, voxel.y, 0.0));
  vv_ipYm = vv_ipFetch(g_dataPos - vec3(0.0, voxel.y, 0.0));
  vv_ipZp = vv_ipFetch(g_dataPos + vec3(0.0, 0.0, voxel.z));
  vv_ipZm = vv_ipFetch(g_dataPos - vec3(0.0, 0.0, voxel.z));
}

// f̃ at g_dataPos from VTK's sample there (`scalar`, scaled) and the cached neighbours; every
// component is corrected with the same weights (the filter is linear).
vec4 vv_corrected(vec4 scalar)
{
  vec3 voxel = 2.0 * in_texMin[0];
  vec3 t = fract((g_dataPos - in_texMin[0]) / voxel);
  vec3 w = 0.5 * (t * t - t);
#ifdef VV_INDEPENDENT
  return scalar + (vv_ipXm - 2.0 * scalar + vv_ipXp) * w.x
                + (vv_ipYm - 2.0 * scalar + vv_ipYp) * w.y
                + (vv_ipZm - 2.0 * scalar + vv_ipZp) * w.z;
#else
  // One component: VTK passes vec4(f) and reads .w; the fetches hold f in .r.
  float f0 = scalar.r;
  return vec4(f0 + (vv_ipXm.r - 2.0 * f0 + vv_ipXp.r) * w.x
                 + (vv_ipYm.r - 2.0 * f0 + vv_ipYp.r) * w.y
                 + (vv_ipZm.r - 2.0 * f0 + vv_ipZp.r) * w.z);
#endif
}

#ifdef VV_INDEPENDENT
float vv_ipOpacity(vec4 scalar, int c) { return computeOpacity(vv_corrected(scalar), c); }
#else
float vv_ipOpacity(vec4 scalar) { return computeOpacity(vv_corrected(scalar)); }
#endif
#undef computeOpacity
#define computeOpacity vv_ipOpacity

//@inject //VTK::PreComputeGradients::Impl pre before
vv_ipNeighbours();

//@inject //VTK::ComputeGradient::Dec pre after
#ifdef VV_IP_SHARE_GRADIENT
// The shading gradient from the six cached fetches (scaled, as VTK scales its own). VTK's
// computeLighting calls computeGradient only at (g_dataPos, volume 0); the host defines
// VV_IP_SHARE_GRADIENT only where that is all (no gradient opacity, no volumetric shadows).
vec4 vv_ipGradient(in vec3 texPos, in int c, in sampler3D volume, in int index)
{
  vec3 g1 = vec3(vv_ipXp[c], vv_ipYp[c], vv_ipZp[c]);
  vec3 g2 = vec3(vv_ipXm[c], vv_ipYm[c], vv_ipZm[c]);
  return vec4((g1 - g2) / in_cellSpacing[0], -1.0);
}
#define computeGradient vv_ipGradient
#endif

//@inject //VTK::ComputeColor::Dec pre after
#ifdef VV_INDEPENDENT
vec4 vv_ipColor(vec4 scalar, float opacity, int c)
{
  return computeColor(vv_corrected(scalar), opacity, c);
}
#else
vec4 vv_ipColor(vec4 scalar, float opacity) { return computeColor(vv_corrected(scalar), opacity); }
#endif
#define computeColor vv_ipColor
