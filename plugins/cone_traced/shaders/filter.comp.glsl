#version 430
// vtkvol technique "cone_traced": compute shaders that build the filtered-opacity mip chain.
// Compiled by vtkvol.plugins.cone_traced.gpu.GpuFilter (one program per VV_PASS value and blur
// radius; the loader inserts the VV_* defines after #version), dispatched with PyOpenGL.
// Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Spaces: integer texel coordinates of one mip level, (x, y, z). Every pass reads a level
// with imageLoad (no filtering, no texture units) and writes one level with imageStore.
// Everything outside the volume is empty (zero), as in the CPU path
// (plugins/cone_traced/cpu.py).
// Each invocation walks a whole line of texels: on llvmpipe the cost is per invocation and per
// gathered load, so long loops with one load per output are several times faster than one
// invocation per texel.
//
// VV_PASS 0, "down": src = level L-1 of the source pyramid, dst = level L. Area-weighted box
//   reduction per axis: destination texel j of m covers the source interval [j*n/m, (j+1)*n/m)
//   of n texels (GL's mip geometry, floor(n/2) texels per level), so odd sizes are averaged
//   with fractional weights and the volume mean is preserved. Invocation = (x, y), loop over z.
// VV_PASS 1, "blur": one axis of the separable, normalised Gaussian
//   (vv_weights[0..2*VV_RADIUS]), zero outside the level, as a sliding window along the axis
//   (one load per output).
//   With vv_convert = 1 the result (a mean opacity F) is stored as the optical depth per opacity
//   unit distance, D = -ln(1 - F), F clamped at VV_MAX_OPACITY: what the cone accumulates.

#if VV_PASS == 0
layout(local_size_x = 16, local_size_y = 1, local_size_z = 1) in;
layout(binding = 0, r32f) uniform readonly image3D vv_src;
layout(binding = 1, r32f) uniform writeonly image3D vv_dst;
uniform int vv_srcSize[3];
uniform int vv_dstSize[3];

// Overlap weights of destination texel j with source texels i0, i0+1, i0+2 along one axis
// (n = 2m: exactly two halves; n = 2m+1: at most three texels; n = m = 1: one).
void axisWeights(int j, int n, int m, out int i0, out vec3 w)
{
  float scale = float(n) / float(m);
  float lo = float(j) * scale;
  float hi = float(j + 1) * scale;
  i0 = int(floor(lo));
  for (int t = 0; t < 3; ++t)
  {
    float a = float(i0 + t);
    w[t] = (i0 + t < n) ? max(min(hi, a + 1.0) - max(lo, a), 0.0) / scale : 0.0;
  }
}

// Taps per axis: uniform across the dispatch, so the loops below are not divergent.
int axisTaps(int n, int m)
{
  return n == m ? 1 : (n == 2 * m ? 2 : 3);
}

void main()
{
  ivec2 xy = ivec2(gl_GlobalInvocationID.xy);
  if (xy.x >= vv_dstSize[0] || xy.y >= vv_dstSize[1]) return;
  int ix, iy, iz;
  vec3 wx, wy, wz;
  axisWeights(xy.x, vv_srcSize[0], vv_dstSize[0], ix, wx);
  axisWeights(xy.y, vv_srcSize[1], vv_dstSize[1], iy, wy);
  int tx = axisTaps(vv_srcSize[0], vv_dstSize[0]);
  int ty = axisTaps(vv_srcSize[1], vv_dstSize[1]);
  int tz = axisTaps(vv_srcSize[2], vv_dstSize[2]);
  for (int z = 0; z < vv_dstSize[2]; ++z)
  {
    axisWeights(z, vv_srcSize[2], vv_dstSize[2], iz, wz);
    float acc = 0.0;
    for (int c = 0; c < tz; ++c)
    {
      for (int b = 0; b < ty; ++b)
      {
        float wzy = wz[c] * wy[b];
        for (int a = 0; a < tx; ++a)
        {
          // Clamp: a zero-weight tap past the edge must not read outside the level.
          ivec3 q = min(ivec3(ix + a, iy + b, iz + c),
                        ivec3(vv_srcSize[0], vv_srcSize[1], vv_srcSize[2]) - 1);
          acc += wzy * wx[a] * imageLoad(vv_src, q).r;
        }
      }
    }
    imageStore(vv_dst, ivec3(xy, z), vec4(acc, 0.0, 0.0, 0.0));
  }
}
#endif

#if VV_PASS == 1
#define VV_TAPS (2 * VV_RADIUS + 1)
layout(local_size_x = 16, local_size_y = 1, local_size_z = 1) in;
layout(binding = 0, r32f) uniform readonly image3D vv_src;
layout(binding = 1, r32f) uniform writeonly image3D vv_dst;
uniform int vv_size[3];
uniform int vv_axis;     // 0 = x, 1 = y, 2 = z: the blurred axis
uniform int vv_convert;  // 1: store -ln(1 - F) instead of F
uniform float vv_weights[VV_TAPS];

float load(ivec3 p, ivec3 e, int c, int n)
{
  return (c >= 0 && c < n) ? imageLoad(vv_src, p + c * e).r : 0.0;
}

void main()
{
  // Lanes run along the fastest axis that is not blurred (x, or y for the x pass), so the
  // loads of neighbouring lanes are neighbours in memory where possible.
  int ua = vv_axis == 0 ? 1 : 0;
  int va = vv_axis == 2 ? 1 : 2;
  ivec3 p = ivec3(0);
  p[ua] = int(gl_GlobalInvocationID.x);
  p[va] = int(gl_GlobalInvocationID.y);
  if (p[ua] >= vv_size[ua] || p[va] >= vv_size[va]) return;
  int n = vv_size[vv_axis];
  ivec3 e = ivec3(vv_axis == 0 ? 1 : 0, vv_axis == 1 ? 1 : 0, vv_axis == 2 ? 1 : 0);
  float w[VV_TAPS];
  float win[VV_TAPS];  // src at i - VV_RADIUS .. i + VV_RADIUS
  for (int k = 0; k < VV_TAPS; ++k)
  {
    w[k] = vv_weights[k];
    win[k] = load(p, e, k - VV_RADIUS, n);
  }
  for (int i = 0; i < n; ++i)
  {
    float acc = 0.0;
    for (int k = 0; k < VV_TAPS; ++k) acc += w[k] * win[k];
    if (vv_convert == 1) acc = -log(1.0 - clamp(acc, 0.0, VV_MAX_OPACITY));
    imageStore(vv_dst, p + i * e, vec4(acc, 0.0, 0.0, 0.0));
    for (int k = 0; k < VV_TAPS - 1; ++k) win[k] = win[k + 1];
    win[VV_TAPS - 1] = load(p, e, i + VV_RADIUS + 1, n);
  }
}
#endif
