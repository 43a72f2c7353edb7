#version 430
// vtkvol technique "convection_diffusion": one convection iteration for every light at once.
// Mirrors plugins/convection_diffusion/cpu.py:convection_step formula by formula (the numpy path
// is the test oracle). Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines (inserted by the loader): VV_CHANNELS 1, 2 or 4 (one light per channel of vv_rhoIn);
// VV_STEADY 1: a sweep of the steady state instead (vtkvol/engine/diffusion.py:
// steady_convection_sweep): nx + ny + nz sweeps give the converged light, one propagation pass.
// Grid: the data's voxel centres, index (x, y, z); vv_origin/vv_spacing in µm (dataset space).
// Per light l: vv_lightVec[l].xyz = the direction the light travels (directional, unit) or its
// position (point, µm), .w = 1 for point lights.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

//@include light_format.glsl

layout(VV_FORMAT) uniform readonly image3D vv_rhoIn;
layout(VV_FORMAT) uniform writeonly image3D vv_rhoOut;
layout(r32f) uniform readonly image3D vv_sigmaA;   // fraction absorbed per iteration
uniform ivec3 vv_dims;
uniform vec3 vv_ratio;          // smallest voxel edge / edge along x, y, z
uniform vec3 vv_origin;         // µm, first voxel centre
uniform vec3 vv_spacing;        // µm
uniform float vv_sourceRadius2; // µm²: voxels this close to a point light are held at 1
uniform int vv_numLights;
uniform vec4 vv_lightVec[4];

// rho of light l at voxel p, or the unit inflow irradiance outside the box.
float rhoAt(ivec3 p, int l)
{
  if (any(lessThan(p, ivec3(0))) || any(greaterThanEqual(p, vv_dims))) return 1.0;
  return imageLoad(vv_rhoIn, p)[l];
}

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, vv_dims))) return;
  vec4 rho = imageLoad(vv_rhoIn, p);
  float keep = 1.0 - imageLoad(vv_sigmaA, p).r;
  vec3 pos = vv_origin + vv_spacing * vec3(p);
  vec4 outRho = vec4(0.0);
  for (int l = 0; l < vv_numLights; ++l)
  {
    bool point = vv_lightVec[l].w > 0.5;
    vec3 d = pos - vv_lightVec[l].xyz;
    vec3 u = point ? d / max(length(d), 1e-12) : vv_lightVec[l].xyz;
#if VV_STEADY
    float upwindSum = 0.0;
    float cSum = 0.0;
    for (int a = 0; a < 3; ++a)
    {
      ivec3 e = ivec3(0);
      e[a] = 1;
      float c = abs(u[a]) * vv_ratio[a];
      upwindSum += c * (u[a] > 0.0 ? rhoAt(p - e, l) : rhoAt(p + e, l));
      cSum += c;
    }
    outRho[l] = keep * 0.5 * upwindSum / (1.0 - keep * (1.0 - 0.5 * cSum));
#else
    float flow = 0.0;
    for (int a = 0; a < 3; ++a)
    {
      ivec3 e = ivec3(0);
      e[a] = 1;
      float c = abs(u[a]) * vv_ratio[a];
      float upwind = u[a] > 0.0 ? rhoAt(p - e, l) : rhoAt(p + e, l);
      flow += c * (rho[l] - upwind);
    }
    outRho[l] = keep * (rho[l] - 0.5 * flow);
#endif
    if (point && dot(d, d) <= vv_sourceRadius2) outRho[l] = 1.0;
  }
  imageStore(vv_rhoOut, p, outRho);
}
