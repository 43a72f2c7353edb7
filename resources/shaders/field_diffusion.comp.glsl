#version 430
// vtkvol engine: one explicit diffusion step of each light's own field (the "published" model's
// one-field split of seed 003's eq. 7: rho_l <- rho_l + lambda * sum_a w_a d2_a rho_l, zero flux
// at the box). Mirrors vtkvol/engine/diffusion.py:diffusion_step(rho, rho, lambda) per light.
// Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines: VV_CHANNELS 1, 2 or 4 (one light per channel).

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

//@include light_format.glsl

layout(VV_FORMAT) uniform readonly image3D vv_fieldIn;
layout(VV_FORMAT) uniform writeonly image3D vv_fieldOut;
layout(r32f) uniform readonly image3D vv_lambda;          // diffusion rate per step
uniform ivec3 vv_dims;
uniform vec3 vv_weights;        // (smallest edge / edge)^2 along x, y, z

vec4 at(ivec3 p) { return imageLoad(vv_fieldIn, clamp(p, ivec3(0), vv_dims - 1)); }

#define VV_LAPLACIAN_TYPE vec4
#define VV_LAPLACIAN_AT at
//@include laplacian.glsl

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID);
  if (any(greaterThanEqual(p, vv_dims))) return;
  vec4 c = at(p);
  imageStore(vv_fieldOut, p, c + imageLoad(vv_lambda, p).r * vv_laplacian(p, c));
}
