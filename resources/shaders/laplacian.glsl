// vtkvol engine: the explicit diffusion step's stencil, shared by diffusion.comp.glsl (the
// scattered light of convection_diffusion) and field_diffusion.comp.glsl (each light's own field):
//   sum_a w_a (f(p + e_a) + f(p - e_a) - 2 f(p)),  w_a = vv_weights[a] = (smallest edge / edge_a)^2
// (vtkvol/engine/diffusion.py:diffusion_step). The including shader declares vv_weights and
// defines VV_LAPLACIAN_TYPE (vec3 or vec4) and VV_LAPLACIAN_AT, the function that reads the
// field at a voxel clamped to the box (zero flux at the box).

VV_LAPLACIAN_TYPE vv_laplacian(ivec3 p, VV_LAPLACIAN_TYPE centre)
{
  VV_LAPLACIAN_TYPE lap = VV_LAPLACIAN_TYPE(0.0);
  for (int a = 0; a < 3; ++a)
  {
    ivec3 e = ivec3(0);
    e[a] = 1;
    lap += vv_weights[a] * (VV_LAPLACIAN_AT(p + e) + VV_LAPLACIAN_AT(p - e) - 2.0 * centre);
  }
  return lap;
}
