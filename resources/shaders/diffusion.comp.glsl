#version 430
// vtkvol technique "convection_diffusion": one explicit diffusion step of the scattered light.
// Mirrors plugins/convection_diffusion/cpu.py:diffusion_step with the total field
// sum_l E_l rho_l + rho_s (Transport.step). Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines: VV_CHANNELS 1, 2 or 4 (lights in vv_direct). Zero flux at the box (clamp to edge).

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

//@include light_format.glsl

layout(VV_FORMAT) uniform readonly image3D vv_direct;     // rho_l, one light per channel
layout(rgba32f) uniform readonly image3D vv_scatteredIn;  // rho_s (rgb)
layout(rgba32f) uniform writeonly image3D vv_scatteredOut;
layout(r32f) uniform readonly image3D vv_lambda;          // diffusion rate per step
uniform ivec3 vv_dims;
uniform vec3 vv_weights;        // (smallest edge / edge)^2 along x, y, z
uniform int vv_numLights;
uniform vec3 vv_color[4];       // colour * intensity of each light

vec3 totalAt(ivec3 p)
{
  p = clamp(p, ivec3(0), vv_dims - 1);
  vec4 rho = imageLoad(vv_direct, p);
  vec3 direct = vec3(0.0);
  for (int l = 0; l < vv_numLights; ++l) direct += rho[l] * vv_color[l];
  return direct + imageLoad(vv_scatteredIn, p).rgb;
}

#define VV_LAPLACIAN_TYPE vec3
#define VV_LAPLACIAN_AT totalAt
//@include laplacian.glsl

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, vv_dims))) return;
  vec3 lap = vv_laplacian(p, totalAt(p));
  vec3 s = imageLoad(vv_scatteredIn, p).rgb + imageLoad(vv_lambda, p).r * lap;
  imageStore(vv_scatteredOut, p, vec4(s, 0.0));
}
