#version 430
// vtkvol host: classification on the GPU. Writes the opacity volume every technique reads
// (Illuminator.opacity_volume()'s definition, docs/architecture.md "Classification on the
// GPU"), slab by slab into a storage buffer the driver copies into an r32f 3-D texture: per
// voxel, every independent component classified by its
// 1-D opacity table (times its gradient-opacity table when one is on) or its 2-D
// (value, |grad I|) table, weighted, expressed per the opacity unit distance of component 0
// and combined as independent absorbers, alpha = 1 - prod(1 - alpha_c); then zeroed by the
// cropping regions and clipping planes and multiplied by the slice weights.
// Compiled by vtkvol.engine.classify.GpuClassifier (the loader inserts the VV_* defines after
// #version), dispatched with PyOpenGL. The numpy twin is Illuminator.opacity_volume_steps()
// and must be kept in step with this file. Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines:
//   VV_COMPONENTS       1..4 independent components of the scalars
//   VV_MODE_0..3        per component: 0 = skipped (weight 0), 1 = 1-D table,
//                       2 = 1-D table x gradient-opacity table, 3 = 2-D table
//   VV_EXACT_0..3       1: the 1-D table has one entry per integer value (read one entry)
//   VV_UNIT_0..3        1: convert alpha per the component's unit distance to component 0's
//   VV_FLOAT_DATA       1: the data may hold NaN/inf (float types): they read vv_nanAlpha
//   VV_GRADIENT         1 when any component needs VTK's gradient (modes 2 and 3)
//   VV_TYPE             how the scalars are packed in vv_words: 0 = uint8 (4 per word),
//                       1 = uint16 (2 per word), 2 = float32
//   VV_CROP             1: test the 27 cropping regions
//   VV_CLIP_PLANES      number of clipping planes (0..6)
//   VV_WEIGHTS          1: multiply by the slice weights
//   VV_GROUP_X, VV_BLOCK  work-group size along x, voxels per invocation
//   VV_OPTICAL_DEPTH    1: store s = -ln(1 - alpha) (alpha clamped at VV_MAX_OPACITY), the
//                       optical depth of one opacity unit distance, instead of alpha (the
//                       shadow volume's extinction grid: its conversion pass fused in here)
//
// Spaces: integer voxel indices (x, y, z) of the data. Storage: shader storage buffers (plain
// memory loads and stores; on llvmpipe several times cheaper than texel fetches and image
// stores): the scalars as uploaded (interleaved components, x fastest), the tables, and the
// output: one slab of z slices vv_z0 .. vv_z1 (x fastest), copied into the host's r32f
// texture by the driver. Each invocation classifies VV_BLOCK consecutive voxels along x.
//
// Tables (vv_lut, every 1-D table one after the other, then the per-axis rows): table of
// component c starts at entry vv_opOffset[c], has vv_opLength[c] entries; a value v reads position p = (v - vv_opLo[c]) * vv_opScale[c],
// clamped to the table, linearly between its two entries. Integer data get one entry per
// integer (scale 1, p integral: the exact value); float data a dense sampling of the
// piecewise-linear function over the component's range. Gradient-opacity tables (vv_go*) are
// read the same way at t = |grad| / (0.25 range), 0..1.

#ifndef VV_GROUP_X
#define VV_GROUP_X 64
#endif
#ifndef VV_BLOCK
#define VV_BLOCK 4
#endif
layout(local_size_x = VV_GROUP_X, local_size_y = 1, local_size_z = 1) in;
layout(std430, binding = 0) readonly buffer VvScalars { uint vv_words[]; };
layout(std430, binding = 1) readonly buffer VvTables { float vv_lut[]; };
layout(std430, binding = 2) writeonly buffer VvOut { float vv_out[]; };

uniform ivec3 vv_dims;              // data voxels (x, y, z)
uniform int vv_z0;                  // first z slice of this dispatch (the output slab's)
uniform int vv_z1;                  // end of the slab
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
uniform int vv_axesOffset;          // in vv_lut: rows 0..2 wX, wY, wZ; rows 3..5 crop region
uniform int vv_axesWidth;           // entries per row
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

// Element e of the scalars (component-interleaved, x fastest), as a float.
float element(int e)
{
#if VV_TYPE == 0
  return float((vv_words[e >> 2] >> uint(8 * (e & 3))) & 255u);
#elif VV_TYPE == 1
  return float((vv_words[e >> 1] >> uint(16 * (e & 1))) & 65535u);
#else
  return uintBitsToFloat(vv_words[e]);
#endif
}

// All components of voxel p (clamped to the volume: the edge repeats, as VTK's texture).
vec4 valueAt(ivec3 p)
{
  p = clamp(p, ivec3(0), vv_dims - 1);
  int e = (p.x + vv_dims.x * (p.y + vv_dims.y * p.z)) * VV_COMPONENTS;
  vec4 v = vec4(0.0);
  v[0] = element(e);
#if VV_COMPONENTS > 1
  v[1] = element(e + 1);
#endif
#if VV_COMPONENTS > 2
  v[2] = element(e + 2);
#endif
#if VV_COMPONENTS > 3
  v[3] = element(e + 3);
#endif
  return v;
}

float lutEntry(int i)
{
  return vv_lut[i];
}

// The table at offset, length n, position p (entries): integral positions (VV_EXACT_c: one
// entry per integer value) read one entry, others interpolate linearly between two.
float table(int offset, int n, float p, bool exact)
{
  p = clamp(p, 0.0, float(n - 1));
  if (exact)
  {
    return lutEntry(offset + int(p));
  }
  int i0 = min(int(p), max(n - 2, 0));
  float f = p - float(i0);
  float a = lutEntry(offset + i0);
  float b = lutEntry(offset + min(i0 + 1, n - 1));
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
// coordinate t (0..1, VTK's normalised |grad I|). Called with literal c, so the per-component
// defines and uniform indices fold at compile time (llvmpipe runs every branch otherwise).
int modeOf(const int c)
{
  return c == 0 ? VV_MODE_0 : (c == 1 ? VV_MODE_1 : (c == 2 ? VV_MODE_2 : VV_MODE_3));
}

bool exactOf(const int c)
{
  return (c == 0 ? VV_EXACT_0 : (c == 1 ? VV_EXACT_1 : (c == 2 ? VV_EXACT_2 : VV_EXACT_3))) == 1;
}

bool unitOf(const int c)
{
  return (c == 0 ? VV_UNIT_0 : (c == 1 ? VV_UNIT_1 : (c == 2 ? VV_UNIT_2 : VV_UNIT_3))) == 1;
}

float classify(const int c, float v, float t)
{
  const int mode = modeOf(c);
  float alpha = 0.0;
  if (mode == 3)
  {
    float s = vv_rangeSpan[c] > 0.0 ? clamp((v - vv_rangeLo[c]) / vv_rangeSpan[c], 0.0, 1.0) : 0.0;
#if VV_FLOAT_DATA
    if (isnan(v)) s = 0.0;
#endif
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
    alpha = table(vv_opOffset[c], vv_opLength[c], (v - vv_opLo[c]) * vv_opScale[c], exactOf(c));
#if VV_FLOAT_DATA
    if (isnan(v) || isinf(v)) alpha = vv_nanAlpha[c];
#endif
    if (mode == 2)
    {
      alpha *= table(vv_goOffset[c], vv_goLength[c], t * float(vv_goLength[c] - 1), false);
    }
  }
  alpha = clamp(alpha * vv_weight[c], 0.0, 1.0);
  if (unitOf(c))
  {
    alpha = clamp(1.0 - pow(1.0 - alpha, vv_unitExponent[c]), 0.0, 1.0);
  }
  return alpha;
}

// Transparency 1 - alpha_c of component c (literal) at value v with gradient magnitude m.
float transparencyOf(const int c, float v, float m)
{
  if (modeOf(c) == 0)
  {
    return 1.0;
  }
  float t = 0.0;
  if (modeOf(c) >= 2)
  {
    t = clamp(m / vv_gradSpan[c], 0.0, 1.0);
    if (isnan(t)) t = 0.0;
  }
  return 1.0 - classify(c, v, t);
}

void main()
{
  int x0 = int(gl_GlobalInvocationID.x) * VV_BLOCK;
  int y = int(gl_GlobalInvocationID.y);
  int z = vv_z0 + int(gl_GlobalInvocationID.z);
  if (x0 >= vv_dims.x || z >= vv_z1)
  {
    return;
  }
  float keepYZ = 1.0;
#if VV_WEIGHTS
  keepYZ = vv_lut[vv_axesOffset + vv_axesWidth + y] * vv_lut[vv_axesOffset + 2 * vv_axesWidth + z];
#endif
#if VV_CROP
  int regionYZ = 3 * int(vv_lut[vv_axesOffset + 4 * vv_axesWidth + y])
               + 9 * int(vv_lut[vv_axesOffset + 5 * vv_axesWidth + z]);
#endif
  int base = (z - vv_z0) * vv_dims.x * vv_dims.y + y * vv_dims.x;
  for (int k = 0; k < VV_BLOCK; ++k)
  {
    int x = x0 + k;
    if (x >= vv_dims.x)
    {
      break;
    }
    ivec3 p = ivec3(x, y, z);
    vec4 v = valueAt(p);
#if VV_GRADIENT
    // VTK's central differences (the edge voxel repeats outside), per component.
    vec4 gx = (valueAt(p + ivec3(1, 0, 0)) - valueAt(p - ivec3(1, 0, 0))) / vv_gradDivisor.x;
    vec4 gy = (valueAt(p + ivec3(0, 1, 0)) - valueAt(p - ivec3(0, 1, 0))) / vv_gradDivisor.y;
    vec4 gz = (valueAt(p + ivec3(0, 0, 1)) - valueAt(p - ivec3(0, 0, 1))) / vv_gradDivisor.z;
    vec4 magnitude = sqrt(gx * gx + gy * gy + gz * gz);
#else
    vec4 magnitude = vec4(0.0);
#endif
    float transparency = transparencyOf(0, v[0], magnitude[0]);
#if VV_COMPONENTS > 1
    transparency *= transparencyOf(1, v[1], magnitude[1]);
#endif
#if VV_COMPONENTS > 2
    transparency *= transparencyOf(2, v[2], magnitude[2]);
#endif
#if VV_COMPONENTS > 3
    transparency *= transparencyOf(3, v[3], magnitude[3]);
#endif
    float alpha = 1.0 - transparency;
#if VV_CROP
    int region = regionYZ + int(vv_lut[vv_axesOffset + 3 * vv_axesWidth + x]);
    if (((vv_cropFlags >> region) & 1) == 0) alpha = 0.0;
#endif
#if VV_CLIP_PLANES > 0
    for (int j = 0; j < VV_CLIP_PLANES; ++j)
    {
      if (dot(vv_clip[j].xyz, vec3(p)) + vv_clip[j].w < 0.0) alpha = 0.0;
    }
#endif
#if VV_WEIGHTS
    alpha *= keepYZ * vv_lut[vv_axesOffset + x];
#endif
#if VV_OPTICAL_DEPTH
    vv_out[base + x] = -log(1.0 - clamp(alpha, 0.0, VV_MAX_OPACITY));
#else
    vv_out[base + x] = alpha;
#endif
  }
}
