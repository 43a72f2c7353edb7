#version 430
// vtkvol engine: the source model's single-scattering source q = sigma_s E_0 restricted from the
// data grid to the reduced scattered-light grid (vtkvol/engine/coarse_diffusion.py,
// ScatterGrid.restrict of diffusion.source_term; the numpy path is the test oracle):
//   q_c(j) = sum_i w(i, j) q(i) / sum_i w(i, j),  w = prod over axes of max(0, 1 - |i r - j|),
// r = (m - 1)/(n - 1) per axis: the coarse points span the data's point bounds (the host's
// vv_unitToGrid mechanism). E_0 and the fall-off are evaluated per data voxel exactly as
// source_diffusion.comp.glsl does on the full grid.
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
uniform vec3 vv_ratio;          // r per axis: coarse index per data index
uniform vec3 vv_spacing;        // um, data grid
uniform vec3 vv_origin;         // um, first voxel centre
uniform int vv_numLights;
uniform vec3 vv_color[4];       // colour * intensity of each light
uniform vec4 vv_falloff[4];     // position (um) and d0 (um; 0 = no fall-off) of each light

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, vv_dims))) return;
  // Data voxels with a non-zero weight: |i r - p| < 1 on every axis.
  ivec3 lo = ivec3(0);
  ivec3 hi = vv_fineDims - 1;
  for (int a = 0; a < 3; ++a)
  {
    if (vv_ratio[a] > 0.0)
    {
      lo[a] = max(0, int(ceil((float(p[a]) - 1.0) / vv_ratio[a])));
      hi[a] = min(vv_fineDims[a] - 1, int(floor((float(p[a]) + 1.0) / vv_ratio[a])));
    }
  }
  vec3 sum = vec3(0.0);
  float weights = 0.0;
  for (int z = lo.z; z <= hi.z; ++z)
  {
    float wz = max(0.0, 1.0 - abs(float(z) * vv_ratio.z - float(p.z)));
    for (int y = lo.y; y <= hi.y; ++y)
    {
      float wy = wz * max(0.0, 1.0 - abs(float(y) * vv_ratio.y - float(p.y)));
      for (int x = lo.x; x <= hi.x; ++x)
      {
        float w = wy * max(0.0, 1.0 - abs(float(x) * vv_ratio.x - float(p.x)));
        if (w <= 0.0) continue;
        ivec3 i = ivec3(x, y, z);
        weights += w;
        float sigmaS = imageLoad(vv_sigmaS, i).r;
        if (sigmaS <= 0.0) continue;
        vec4 rho = imageLoad(vv_direct, i);
        vec3 pos = vv_origin + vv_spacing * vec3(i);
        vec3 e0 = vec3(0.0);
        for (int l = 0; l < vv_numLights; ++l)
        {
          float f = 1.0;
          if (vv_falloff[l].w > 0.0)
          {
            vec3 r = pos - vv_falloff[l].xyz;
            f = vv_falloff[l].w * vv_falloff[l].w / max(dot(r, r), 1e-12);
          }
          e0 += rho[l] * f * vv_color[l];
        }
        sum += w * sigmaS * e0;
      }
    }
  }
  imageStore(vv_source, p, vec4(sum / max(weights, 1e-30), 0.0));
}
