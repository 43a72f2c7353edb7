#version 430
// vtkvol technique "cone_traced": compute shader that bakes the hemisphere ambient occlusion at
// every point of the AO grid (ao_mode = baked_hemisphere). Compiled by
// vtkvol.plugins.cone_traced.gpu.GpuAoBaker (the loader inserts the VV_* defines after
// #version: VV_CONES, VV_DIRS, VV_SIN, VV_CONE_MAX_STEPS, VV_CONE_TAU_EXIT, VV_NORMAL_EPS,
// VV_FRAME_A, VV_FRAME_B, VV_GATE_TAPS), dispatched with PyOpenGL. The CPU twin is
// baked_ao_cpu() in plugins/cone_traced/cpu.py. Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Spaces: the AO grid has vv_gridDims points (x, y, z) spanning the data's point bounds (first
// to last voxel centre), point g at data voxel index g * vv_gridStep (= (n-1)/(m-1)). The cones
// are marched by vv_cone_march() (cone_march.glsl, shared with the fragment shader);
// directions are in index-aligned µm (the image direction matrix only rotates the whole
// hemisphere, which AO does not see).
//
// Per point: outward normal n = -grad(F_0), F_0 = 1 - exp(-D_0) the filtered mean opacity
// (central differences of the trilinear filtered level 0 at +-1 voxel, µm: defined a few
// voxels into and out of every surface, so the points whose values a surface sample
// interpolates all face outwards); AO = mean occlusion of VV_CONES cosine-weighted cones
// about n. Where the gradient vanishes (|difference| <= VV_NORMAL_EPS on every axis) the full
// sphere is used: the same pattern about +z and about -z, 2*VV_CONES cones. Points whose
// neighbourhood holds no opacity (VV_GATE_TAPS trilinear fetches of the source pyramid at level
// vv_gateLod are 0: no ray sample that interpolates this point can be shaded; ao_gate() has the
// geometry) are written as 0 without tracing.
//
// Samplers (the technique's textures, already active on VTK-reserved units):
//   vv_filtered  D_L = -ln(1 - F_L), optical depth per opacity unit distance (border 0)
//   vv_opacity   source pyramid S_L (level 0 = TF opacity per unit distance, border 0)
// Output: image3D vv_ao (r32f): occlusion 0 = open, 1 = closed.

layout(local_size_x = 16, local_size_y = 1, local_size_z = 1) in;
layout(binding = 0, r32f) uniform writeonly image3D vv_ao;
uniform sampler3D vv_filtered;
uniform sampler3D vv_opacity;
uniform int vv_gridDims[3];    // AO grid points (x, y, z)
uniform vec3 vv_gridStep;      // data voxels between grid points
uniform vec3 vv_dims;          // data dimensions (x, y, z)
uniform vec3 vv_spacing;       // voxel size (x, y, z) µm
uniform float vv_unit;         // opacity unit distance u, µm
uniform float vv_maxLod;       // coarsest level of the pyramids
uniform float vv_gateLod;      // level of the emptiness gate
uniform float vv_gateOffset;   // its taps at p +- vv_gateOffset voxels per axis (VV_GATE_TAPS 8)
uniform float vv_lodWidth;     // lod_width * sigma
uniform float vv_h;            // level-0 step, voxels
uniform float vv_h0;           // start offset, voxels
uniform float vv_maxDistUm;    // AO maximum distance, µm
uniform int vv_zOffset;        // first grid slice of this dispatch (baked in slabs)

const vec3 vv_dirs[VV_CONES] = VV_DIRS;

//@include cone_march.glsl

// Transmittance of one cone from texture position tex0 along the µm direction dirUm.
float trace(vec3 tex0, vec3 dirUm)
{
  return vv_cone_march(vv_filtered, tex0, dirUm / vv_spacing, vv_dims, vv_unit, vv_maxDistUm,
                       VV_SIN, vv_lodWidth, vv_h, vv_h0, vv_maxLod);
}

// exp(-D_0) = 1 - F_0 at data voxel coordinates p (F: filtered mean opacity).
float clearAt(vec3 p)
{
  return exp(-textureLod(vv_filtered, (p + 0.5) / vv_dims, 0.0).r);
}

void main()
{
  ivec3 g = ivec3(gl_GlobalInvocationID.x, gl_GlobalInvocationID.y,
                  int(gl_GlobalInvocationID.z) + vv_zOffset);
  if (g.x >= vv_gridDims[0] || g.y >= vv_gridDims[1] || g.z >= vv_gridDims[2]) return;
  vec3 p = vec3(g) * vv_gridStep;  // data voxel index coordinates
  vec3 tex0 = (p + 0.5) / vv_dims;
  float occlusion = 0.0;
#if VV_GATE_TAPS == 1
  float near = textureLod(vv_opacity, tex0, vv_gateLod).r;
#else
  float near = 0.0;
  for (int k = 0; k < 8; ++k)
  {
    vec3 o = vv_gateOffset * vec3((k & 1) != 0 ? 1.0 : -1.0, (k & 2) != 0 ? 1.0 : -1.0,
                                  (k & 4) != 0 ? 1.0 : -1.0);
    near += textureLod(vv_opacity, (p + o + 0.5) / vv_dims, vv_gateLod).r;
  }
#endif
  if (near > 0.0)
  {
    // (F(p+e) - F(p-e)) / 2 per axis, F = 1 - exp(-D_0).
    vec3 dv = 0.5 * vec3(clearAt(p - vec3(1.0, 0.0, 0.0)) - clearAt(p + vec3(1.0, 0.0, 0.0)),
                         clearAt(p - vec3(0.0, 1.0, 0.0)) - clearAt(p + vec3(0.0, 1.0, 0.0)),
                         clearAt(p - vec3(0.0, 0.0, 1.0)) - clearAt(p + vec3(0.0, 0.0, 1.0)));
    bool oriented = max(abs(dv.x), max(abs(dv.y), abs(dv.z))) > VV_NORMAL_EPS;
    vec3 gUm = dv / vv_spacing;
    vec3 n = oriented ? -normalize(gUm) : vec3(0.0, 0.0, 1.0);
    // Tangent frame about n from a generic helper axis, as helper_basis(): continuous except
    // at n = +-VV_FRAME_A (Duff's frame would jump on every vertical face).
    vec3 c = cross(VV_FRAME_A, n);
    if (length(c) < 1e-2) c = cross(VV_FRAME_B, n);
    vec3 t = normalize(c);
    vec3 bt = cross(n, t);
    int count = oriented ? VV_CONES : 2 * VV_CONES;
    for (int k = 0; k < count; ++k)
    {
      vec3 d = vv_dirs[k < VV_CONES ? k : k - VV_CONES];
      float side = k < VV_CONES ? 1.0 : -1.0;  // second half: the mirrored hemisphere
      occlusion += 1.0 - trace(tex0, d.x * t + d.y * bt + side * d.z * n);
    }
    occlusion /= float(count);
  }
  imageStore(vv_ao, g, vec4(occlusion, 0.0, 0.0, 0.0));
}
