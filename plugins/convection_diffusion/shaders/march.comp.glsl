#version 430
// vtkvol technique "convection_diffusion", source model: the direct light of every light at
// once, ray-marched from each voxel centre to the light (the exact transmittance up to the
// midpoint rule). Mirrors vtkvol/engine/diffusion.py:marched_transmittance (the numpy path is
// the test oracle). Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines (inserted by the loader): VV_CHANNELS 1, 2 or 4 (one light per channel of vv_rhoOut).
// Grid: the data's voxel centres, index (x, y, z); vv_origin/vv_spacing in µm (dataset space).
// Per light l: vv_lightVec[l].xyz = the direction towards the light (directional, unit) or its
// position (point, µm), .w = 1 for point lights.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

//@include light_format.glsl

layout(VV_FORMAT) uniform writeonly image3D vv_rhoOut;
layout(r32f) uniform readonly image3D vv_alpha;   // opacity of one unit distance, 1 - exp(-sigma_t u)
uniform ivec3 vv_dims;
uniform vec3 vv_origin;         // µm, first voxel centre
uniform vec3 vv_spacing;        // µm
uniform float vv_unitDistance;  // µm: the thickness vv_alpha is the opacity of
uniform float vv_step;          // µm: the longest march step
uniform float vv_maxOpacity;
uniform int vv_numLights;
uniform vec4 vv_lightVec[4];

//@include grid_cell.glsl

float lerp(float a, float b, float w) { return a + (b - a) * w; }

// sigma_t (per µm) of the trilinearly interpolated opacity at p (µm), clamped to the box.
float sigmaAt(vec3 p)
{
  ivec3 i0, i1;
  vec3 w;
  vv_gridCell(p, i0, i1, w);
  float c0 = lerp(lerp(imageLoad(vv_alpha, ivec3(i0.x, i0.y, i0.z)).r,
                       imageLoad(vv_alpha, ivec3(i1.x, i0.y, i0.z)).r, w.x),
                  lerp(imageLoad(vv_alpha, ivec3(i0.x, i1.y, i0.z)).r,
                       imageLoad(vv_alpha, ivec3(i1.x, i1.y, i0.z)).r, w.x), w.y);
  float c1 = lerp(lerp(imageLoad(vv_alpha, ivec3(i0.x, i0.y, i1.z)).r,
                       imageLoad(vv_alpha, ivec3(i1.x, i0.y, i1.z)).r, w.x),
                  lerp(imageLoad(vv_alpha, ivec3(i0.x, i1.y, i1.z)).r,
                       imageLoad(vv_alpha, ivec3(i1.x, i1.y, i1.z)).r, w.x), w.y);
  float a = min(lerp(c0, c1, w.z), vv_maxOpacity);
  return -log(1.0 - a) / vv_unitDistance;
}

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, vv_dims))) return;
  vec3 pos = vv_origin + vv_spacing * vec3(p);
  vec4 outRho = vec4(0.0);
  for (int l = 0; l < vv_numLights; ++l)
  {
    vec3 d = vv_lightVec[l].xyz;
    float dist = 1e30;
    if (vv_lightVec[l].w > 0.5)
    {
      d = vv_lightVec[l].xyz - pos;
      dist = length(d);
      d = d / max(dist, 1e-12);
    }
    float len = min(vv_boxExit(pos, d), dist);
    int steps = int(ceil(len / vv_step));
    float h = steps > 0 ? len / float(steps) : 0.0;
    float tau = 0.0;
    for (int k = 0; k < steps; ++k)
      tau += h * sigmaAt(pos + (float(k) + 0.5) * h * d);
    outRho[l] = exp(-tau);
  }
  imageStore(vv_rhoOut, p, outRho);
}
