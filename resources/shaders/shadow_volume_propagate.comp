#version 430
// vtkvol technique "shadow_volume": compute passes that build the light volume.
// Compiled by VTK (vtkShaderProgram), dispatched by vtkvol via PyOpenGL; see
// plugins/shadow_volume.py, which mirrors every formula here in numpy (the CPU path) and must be
// kept in step with this file. Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// The host inserts #define lines after the #version line:
//   VV_PASS      0 = prefilter (TF opacity -> extinction on the light grid), 1 = propagate
//   VV_SEED000   1 = the thesis's additive clamped opacity model, 0 = transmittance
//   VV_CHANNELS  1, 2 or 4: channels of the light-volume texture (one light per channel)
//
// Spaces: "grid" = index space of the light grid (cell centres at integers, same point bounds
// as the data; cell edge vv_cellUm µm per axis, possibly anisotropic). Slices are planes of
// constant grid index along the propagation axis vv_axis; (u, v) are the two other axes in
// increasing order. Every pass processes one slice per dispatch; the previous slice (towards
// the light) lives in the 2-layer scratch image vv_work, indexed (u, v, slice & 1).
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
// Prefilter: for every light-grid cell centre X (data index coordinates X = g * vv_gridStep),
// the average of s over the box of width max(gridStep, 1) voxels centred on X, each data voxel
// weighted by the overlap of its cell [i - 0.5, i + 0.5] with the box (only voxels inside the
// data count). At full resolution this is the identity. Averaging s (not alpha) keeps the
// optical depth of thin structures when the grid is coarser than the data.
layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(r32f) uniform readonly image3D vv_alpha;    // TF opacity per data voxel
layout(r32f) uniform writeonly image3D vv_sigmaOut;
uniform ivec3 vv_dataDims;
uniform ivec3 vv_gridDims;
uniform vec3 vv_gridStep;                          // data voxels per grid cell, per axis

const float MAX_OPACITY = 0.999999;

float overlap(int i, float centre, float halfWidth)
{
  return max(0.0, min(float(i) + 0.5, centre + halfWidth) - max(float(i) - 0.5, centre - halfWidth));
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
        float a = clamp(imageLoad(vv_alpha, ivec3(x, y, z)).r, 0.0, MAX_OPACITY);
        sum += w * -log(1.0 - a);
        wsum += w;
      }
    }
  }
  imageStore(vv_sigmaOut, g, vec4(wsum > 0.0 ? sum / wsum : 0.0));
}

#else
// ---------------------------------------------------------------------------------------------
// Propagation of one slice. Each work group owns a TILE x TILE block of the slice. The rays
// from the block's cells towards the light cross the previous slice inside a footprint at most
// TILE + 2R + 1 cells wide per axis (the crossing moves by at most one cell per cell, see
// crossing()), which the group loads once into shared memory. The neighbourhood filter is
// separable because the crossing's u coordinate depends only on u (and v only on v) within a
// slice, for directional and point lights alike; so it runs as a u pass then a v pass:
// 2 * (2R + 2) multiply-adds per cell instead of (2R + 2)^2 image loads.
layout(local_size_x = 16, local_size_y = 16, local_size_z = 1) in;

#define TILE 16
#define RMAX 12
#define NTAPMAX (2 * RMAX + 2)
#define SPAN (TILE + 2 * RMAX + 2)

layout(r32f) uniform readonly image3D vv_sigma;    // s per light-grid cell
layout(r32f) uniform image3D vv_work;              // (u, v, slice & 1): T or S of two slices
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
uniform int vv_radius;       // R: taps floor(p) - R ... floor(p) + R + 1 per axis
uniform float vv_gauss[RMAX + 1];  // normalised discrete Gaussian g(0..R) (transmittance model)
uniform int vv_channel;      // output channel (light index)

shared float s_src[SPAN * SPAN];   // previous slice over the footprint, [row v][column u]
shared float s_row[SPAN * TILE];   // after the u pass, [row v][output column]

#if VV_SEED000
const float OUTSIDE = 0.0;   // accumulated opacity outside the volume (the thesis's imageLoad = 0)
#else
const float OUTSIDE = 1.0;   // transmittance outside the volume: nothing absorbs there
#endif

ivec3 gridPos(int u, int v, int k)
{
  return vv_axis == 0 ? ivec3(k, u, v) : (vv_axis == 1 ? ivec3(u, k, v) : ivec3(u, v, k));
}

// Coordinate along in-plane axis b where the ray from cell coordinate c of this slice towards
// the light crosses the previous slice. Only called when that slice lies between the cell and
// the light, so |vv_light[a] - slice| >= 1 for point lights: the crossing moves by 1 - 1/D <= 1
// cell per cell (directional: exactly 1).
float crossing(int c, int b)
{
  if (vv_point == 1)
  {
    return float(c) + (vv_light[b] - float(c)) / abs(vv_light[vv_axis] - float(vv_slice));
  }
  return float(c) + vv_light[b] / abs(vv_light[vv_axis]);
}

float gauss(int k)
{
  k = abs(k);
  return k <= vv_radius ? vv_gauss[k] : 0.0;
}

// Per-axis weights of the 2R + 2 taps floor(p) - R + m around the crossing p.
void tapWeights(float p, out float w[NTAPMAX])
{
  float f = floor(p);
  float t = p - f;
  for (int m = 0; m < 2 * vv_radius + 2; ++m)
  {
#if VV_SEED000
    // The thesis: a unit Gaussian of the continuous distance to the crossing, 8 taps (R = 3),
    // not normalised (the truncated kernel sums to 0.9999).
    float x = f - float(vv_radius) + float(m) - p;
    w[m] = 0.3989422804014327 * exp(-0.5 * x * x);
#else
    // Bilinear interpolation at the crossing followed by the discrete Gaussian blur: the
    // convolution of [1 - t, t] with g. Sums to 1, so empty space stays at T = 1.
    int k = m - vv_radius;
    w[m] = (1.0 - t) * gauss(k) + t * gauss(k - 1);
#endif
  }
}

float sigmaAt(int u, int v, int k, int nu, int nv)
{
  if (u < 0 || v < 0 || u >= nu || v >= nv)
  {
    return 0.0;
  }
  return imageLoad(vv_sigma, gridPos(u, v, k)).r;
}

void main()
{
  ivec2 lid = ivec2(gl_LocalInvocationID.xy);
  ivec2 base = ivec2(gl_WorkGroupID.xy) * TILE;
  int ua = vv_axis == 0 ? 1 : 0;
  int va = vv_axis == 2 ? 1 : 2;
  int nu = vv_dims[ua];
  int nv = vv_dims[va];
  int na = vv_dims[vv_axis];
  int k = vv_slice;
  int kp = k - vv_sweep;                              // previous slice (towards the light)
  bool prevInside = kp >= 0 && kp < na;
  bool direct = vv_point == 1 && abs(vv_light[vv_axis] - float(k)) < 1.0;
  bool useTaps = prevInside && !direct && vv_first == 0;
  int u = base.x + lid.x;
  int v = base.y + lid.y;
  int R = vv_radius;
  int ntap = 2 * R + 2;

  // All branches below depend on uniforms only, so every barrier is in uniform control flow.
  int fu0 = 0, fv0 = 0, fw = 0, fh = 0;
  float pu = float(u), pv = float(v);
  if (!direct && prevInside)
  {
    pu = crossing(u, ua);
    pv = crossing(v, va);
  }
  if (useTaps)
  {
    fu0 = int(floor(crossing(base.x, ua))) - R;
    fv0 = int(floor(crossing(base.y, va))) - R;
    fw = min(int(floor(crossing(base.x + TILE - 1, ua))) + R + 2 - fu0, SPAN);
    fh = min(int(floor(crossing(base.y + TILE - 1, va))) + R + 2 - fv0, SPAN);
    int layer = kp & 1;
    for (int i = lid.y * TILE + lid.x; i < fw * fh; i += TILE * TILE)
    {
      int cu = fu0 + i % fw;
      int cv = fv0 + i / fw;
      bool inside = cu >= 0 && cv >= 0 && cu < nu && cv < nv;
      s_src[i] = inside ? imageLoad(vv_work, ivec3(cu, cv, layer)).r : OUTSIDE;
    }
  }
  memoryBarrierShared();
  barrier();

  if (useTaps)
  {
    float w[NTAPMAX];
    tapWeights(pu, w);
    int first = int(floor(pu)) - R - fu0;
    for (int r = lid.y; r < fh; r += TILE)
    {
      float acc = 0.0;
      for (int m = 0; m < ntap; ++m)
      {
        acc += w[m] * s_src[r * fw + clamp(first + m, 0, fw - 1)];
      }
      s_row[r * TILE + lid.x] = acc;
    }
  }
  memoryBarrierShared();
  barrier();

  if (u >= nu || v >= nv)
  {
    return;
  }
  float prev = OUTSIDE;
  if (useTaps)
  {
    float w[NTAPMAX];
    tapWeights(pv, w);
    int first = int(floor(pv)) - R - fv0;
    prev = 0.0;
    for (int m = 0; m < ntap; ++m)
    {
      prev += w[m] * s_row[clamp(first + m, 0, fh - 1) * TILE + lid.x];
    }
  }

  ivec3 A = gridPos(u, v, k);
  float sA = imageLoad(vv_sigma, A).r;
  float value;
#if VV_SEED000
  // S(A) = min(1, alpha(A) + sum g S_prev): first slices hold their own opacity only.
  value = min(1.0, (1.0 - exp(-sA)) + prev);
  float vis = 1.0 - value;
#else
  if (!prevInside)
  {
    value = 1.0;                                     // a face towards the light: T = 1
  }
  else if (direct)
  {
    // Point light less than one slice away: straight to the light through this cell's medium.
    value = exp(-sA * length((vec3(A) - vv_light) * vv_cellUm) * vv_invUnit);
  }
  else
  {
    // T(A) = T(P) * exp(-(s(A) + s(P)) / 2 * ds / u): trapezoid rule on the segment A -> P,
    // ds its length in µm (the oblique path through one slice), s(P) bilinear in the slice.
    int iu = int(floor(pu));
    int iv = int(floor(pv));
    float tu = pu - float(iu);
    float tv = pv - float(iv);
    float sP = mix(mix(sigmaAt(iu, iv, kp, nu, nv), sigmaAt(iu + 1, iv, kp, nu, nv), tu),
                   mix(sigmaAt(iu, iv + 1, kp, nu, nv), sigmaAt(iu + 1, iv + 1, kp, nu, nv), tu),
                   tv);
    vec3 stepCells = vec3(0.0);
    stepCells[ua] = pu - float(u);
    stepCells[va] = pv - float(v);
    stepCells[vv_axis] = 1.0;
    float ds = length(stepCells * vv_cellUm);
    value = min(1.0, prev * exp(-0.5 * (sA + sP) * ds * vv_invUnit));  // rounding of sum(w)
  }
  float vis = value;
#endif
  imageStore(vv_work, ivec3(u, v, k & 1), vec4(value));

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
#if VV_CHANNELS == 1
  imageStore(vv_out, A, vec4(vis));
#else
  vec4 cur = imageLoad(vv_out, A);
  cur[vv_channel] = vis;
  imageStore(vv_out, A, cur);
#endif
}
#endif
