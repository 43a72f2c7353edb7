// vtkvol technique "cone_traced": compute shaders that build the filtered-opacity mip chain.
// Compiled by vtkvol.plugins.cone_traced.GpuFilter (one program per VV_PASS value, the
// "#version 430" line and the VV_* defines are prepended there), dispatched with PyOpenGL.
// Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Spaces: integer texel coordinates of one mip level, (x, y, z). Every pass reads level images
// with imageLoad (no filtering, no texture units) and writes one level with imageStore.
// Everything outside the volume is empty (zero), as for the CPU path in cone_traced.py.
//
// VV_PASS 0, "down": src = level L-1 of the source pyramid, dst = level L.
//   Area-weighted box reduction per axis: destination texel j of m covers the source interval
//   [j*n/m, (j+1)*n/m) of n texels (GL's mip geometry, floor(n/2) texels per level), so odd
//   sizes are averaged with fractional weights and the mean over the volume is preserved.
// VV_PASS 1, "blur": one axis of the separable, normalised Gaussian (weights[0..2*radius]),
//   zero outside the level. With convert = 1 the result (a mean opacity F) is stored as the
//   optical depth per opacity unit distance, D = -ln(1 - F), clamped at F = 1 - 1e-6, which is
//   what the cone tracer accumulates.

#if VV_PASS == 0
layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(binding = 0, r32f) uniform readonly image3D src;
layout(binding = 1, r32f) uniform writeonly image3D dst;
uniform int srcSize[3];
uniform int dstSize[3];

// Overlap weights of destination texel j with source texels i0 .. i0+3 along one axis.
void axisWeights(int j, int n, int m, out int i0, out vec4 w)
{
  float scale = float(n) / float(m);
  float lo = float(j) * scale;
  float hi = float(j + 1) * scale;
  i0 = int(floor(lo));
  for (int t = 0; t < 4; ++t)
  {
    float a = float(i0 + t);
    float overlap = min(hi, a + 1.0) - max(lo, a);
    w[t] = (i0 + t < n) ? max(overlap, 0.0) / scale : 0.0;
  }
}

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (p.x >= dstSize[0] || p.y >= dstSize[1] || p.z >= dstSize[2]) return;
  int ix, iy, iz;
  vec4 wx, wy, wz;
  axisWeights(p.x, srcSize[0], dstSize[0], ix, wx);
  axisWeights(p.y, srcSize[1], dstSize[1], iy, wy);
  axisWeights(p.z, srcSize[2], dstSize[2], iz, wz);
  float acc = 0.0;
  for (int c = 0; c < 4; ++c)
  {
    if (wz[c] <= 0.0) continue;
    for (int b = 0; b < 4; ++b)
    {
      float wzy = wz[c] * wy[b];
      if (wzy <= 0.0) continue;
      for (int a = 0; a < 4; ++a)
      {
        if (wx[a] <= 0.0) continue;
        acc += wzy * wx[a] * imageLoad(src, ivec3(ix + a, iy + b, iz + c)).r;
      }
    }
  }
  imageStore(dst, p, vec4(acc, 0.0, 0.0, 0.0));
}
#endif

#if VV_PASS == 1
layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(binding = 0, r32f) uniform readonly image3D src;
layout(binding = 1, r32f) uniform writeonly image3D dst;
uniform int size[3];
uniform int axis;     // 0 = x, 1 = y, 2 = z
uniform int radius;   // taps = 2 * radius + 1 <= VV_MAX_TAPS
uniform int convert;  // 1: store -ln(1 - F) instead of F
uniform float weights[VV_MAX_TAPS];

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (p.x >= size[0] || p.y >= size[1] || p.z >= size[2]) return;
  ivec3 e = ivec3(axis == 0 ? 1 : 0, axis == 1 ? 1 : 0, axis == 2 ? 1 : 0);
  int n = size[axis];
  int c = p[axis];
  // Clip the tap range to the level instead of testing every tap (zero outside).
  int k0 = max(-radius, -c);
  int k1 = min(radius, n - 1 - c);
  float acc = 0.0;
  for (int k = k0; k <= k1; ++k)
  {
    acc += weights[k + radius] * imageLoad(src, p + k * e).r;
  }
  if (convert == 1)
  {
    acc = -log(1.0 - clamp(acc, 0.0, VV_MAX_OPACITY));
  }
  imageStore(dst, p, vec4(acc, 0.0, 0.0, 0.0));
}
#endif
