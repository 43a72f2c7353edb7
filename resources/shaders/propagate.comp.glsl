#version 430
// vtkvol technique "shadow_volume": compute passes that build the light volume.
// Compiled by VTK (vtkShaderProgram), dispatched by vtkvol via PyOpenGL; see
// plugins/shadow_volume/gpu.py (the driver) and cpu.py, which mirrors every formula here in
// numpy (the CPU path) and must be kept in step with this file. Tested with VTK 9.7.1 on Mesa
// llvmpipe (GL 4.5).
//
// The loader (shaders.compute_source) inserts #define lines after the #version line:
//   VV_PASS      0 = TF opacity -> extinction in place, 2 = reduction to a coarser light grid,
//                1 = propagate
//   VV_SEED000   1 = the thesis's additive clamped opacity model, 0 = transmittance
//   VV_CHANNELS  1, 2 or 4: channels of the light-volume texture (one light per channel)
//   VV_RADIUS    R: the neighbourhood filter has (2R + 2)^2 taps (seed000: R = 3, 8 x 8)
//   VV_BLOCK     cells along u per invocation: 1 (point lights) or more (directional lights)
//   VV_GROUP_X/Y work-group size of the propagation
//   VV_SIDE_FACES 1: finishCell handles rays that leave through a side face before the previous
//                slice; 0: it assumes every crossing lies inside the slice (the directional
//                block kernel: the driver recomputes the few edge cells with the one-cell kernel
//                in a second dispatch per slice). llvmpipe executes both arms of a divergent
//                branch under a mask, so the rare side-face arm (16 extra loads and an exp per
//                cell) would otherwise cost every cell.
//
// Spaces: "grid" = index space of the light grid (cell centres at integers, same point bounds
// as the data; cell edge vv_cellUm µm per axis, possibly anisotropic). Slices are planes of
// constant grid index along the propagation axis vv_axis; (u, v) are the two other axes in
// increasing order. Every pass processes one slice per dispatch, starting at the light.
//
// Units: vv_sigma holds the optical depth of one opacity unit distance, s = -ln(1 - alpha)
// (dimensionless); a path of L µm through it attenuates by exp(-s * L / unit_distance).

#ifndef VV_PASS
#define VV_PASS 1
#endif
#ifndef VV_SEED000
#define VV_SEED000 0
#endif
#ifndef VV_CHANNELS
#define VV_CHANNELS 1
#endif

#if VV_PASS == 0
// ---------------------------------------------------------------------------------------------
// Conversion in place, on the data grid: TF opacity alpha -> s = -ln(1 - alpha).
layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(r32f) uniform image3D vv_volume;
uniform ivec3 vv_dataDims;

const float MAX_OPACITY = 0.999999;

void main()
{
  ivec3 g = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(g, vv_dataDims)))
  {
    return;
  }
  float a = clamp(imageLoad(vv_volume, g).r, 0.0, MAX_OPACITY);
  imageStore(vv_volume, g, vec4(-log(1.0 - a)));
}

#elif VV_PASS == 2
// ---------------------------------------------------------------------------------------------
// Reduction to a coarser light grid: for every light-grid cell centre X (data index coordinates
// X = g * vv_gridStep), the average of s over the box of width vv_gridStep voxels centred on X,
// each data voxel weighted by the overlap of its cell [i - 0.5, i + 0.5] with the box (only
// voxels inside the data count). Averaging s (not alpha) keeps the optical depth of thin
// structures.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(r32f) uniform readonly image3D vv_sigmaData;   // s per data voxel (pass 0's output)
layout(r32f) uniform writeonly image3D vv_sigmaOut;
uniform ivec3 vv_dataDims;
uniform ivec3 vv_gridDims;
uniform vec3 vv_gridStep;                             // data voxels per grid cell, per axis

float overlap(int i, float centre, float halfWidth)
{
  float lo = max(float(i) - 0.5, centre - halfWidth);
  return max(0.0, min(float(i) + 0.5, centre + halfWidth) - lo);
}

void main()
{
  ivec3 g = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(g, vv_gridDims)))
  {
    return;
  }
  vec3 X = vec3(g) * vv_gridStep;
  vec3 halfW = 0.5 * max(vv_gridStep, vec3(1.0));
  ivec3 lo = max(ivec3(floor(X - halfW + 0.5)), ivec3(0));
  ivec3 hi = min(ivec3(ceil(X + halfW - 0.5)), vv_dataDims - 1);
  float sum = 0.0;
  float wsum = 0.0;
  for (int z = lo.z; z <= hi.z; ++z)
  {
    float wz = overlap(z, X.z, halfW.z);
    for (int y = lo.y; y <= hi.y; ++y)
    {
      float wzy = wz * overlap(y, X.y, halfW.y);
      for (int x = lo.x; x <= hi.x; ++x)
      {
        float w = wzy * overlap(x, X.x, halfW.x);
        sum += w * imageLoad(vv_sigmaData, ivec3(x, y, z)).r;
        wsum += w;
      }
    }
  }
  imageStore(vv_sigmaOut, g, vec4(wsum > 0.0 ? sum / wsum : 0.0));
}

#else
// ---------------------------------------------------------------------------------------------
// Propagation of one slice: one invocation per cell (or per VV_BLOCK cells of a row) of the
// slice. The previous slice lives in vv_work, a 2-layer image of exactly one slice's size
// (nu, nv, 2) for this propagation axis, layer = slice & 1. It stores the quantity whose value
// outside the volume is 0 (S, or 1 - W), because image loads outside an image return 0
// (GL 4.5 §8.26), so the tap loops need no bounds checks. The filter around the crossing P has
// (2R + 2)^2 taps with R a compile-time constant, so the loops unroll. (A shared-memory tile
// with a separable filter was several times slower on llvmpipe, where barrier() switches
// coroutines per SIMD batch.)
#ifndef VV_GROUP_X
#define VV_GROUP_X 8
#define VV_GROUP_Y 8
#endif
layout(local_size_x = VV_GROUP_X, local_size_y = VV_GROUP_Y, local_size_z = 1) in;

#ifndef VV_RADIUS
#define VV_RADIUS 0
#endif
#ifndef VV_BLOCK
#define VV_BLOCK 1
#endif
#ifndef VV_SIDE_FACES
#define VV_SIDE_FACES 1
#endif
#define NTAP (2 * VV_RADIUS + 2)

layout(r32f) uniform readonly image3D vv_sigma;    // s per light-grid cell
layout(r32f) uniform image3D vv_work;              // (u, v, slice & 1): S or 1 - W
#if VV_CHANNELS == 1
layout(r32f) uniform writeonly image3D vv_out;
#elif VV_CHANNELS == 2
layout(rg32f) uniform image3D vv_out;
#else
layout(rgba32f) uniform image3D vv_out;
#endif

uniform ivec3 vv_dims;       // light grid (x, y, z)
uniform int vv_axis;         // propagation axis a: 0, 1, 2
uniform int vv_sweep;        // +1 / -1: the order slices are processed in (away from the light)
uniform int vv_slice;        // index of this slice along a
uniform int vv_first;        // 1: the previous slice was not computed in this pass
uniform int vv_point;        // 1: vv_light is a position (grid); 0: a direction (grid units)
uniform vec3 vv_light;
uniform int vv_restrict;     // 1: store only cells whose dominant axis from the light is a
uniform vec3 vv_cellUm;      // grid cell edge per axis, µm
uniform float vv_invUnit;    // 1 / opacity unit distance, 1/µm
uniform float vv_gauss[VV_RADIUS + 1];  // normalised discrete Gaussian g(0..R) (transmittance)
uniform int vv_channel;      // output channel (light index)
uniform ivec2 vv_cellOrigin; // one-cell kernel: (u, v) of invocation (0, 0) (edge strips)

ivec3 gridPos(int u, int v, int k)
{
  return vv_axis == 0 ? ivec3(k, u, v) : (vv_axis == 1 ? ivec3(u, k, v) : ivec3(u, v, k));
}

float gauss(int k)
{
  k = abs(k);
  return k <= VV_RADIUS ? vv_gauss[k] : 0.0;
}

// Per-axis weights of the taps floor(p) - R + m, m = 0 .. 2R + 1, around the crossing p.
void tapWeights(float p, out float w[NTAP])
{
  float f = floor(p);
  float t = p - f;
  for (int m = 0; m < NTAP; ++m)
  {
#if VV_SEED000
    // The thesis: a unit Gaussian of the continuous distance to the crossing, 8 taps (R = 3),
    // not normalised (the truncated kernel sums to 0.9999).
    float x = f - float(VV_RADIUS) + float(m) - p;
    w[m] = 0.3989422804014327 * exp(-0.5 * x * x);
#else
    // Bilinear interpolation at the crossing followed by the discrete Gaussian blur: the
    // convolution of [1 - t, t] with g. Sums to 1, so empty space stays at T = 1.
    int k = m - VV_RADIUS;
    w[m] = (1.0 - t) * gauss(k) + t * gauss(k - 1);
#endif
  }
}

float sigmaAt(int u, int v, int k)
{
  return imageLoad(vv_sigma, gridPos(u, v, k)).r;   // 0 outside the grid
}

// s at in-plane position (pu, pv), a fraction lambda of the way from slice k to slice kp:
// trilinear, 0 outside the grid.
float sigmaBetween(float pu, float pv, float lambda, int k, int kp)
{
  int iu = int(floor(pu));
  int iv = int(floor(pv));
  float tu = pu - float(iu);
  float tv = pv - float(iv);
  float s00 = mix(sigmaAt(iu, iv, k), sigmaAt(iu, iv, kp), lambda);
  float s10 = mix(sigmaAt(iu + 1, iv, k), sigmaAt(iu + 1, iv, kp), lambda);
  float s01 = mix(sigmaAt(iu, iv + 1, k), sigmaAt(iu, iv + 1, kp), lambda);
  float s11 = mix(sigmaAt(iu + 1, iv + 1, k), sigmaAt(iu + 1, iv + 1, kp), lambda);
  return mix(mix(s00, s10, tu), mix(s01, s11, tu), tv);
}

bool insideSlice(float pu, float pv)
{
  int ua = vv_axis == 0 ? 1 : 0;
  int va = vv_axis == 2 ? 1 : 2;
  return pu >= 0.0 && pv >= 0.0 && pu <= float(vv_dims[ua] - 1) && pv <= float(vv_dims[va] - 1);
}

// This cell's step to the previous slice, in grid cells: along the ray towards the light, one
// slice along vv_axis. Next to a point light (less than a slice away) the in-plane part is
// capped at the light's in-plane offset.
vec3 stepToLight(ivec3 A)
{
  if (vv_point == 1)
  {
    vec3 d = vv_light - vec3(A);
    return d / max(abs(d[vv_axis]), 1.0);
  }
  return vv_light / abs(vv_light[vv_axis]);
}

// Everything after the filtered previous slice, for one cell A = (u, v) of slice k: its
// visibility, what it hands on to the next slice (vv_work) and, if this pass owns it, the
// output. acc: the filtered previous slice at P; sM: s at the segment's midpoint (used when P
// lies inside the slice).
void finishCell(int u, int v, int k, int kp, vec3 stepCells, float acc, float sA, float sM,
                bool prevInside, bool direct)
{
  int ua = vv_axis == 0 ? 1 : 0;
  int va = vv_axis == 2 ? 1 : 2;
  ivec3 A = gridPos(u, v, k);
  float stored;
  float vis;
#if VV_SEED000
  // S(A) = min(1, alpha(A) + sum g S_prev); the first slices hold their own opacity only.
  stored = min(1.0, (1.0 - exp(-sA)) + acc);
  vis = 1.0 - stored;
#else
  // Simpson's rule on each segment A -> P between two slices, of length ds µm (the oblique
  // path through one slice): optical depth (s(P) + 4 s(M) + s(A)) / 6 * ds / u, M the
  // midpoint, s trilinear there (exact for the trilinear interpolant inside one cell, so a 45°
  // ray that passes between cell centres still sees the cells beside it). A slice hands on
  // W = T exp(-s ds / 6u), the light that has passed the P-end share (stored as 1 - W and
  // interpolated at P), so T(A) = W(P) exp(-(4 s(M) + s(A)) / 6 * ds / u).
  float depthPerS = length(stepCells * vv_cellUm) * vv_invUnit;   // ds / u
  float pu = float(u) + stepCells[ua];
  float pv = float(v) + stepCells[va];
  if (!prevInside)
  {
    vis = 1.0;                                       // a face towards the light: T = 1
  }
  else if (direct)
  {
    // Point light less than one slice away: straight to the light through this cell's medium.
    vis = exp(-sA * length((vec3(A) - vv_light) * vv_cellUm) * vv_invUnit);
  }
#if VV_SIDE_FACES
  else if (insideSlice(pu, pv))
#else
  else   // the crossing lies inside the slice, or the cell is computed again (edge strips)
#endif
  {
    // clamp(): the weights sum to 1 only up to rounding.
    vis = clamp((1.0 - acc) * exp(-(4.0 * sM + sA) / 6.0 * depthPerS), 0.0, 1.0);
  }
#if VV_SIDE_FACES
  else
  {
    // The ray leaves through a side face before the previous slice, after a fraction f of the
    // segment: Simpson's rule on that part only, and nothing beyond.
    float f = 1.0;
    for (int i = 0; i < 2; ++i)
    {
      int b = i == 0 ? ua : va;
      float c = float(i == 0 ? u : v);
      float p = c + stepCells[b];
      float lim = float(vv_dims[b] - 1);
      if (p > lim) f = min(f, (lim - c) / stepCells[b]);
      if (p < 0.0) f = min(f, -c / stepCells[b]);
    }
    f = max(f, 0.0);
    float sMf = sigmaBetween(float(u) + 0.5 * f * stepCells[ua],
                             float(v) + 0.5 * f * stepCells[va], 0.5 * f, k, kp);
    float sE = sigmaBetween(float(u) + f * stepCells[ua], float(v) + f * stepCells[va], f, k,
                            kp);
    vis = exp(-(sA + 4.0 * sMf + sE) / 6.0 * f * depthPerS);
  }
#endif
  stored = 1.0 - vis * exp(-sA / 6.0 * depthPerS);
#endif
  imageStore(vv_work, ivec3(u, v, k & 1), vec4(stored));

#if VV_BLOCK == 1
  // Only the one-cell kernel serves point lights (the check costs every cell on llvmpipe).
  if (vv_restrict == 1)
  {
    // Point light: this pass owns the cells whose largest |A - L| component (grid cells) is
    // along its axis; ties go to the lower axis, so every cell is stored by exactly one pass.
    vec3 d = abs(vec3(A) - vv_light);
    float da = d[vv_axis];
    for (int b = 0; b < 3; ++b)
    {
      if (b != vv_axis && (b < vv_axis ? d[b] >= da : d[b] > da))
      {
        return;
      }
    }
  }
#endif
#if VV_CHANNELS == 1
  imageStore(vv_out, A, vec4(vis));
#else
  vec4 cur = imageLoad(vv_out, A);
  cur[vv_channel] = vis;
  imageStore(vv_out, A, cur);
#endif
}

#if VV_BLOCK == 1
// One cell per invocation (point lights: the crossing's offset differs per cell; directional
// lights: the edge strips of a slice whose rays leave through a side face, vv_cellOrigin).
void main()
{
  int ua = vv_axis == 0 ? 1 : 0;
  int va = vv_axis == 2 ? 1 : 2;
  int u = vv_cellOrigin.x + int(gl_GlobalInvocationID.x);
  int v = vv_cellOrigin.y + int(gl_GlobalInvocationID.y);
  if (u >= vv_dims[ua] || v >= vv_dims[va])
  {
    return;
  }
  int k = vv_slice;
  int kp = k - vv_sweep;                              // previous slice (towards the light)
  vec3 stepCells = stepToLight(gridPos(u, v, k));
  stepCells[vv_axis] = 1.0;   // one slice; only the length uses it (the sign is vv_sweep's)
  bool prevInside = kp >= 0 && kp < vv_dims[vv_axis];
  bool direct = vv_point == 1 && abs(vv_light[vv_axis] - float(k)) < 1.0;

  // Filtered previous slice at the crossing P = A + step: sum of w * (S or 1 - W), 0 outside
  // the slice. The volume ends at its outermost cell centres (as in the ray caster): a
  // crossing outside them means the ray has left the volume and nothing lies beyond (seed000
  // keeps the thesis's behaviour: taps outside read 0, those inside still count).
  float acc = 0.0;
  float pu = float(u) + stepCells[ua];
  float pv = float(v) + stepCells[va];
  if (prevInside && !direct && vv_first == 0 && (insideSlice(pu, pv) || VV_SEED000 == 1))
  {
    float wu[NTAP];
    float wv[NTAP];
    tapWeights(pu, wu);
    tapWeights(pv, wv);
    int u0 = int(floor(pu)) - VV_RADIUS;
    int v0 = int(floor(pv)) - VV_RADIUS;
    int layer = kp & 1;
    for (int j = 0; j < NTAP; ++j)
    {
      float row = 0.0;
      for (int i = 0; i < NTAP; ++i)
      {
        row += wu[i] * imageLoad(vv_work, ivec3(u0 + i, v0 + j, layer)).r;
      }
      acc += wv[j] * row;
    }
  }
  float sA = sigmaAt(u, v, k);
  float sM = 0.0;
#if !VV_SEED000
  if (prevInside && !direct)
  {
    sM = sigmaBetween(float(u) + 0.5 * stepCells[ua], float(v) + 0.5 * stepCells[va], 0.5, k,
                      kp);
  }
#endif
  finishCell(u, v, k, kp, stepCells, acc, sA, sM, prevInside, direct);
}

#else
// Directional light: VV_BLOCK consecutive cells along u per invocation. Every cell's crossing
// has the same offset, so the tap weights are shared and each loaded value serves up to
// NTAP cells: (2R + 2)(VV_BLOCK + 2R + 1) tap loads per block instead of (2R + 2)^2 per cell,
// and 4 (VV_BLOCK + 1) instead of 8 per cell for s at the midpoints.
void main()
{
  int ua = vv_axis == 0 ? 1 : 0;
  int va = vv_axis == 2 ? 1 : 2;
  int nu = vv_dims[ua];
  int ub = int(gl_GlobalInvocationID.x) * VV_BLOCK;
  int v = int(gl_GlobalInvocationID.y);
  if (ub >= nu || v >= vv_dims[va])
  {
    return;
  }
  int k = vv_slice;
  int kp = k - vv_sweep;
  vec3 stepCells = vv_light / abs(vv_light[vv_axis]);
  stepCells[vv_axis] = 1.0;
  bool prevInside = kp >= 0 && kp < vv_dims[vv_axis];
  float pv = float(v) + stepCells[va];

  float acc[VV_BLOCK];
  for (int i = 0; i < VV_BLOCK; ++i)
  {
    acc[i] = 0.0;
  }
  bool pvInside = pv >= 0.0 && pv <= float(vv_dims[va] - 1);
  if (prevInside && vv_first == 0 && (pvInside || VV_SEED000 == 1))
  {
    float pu = float(ub) + stepCells[ua];
    float wu[NTAP];
    float wv[NTAP];
    tapWeights(pu, wu);   // the same fractional part for every cell of the block
    tapWeights(pv, wv);
    int u0 = int(floor(pu)) - VV_RADIUS;
    int v0 = int(floor(pv)) - VV_RADIUS;
    int layer = kp & 1;
    for (int j = 0; j < NTAP; ++j)
    {
      float seg[VV_BLOCK + NTAP - 1];
      for (int m = 0; m < VV_BLOCK + NTAP - 1; ++m)
      {
        seg[m] = imageLoad(vv_work, ivec3(u0 + m, v0 + j, layer)).r;
      }
      for (int i = 0; i < VV_BLOCK; ++i)
      {
        float row = 0.0;
        for (int m = 0; m < NTAP; ++m)
        {
          row += wu[m] * seg[i + m];
        }
        acc[i] += wv[j] * row;
      }
    }
  }

  float sM[VV_BLOCK];
  float sA[VV_BLOCK];
  for (int i = 0; i < VV_BLOCK; ++i)
  {
    sM[i] = 0.0;
    sA[i] = sigmaAt(ub + i, v, k);
  }
#if !VV_SEED000
  if (prevInside)
  {
    // Trilinear s at the midpoints, a shared 2 x (VV_BLOCK + 1) x 2 neighbourhood.
    float mu = float(ub) + 0.5 * stepCells[ua];
    float mv = float(v) + 0.5 * stepCells[va];
    int iu = int(floor(mu));
    int iv = int(floor(mv));
    float tu = mu - float(iu);
    float tv = mv - float(iv);
    float col[VV_BLOCK + 1];
    for (int m = 0; m <= VV_BLOCK; ++m)
    {
      float r0 = sigmaAt(iu + m, iv, k) + sigmaAt(iu + m, iv, kp);
      float r1 = sigmaAt(iu + m, iv + 1, k) + sigmaAt(iu + m, iv + 1, kp);
      col[m] = 0.5 * mix(r0, r1, tv);
    }
    for (int i = 0; i < VV_BLOCK; ++i)
    {
      sM[i] = mix(col[i], col[i + 1], tu);
    }
  }
#endif
  for (int i = 0; i < VV_BLOCK; ++i)
  {
    int u = ub + i;
    if (u < nu)
    {
      float a = acc[i];
#if !VV_SEED000
      float pu = float(u) + stepCells[ua];
      a = pu >= 0.0 && pu <= float(nu - 1) ? a : 0.0;   // left the volume: nothing beyond
#endif
      finishCell(u, v, k, kp, stepCells, a, sA[i], sM[i], prevInside, false);
    }
  }
}
#endif
#endif
