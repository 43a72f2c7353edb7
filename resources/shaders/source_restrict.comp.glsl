#version 430
// vtkvol engine: the source model's single-scattering source q = sigma_s E_0 restricted from the
// data grid to the reduced scattered-light grid (vtkvol/engine/coarse_diffusion.py,
// ScatterGrid.restrict of diffusion.source_term; the numpy path is the test oracle):
//   q_c(j) = sum_i w(i, j) q(i) / c^3,  w = prod over axes of the length of data cell [i, i+1)
// inside coarse cell [j c, (j+1) c), c = n/m data voxels per coarse cell and axis: the coarse
// cells tile the data's cell bounds (the same texture extent). E_0 and the fall-off are
// evaluated per data voxel exactly as source_diffusion.comp.glsl does on the full grid.
// Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines: VV_CHANNELS 1, 2 or 4 (lights in vv_direct).

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

//@include light_format.glsl

layout(VV_FORMAT) uniform readonly image3D vv_direct;   // data grid: direct light l in channel l
layout(r32f) uniform readonly image3D vv_sigmaS;        // data grid: sigma_s per um (0 = empty)
layout(rgba32f) uniform writeonly image3D vv_source;    // coarse grid: q (rgb) per um^3
uniform ivec3 vv_dims;          // coarse points (x, y, z)
uniform ivec3 vv_fineDims;      // data voxels (x, y, z)
uniform vec3 vv_cell;           // c per axis: data voxels per coarse cell
uniform vec3 vv_spacing;        // um, data grid
uniform vec3 vv_origin;         // um, first voxel centre
uniform int vv_numLights;
uniform vec3 vv_color[4];       // colour * intensity of each light
uniform vec4 vv_falloff[4];     // position (um) and d0 (um; 0 = no fall-off) of each light

//@include direct_irradiance.glsl

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, vv_dims))) return;
  // Data voxels overlapping coarse cell p: [floor(p c), ceil((p + 1) c)).
  vec3 first = vec3(p) * vv_cell;
  vec3 last = vec3(p + 1) * vv_cell;
  ivec3 lo = max(ivec3(floor(first)), ivec3(0));
  ivec3 hi = min(ivec3(ceil(last)) - 1, vv_fineDims - 1);
  vec3 sum = vec3(0.0);
  for (int z = lo.z; z <= hi.z; ++z)
  {
    float wz = max(0.0, min(float(z + 1), last.z) - max(float(z), first.z));
    for (int y = lo.y; y <= hi.y; ++y)
    {
      float wy = wz * max(0.0, min(float(y + 1), last.y) - max(float(y), first.y));
      for (int x = lo.x; x <= hi.x; ++x)
      {
        float w = wy * max(0.0, min(float(x + 1), last.x) - max(float(x), first.x));
        if (w <= 0.0) continue;
        ivec3 i = ivec3(x, y, z);
        float sigmaS = imageLoad(vv_sigmaS, i).r;
        if (sigmaS <= 0.0) continue;
        vec4 rho = imageLoad(vv_direct, i);
        vec3 pos = vv_origin + vv_spacing * vec3(i);
        vec3 e0 = vv_directIrradiance(rho, pos);
        sum += w * sigmaS * e0;
      }
    }
  }
  imageStore(vv_source, p, vec4(sum / (vv_cell.x * vv_cell.y * vv_cell.z), 0.0));
}
