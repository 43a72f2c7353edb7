#version 430
// vtkvol host: classification on the GPU. Writes the opacity volume every technique reads
// (Illuminator.opacity_volume()'s definition, docs/architecture.md "Classification on the
// GPU") into an r32f 3-D image: per voxel, every independent component classified by its
// 1-D opacity table (times its gradient-opacity table when one is on) or its 2-D
// (value, |grad I|) table, weighted, expressed per the opacity unit distance of component 0
// and combined as independent absorbers, alpha = 1 - prod(1 - alpha_c); then zeroed by the
// cropping regions and clipping planes and multiplied by the slice weights.
// Compiled by vtkvol.engine.classify.GpuClassifier (the loader inserts the VV_* defines after
// #version), dispatched with PyOpenGL. The numpy twin is Illuminator.opacity_volume_steps()
// and must be kept in step with this file. Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines:
//   VV_COMPONENTS       1..4 independent components of the scalar texture
//   VV_MODE_0..3        per component: 0 = skipped (weight 0), 1 = 1-D table,
//                       2 = 1-D table x gradient-opacity table, 3 = 2-D table
//   VV_GRADIENT         1 when any component needs VTK's gradient (modes 2 and 3)
//   VV_ROUND            1: the scalar texture is unsigned-normalised integer data (r8/r16):
//                       value = round(fetch * vv_decode), exactly the stored integer
//   VV_CROP             1: test the 27 cropping regions
//   VV_CLIP_PLANES      number of clipping planes (0..6)
//   VV_WEIGHTS          1: multiply by the slice weights
//
// Spaces: integer voxel indices (x, y, z) of the data, texelFetch everywhere (no filtering).
// Each invocation walks one column (x, y) along z, keeping the z-neighbours of the gradient
// in registers (on llvmpipe the cost is per invocation and per load).
//
// Tables (vv_lut, one r32f 2-D texture holding every 1-D table, row-major in rows of
// vv_lutWidth entries): table of component c starts at entry vv_opOffset[c], has
// vv_opLength[c] entries; a value v reads position p = (v - vv_opLo[c]) * vv_opScale[c],
// clamped to the table, linearly between its two entries. Integer data get one entry per
// integer (scale 1, p integral: the exact value); float data a dense sampling of the
// piecewise-linear function over the component's range. Gradient-opacity tables (vv_go*) are
// read the same way at t = |grad| / (0.25 range), 0..1.

layout(local_size_x = 16, local_size_y = 1, local_size_z = 1) in;
layout(binding = 0, r32f) uniform writeonly image3D vv_out;

uniform sampler3D vv_scalars;       // the data, VV_COMPONENTS channels
uniform sampler2D vv_lut;           // every 1-D table
uniform int vv_lutWidth;
uniform ivec3 vv_dims;              // data voxels (x, y, z)
uniform int vv_z0;                  // first and end z slice of this dispatch
uniform int vv_z1;
uniform vec4 vv_decode;             // per component: VV_ROUND scale (255, 65535) or 1
uniform int vv_opOffset[4];
uniform int vv_opLength[4];
uniform float vv_opLo[4];
uniform float vv_opScale[4];
uniform float vv_nanAlpha[4];       // a non-finite value reads the first node (as numpy does)
uniform int vv_goOffset[4];
uniform int vv_goLength[4];
uniform float vv_weight[4];         // component weight (1 for one component)
uniform float vv_unitExponent[4];   // u0 / u_c: alpha per u_c -> alpha per u0
uniform float vv_rangeLo[4];        // the component's scalar range: the 2-D value axis
uniform float vv_rangeSpan[4];      // (<= 0: degenerate, s = 0) and the gradient's scale
uniform float vv_gradSpan[4];       // 0.25 * span (1 for a degenerate range)
uniform vec3 vv_gradDivisor;        // 2 s_i / mean(s), per axis

#if VV_CROP || VV_WEIGHTS
uniform sampler2D vv_axes;          // rows 0..2: wX, wY, wZ; rows 3..5: crop region 0/1/2
#endif
#if VV_CROP
uniform int vv_cropFlags;           // VTK's 27-bit region flags
#endif
#if VV_CLIP_PLANES > 0
uniform vec4 vv_clip[VV_CLIP_PLANES];   // side = dot(xyz, voxel index) + w; < 0 is cut
#endif
#if VV_MODE_0 == 3
uniform sampler2D vv_tf2d_0;
#endif
#if VV_MODE_1 == 3
uniform sampler2D vv_tf2d_1;
#endif
#if VV_MODE_2 == 3
uniform sampler2D vv_tf2d_2;
#endif
#if VV_MODE_3 == 3
uniform sampler2D vv_tf2d_3;
#endif

const int C = VV_COMPONENTS;

vec4 valueAt(ivec3 p)
{
  vec4 v = texelFetch(vv_scalars, clamp(p, ivec3(0), vv_dims - 1), 0) * vv_decode;
#if VV_ROUND
  v = floor(v + 0.5);
#endif
  return v;
}

float lutEntry(int i)
{
  return texelFetch(vv_lut, ivec2(i % vv_lutWidth, i / vv_lutWidth), 0).r;
}

// Linear read of the table at offset, length n, position p (entries).
float table(int offset, int n, float p)
{
  p = clamp(p, 0.0, float(n - 1));
  int i0 = min(int(p), max(n - 2, 0));
  float f = p - float(i0);
  float a = lutEntry(offset + i0);
  float b = n > 1 ? lutEntry(offset + i0 + 1) : a;
  return a * (1.0 - f) + b * f;
}

// Bilinear lookup of a (h, w) 2-D table at texture coordinates (s, t), as GL's linear
// filter with clamp to edge reads it (vtkvol.engine.tf2d.lookup).
float lookup2d(sampler2D tf, float s, float t)
{
  ivec2 size = textureSize(tf, 0);
  float x = clamp(s * float(size.x) - 0.5, 0.0, float(size.x - 1));
  float y = clamp(t * float(size.y) - 0.5, 0.0, float(size.y - 1));
  int x0 = min(int(x), max(size.x - 2, 0));
  int y0 = min(int(y), max(size.y - 2, 0));
  float fx = x - float(x0);
  float fy = y - float(y0);
  int x1 = min(x0 + 1, size.x - 1);
  int y1 = min(y0 + 1, size.y - 1);
  float top = texelFetch(tf, ivec2(x0, y0), 0).r * (1.0 - fx) + texelFetch(tf, ivec2(x1, y0), 0).r * fx;
  float bottom = texelFetch(tf, ivec2(x0, y1), 0).r * (1.0 - fx) + texelFetch(tf, ivec2(x1, y1), 0).r * fx;
  return top * (1.0 - fy) + bottom * fy;
}

// Component c's opacity per its own unit distance, from its value v and its gradient
// coordinate t (0..1, VTK's normalised |grad I|).
float classify(int c, int mode, float v, float t)
{
  float alpha;
  if (mode == 3)
  {
    float s = vv_rangeSpan[c] > 0.0 ? clamp((v - vv_rangeLo[c]) / vv_rangeSpan[c], 0.0, 1.0) : 0.0;
    if (isnan(v)) s = 0.0;
#if VV_MODE_0 == 3
    if (c == 0) alpha = lookup2d(vv_tf2d_0, s, t);
#endif
#if VV_MODE_1 == 3
    if (c == 1) alpha = lookup2d(vv_tf2d_1, s, t);
#endif
#if VV_MODE_2 == 3
    if (c == 2) alpha = lookup2d(vv_tf2d_2, s, t);
#endif
#if VV_MODE_3 == 3
    if (c == 3) alpha = lookup2d(vv_tf2d_3, s, t);
#endif
  }
  else
  {
    bool finite = !isnan(v) && !isinf(v);
    alpha = finite ? table(vv_opOffset[c], vv_opLength[c], (v - vv_opLo[c]) * vv_opScale[c])
                   : vv_nanAlpha[c];
    if (mode == 2)
    {
      alpha *= table(vv_goOffset[c], vv_goLength[c], t * float(vv_goLength[c] - 1));
    }
  }
  alpha = clamp(alpha * vv_weight[c], 0.0, 1.0);
  if (vv_unitExponent[c] != 1.0)
  {
    alpha = 1.0 - pow(1.0 - alpha, vv_unitExponent[c]);
  }
  return clamp(alpha, 0.0, 1.0);
}

int modeOf(int c)
{
  return c == 0 ? VV_MODE_0 : (c == 1 ? VV_MODE_1 : (c == 2 ? VV_MODE_2 : VV_MODE_3));
}

void main()
{
  ivec2 xy = ivec2(gl_GlobalInvocationID.xy);
  if (xy.x >= vv_dims.x || xy.y >= vv_dims.y)
  {
    return;
  }
  float keepXY = 1.0;
  float wXY = 1.0;
#if VV_WEIGHTS
  wXY = texelFetch(vv_axes, ivec2(xy.x, 0), 0).r * texelFetch(vv_axes, ivec2(xy.y, 1), 0).r;
#endif
#if VV_CROP
  int regionXY = int(texelFetch(vv_axes, ivec2(xy.x, 3), 0).r)
               + 3 * int(texelFetch(vv_axes, ivec2(xy.y, 4), 0).r);
#endif
#if VV_GRADIENT
  vec4 below = valueAt(ivec3(xy, vv_z0 - 1));
  vec4 here = valueAt(ivec3(xy, vv_z0));
#endif
  for (int z = vv_z0; z < vv_z1; ++z)
  {
#if VV_GRADIENT
    vec4 above = valueAt(ivec3(xy, z + 1));
    vec4 v = here;
    // VTK's central differences (the edge voxel repeats outside), per component.
    vec4 gx = (valueAt(ivec3(xy.x + 1, xy.y, z)) - valueAt(ivec3(xy.x - 1, xy.y, z))) / vv_gradDivisor.x;
    vec4 gy = (valueAt(ivec3(xy.x, xy.y + 1, z)) - valueAt(ivec3(xy.x, xy.y - 1, z))) / vv_gradDivisor.y;
    vec4 gz = (above - below) / vv_gradDivisor.z;
    vec4 magnitude = sqrt(gx * gx + gy * gy + gz * gz);
#else
    vec4 v = valueAt(ivec3(xy, z));
    vec4 magnitude = vec4(0.0);
#endif
    float transparency = 1.0;
    for (int c = 0; c < C; ++c)
    {
      int mode = modeOf(c);
      if (mode == 0) continue;
      float t = clamp(magnitude[c] / vv_gradSpan[c], 0.0, 1.0);
      if (isnan(t)) t = 0.0;
      transparency *= 1.0 - classify(c, mode, v[c], t);
    }
    float alpha = 1.0 - transparency;
#if VV_CROP
    int region = regionXY + 9 * int(texelFetch(vv_axes, ivec2(z, 5), 0).r);
    if (((vv_cropFlags >> region) & 1) == 0) alpha = 0.0;
#endif
#if VV_CLIP_PLANES > 0
    for (int k = 0; k < VV_CLIP_PLANES; ++k)
    {
      if (dot(vv_clip[k].xyz, vec3(xy, z)) + vv_clip[k].w < 0.0) alpha = 0.0;
    }
#endif
#if VV_WEIGHTS
    alpha *= wXY * texelFetch(vv_axes, ivec2(z, 2), 0).r;
#endif
    imageStore(vv_out, ivec3(xy, z), vec4(alpha));
#if VV_GRADIENT
    below = here;
    here = above;
#endif
  }
}
